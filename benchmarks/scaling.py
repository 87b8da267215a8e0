"""Tick cost vs number of DOF and vs number of tasks, on synthetic mobile manipulators.

    python -m benchmarks.scaling [--dofs 8 16 24 32 48 64 128 256] [--tasks 1 2 4 8] [--ticks 1000]
                                 [--no-peers] [--out benchmarks/output/scaling]

Robots: a planar base (prismatic x, prismatic y, revolute yaw; 0.8 m/s, 1 rad/s) carrying
a serial chain of ``DOF - 3`` revolute joints (axes cycling z, y, y, x; total length
0.8 m whatever the DOF; limits ±2.5 rad, 2 rad/s), frame ``ee`` at the tip. URDF and a
matching MJCF are generated in a temporary folder.

* **DOF sweep**: FrameTask(ee) + PostureTask + position limits + velocity limits (the
  peer stack of :mod:`benchmarks.peers`, world-axis speed box), the tool following a
  horizontal circle (r = 5 cm, 4 s) in closed loop; wbc and, unless ``--no-peers``, Pink
  (URDF) and mink (MJCF): at each DOF the three libraries alternate in blocks of ``--block``
  consecutive ticks (50), the blocks in a random order each round (seeded), so noise hits
  them alike and each runs like a control loop (a library stepped right after another one
  at 128 DOF finds its data evicted from the caches). From 16 DOF wbc solves the lifted QP
  (``wbc.qp.lifting``).
* **task sweep**: on the 24-DOF chain, k FrameTasks on frames spread along the chain
  (each on its own small circle) + PostureTask, k in ``--tasks``; wbc only.

Latency is the whole ``step`` call; ``solve`` is DAQP's share as wbc reports it. The growth
exponent of each library is the slope of the least-squares line through (log DOF, log median
tick) over the sweep, and over its sizes from 32 DOF on (the tick ~ DOF^exponent).
Output: ``report.md``, ``results.json``, ``scaling.png`` in ``--out``.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

import numpy as np

import wbc
from wbc.app.references import Circle

from .common import OUTPUT, fmt, machine_note, markdown_table, package_versions, percentiles_us, progress
from .peer_setups import MinkSetup, PinkSetup, StackSpec, WorldVelocityLimits

AXES = ("0 0 1", "0 1 0", "0 1 0", "1 0 0")
BASE_SPEED, YAW_RATE, JOINT_LIMIT, JOINT_SPEED, REACH = 0.8, 1.0, 2.5, 2.0, 0.8


def chain_urdf(dof: int) -> str:
    """URDF text of the synthetic robot with ``dof`` velocity coordinates (>= 4)."""
    n_arm = dof - 3
    length = REACH / n_arm
    links = ["world", "base_x_link", "base_y_link", "base_link"] + [f"link_{i}" for i in range(1, n_arm + 1)] + ["ee"]
    parts = [f'<robot name="chain{dof}">'] + [f'  <link name="{name}"/>' for name in links]

    def joint(name, kind, parent, child, axis, xyz, lower, upper, speed):
        return (f'  <joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
                f'<origin xyz="{xyz}"/><axis xyz="{axis}"/>'
                f'<limit lower="{lower}" upper="{upper}" effort="100" velocity="{speed}"/></joint>')

    parts.append(joint("base_x", "prismatic", "world", "base_x_link", "1 0 0", "0 0 0", -1000, 1000, BASE_SPEED))
    parts.append(joint("base_y", "prismatic", "base_x_link", "base_y_link", "0 1 0", "0 0 0", -1000, 1000, BASE_SPEED))
    parts.append(joint("base_yaw", "revolute", "base_y_link", "base_link", "0 0 1", "0 0 0", -1000, 1000, YAW_RATE))
    parent = "base_link"
    for i in range(1, n_arm + 1):
        offset = "0.1 0 0.1" if i == 1 else f"0 0 {length:.6f}"
        parts.append(joint(f"joint_{i}", "revolute", parent, f"link_{i}", AXES[(i - 1) % 4], offset,
                           -JOINT_LIMIT, JOINT_LIMIT, JOINT_SPEED))
        parent = f"link_{i}"
    parts.append(f'  <joint name="ee_joint" type="fixed"><parent link="{parent}"/><child link="ee"/>'
                 f'<origin xyz="0 0 {length:.6f}"/></joint>')
    parts.append("</robot>")
    return "\n".join(parts)


def chain_mjcf(dof: int) -> str:
    """MJCF text with the same kinematics as :func:`chain_urdf` (site ``ee``)."""
    n_arm = dof - 3
    length = REACH / n_arm
    lines = [f'<mujoco model="chain{dof}"><compiler angle="radian" autolimits="true"/><worldbody>',
             '<body name="base_link"><joint name="base_x" type="slide" axis="1 0 0"/>'
             '<joint name="base_y" type="slide" axis="0 1 0"/><joint name="base_yaw" type="hinge" axis="0 0 1"/>'
             '<inertial pos="0 0 0" mass="1" diaginertia="0.1 0.1 0.1"/>']
    for i in range(1, n_arm + 1):
        pos = "0.1 0 0.1" if i == 1 else f"0 0 {length:.6f}"
        lines.append(f'<body name="link_{i}" pos="{pos}">'
                     f'<joint name="joint_{i}" type="hinge" axis="{AXES[(i - 1) % 4]}" '
                     f'range="{-JOINT_LIMIT} {JOINT_LIMIT}"/>'
                     '<inertial pos="0 0 0" mass="0.1" diaginertia="1e-3 1e-3 1e-3"/>')
    lines.append(f'<site name="ee" pos="0 0 {length:.6f}"/>' + "</body>" * n_arm + "</body></worldbody></mujoco>")
    return "\n".join(lines)


def initial_configuration(dof: int) -> np.ndarray:
    """A bent, non-singular start: arm joints 0.4 sin(i)."""
    q = np.zeros(dof)
    q[3:] = 0.4 * np.sin(np.arange(1, dof - 2))
    return q


class Case:
    """One robot + task stack + its closed-loop state, stepped one tick at a time."""

    def __init__(self, name: str, robot: wbc.Robot, controller_step, targets: list, q0: np.ndarray,
                 dt: float, solve_time=None) -> None:
        self.name, self.robot, self.step, self.targets, self.dt = name, robot, controller_step, targets, dt
        self.q = q0.copy()
        self.solve_time = solve_time
        self.times: list[float] = []
        self.solves: list[float] = []

    def tick(self, k: int, record: bool) -> None:
        import time

        for set_target, reference in self.targets:
            set_target(np.array(reference(k * self.dt)[0]))
        start = time.perf_counter()
        v = self.step(self.q)
        elapsed = time.perf_counter() - start
        if record:
            self.times.append(elapsed)
            if self.solve_time is not None:
                self.solves.append(self.solve_time())
        self.q = self.robot.integrate(self.q, v, self.dt)


def _circle(robot: wbc.Robot, q0: np.ndarray, frame: str, radius: float = 0.05) -> Circle:
    return Circle(start=robot.frame_pose(q0, frame), radius=radius, period=4.0, normal=[0.0, 0.0, 1.0],
                  start_axis=[1.0, 0.0, 0.0], ramp_time=0.5)


def dof_cases(folder: Path, dof: int, peers: bool, dt: float = 0.01) -> list[Case]:
    urdf, mjcf = folder / f"chain{dof}.urdf", folder / f"chain{dof}.xml"
    urdf.write_text(chain_urdf(dof))
    mjcf.write_text(chain_mjcf(dof))
    robot = wbc.load_robot(urdf)
    q0 = initial_configuration(dof)
    reference = _circle(robot, q0, "ee")
    task = wbc.FrameTask("ee", 1.0, 0.5, gain=0.5)
    controller = wbc.Controller(robot, [task, wbc.PostureTask(1e-3, target=q0, gain=0.05)],
                                [wbc.JointPositionLimits(gain=0.5), WorldVelocityLimits()], solver="daqp", dt=dt)
    cases = [Case(f"wbc {dof}", robot, controller.step, [(task.set_target, reference)], q0, dt,
                  solve_time=lambda: controller.last.solve_time)]
    if peers:
        spec = StackSpec(frame="ee", position_cost=1.0, orientation_cost=0.5, gain=0.5, posture_cost=1e-3,
                         posture_gain=0.05, posture_target=q0, limit_gain=0.5, damping=1e-3, dt=dt,
                         velocity_limit=robot.velocity_limit.copy(), joint_names=list(robot.joint_names),
                         base_indices=tuple(robot.base.indices))
        pink = PinkSetup(spec, urdf=urdf)
        mink = MinkSetup(spec, mjcf=mjcf)
        cases += [Case(f"Pink {dof}", robot, pink.step, [(pink.set_target, reference)], q0, dt),
                  Case(f"mink {dof}", robot, mink.step, [(mink.set_target, reference)], q0, dt)]
    return cases


def task_cases(folder: Path, counts: list[int], dof: int = 24, dt: float = 0.01) -> list[Case]:
    urdf = folder / f"chain{dof}.urdf"
    urdf.write_text(chain_urdf(dof))
    robot = wbc.load_robot(urdf)
    q0 = initial_configuration(dof)
    n_arm = dof - 3
    cases = []
    for count in counts:
        frames = ["ee"] + [f"link_{i}" for i in np.linspace(n_arm, 1, count + 1)[1:count].round().astype(int)]
        tasks = [wbc.FrameTask(frame, 1.0, 0.5, gain=0.5) for frame in frames]
        controller = wbc.Controller(robot, tasks + [wbc.PostureTask(1e-3, target=q0, gain=0.05)],
                                    [wbc.JointPositionLimits(gain=0.5), WorldVelocityLimits()], solver="daqp", dt=dt)
        targets = [(task.set_target, _circle(robot, q0, task.frame, 0.02)) for task in tasks]
        cases.append(Case(f"{count} tasks", robot, controller.step, targets, q0, dt,
                          solve_time=lambda c=controller: c.last.solve_time))
    return cases


def run_interleaved(cases: list[Case], ticks: int, warmup: int, label: str, show_progress: bool,
                    block: int = 1) -> None:
    """Every case's ticks in blocks of ``block`` consecutive ticks, the cases' blocks in a random
    order (seeded) each round: machine noise hits all cases alike; within a block a case runs
    like a control loop (its own data in cache, not the previous case's)."""
    iterator = range(0, warmup + ticks, block)
    if show_progress:
        iterator = progress(iterator, desc=label, unit=f"{block} ticks")
    order = np.random.default_rng(0)
    for first in iterator:
        for index in order.permutation(len(cases)):
            for k in range(first, min(first + block, warmup + ticks)):
                cases[index].tick(k, record=k >= warmup)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.scaling", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--dofs", type=int, nargs="+", default=[8, 16, 24, 32, 48, 64, 128, 256])
    parser.add_argument("--tasks", type=int, nargs="+", default=[1, 2, 4, 8])
    parser.add_argument("--ticks", type=int, default=1000, help="measured ticks per case (default 1000)")
    parser.add_argument("--warmup", type=int, default=50)
    parser.add_argument("--no-peers", action="store_true", help="wbc only in the DOF sweep")
    parser.add_argument("--block", type=int, default=50,
                        help="DOF sweep: consecutive ticks of one library between switches (default 50)")
    parser.add_argument("--out", type=Path, default=OUTPUT / "scaling")
    parser.add_argument("--no-progress", action="store_true")
    args = parser.parse_args(argv)
    command = "python -m benchmarks.scaling " + " ".join(argv if argv is not None else sys.argv[1:])
    args.out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        dof = []
        for n in args.dofs:  # wbc, Pink and mink at one DOF: alternating blocks of ticks
            dof += (group := dof_cases(folder, n, not args.no_peers))
            run_interleaved(group, args.ticks, args.warmup, f"{n} DOF", not args.no_progress, block=args.block)
        tasks = task_cases(folder, args.tasks)
        run_interleaved(tasks, args.ticks, args.warmup, "task sweep", not args.no_progress)

    stats = {case.name: percentiles_us(case.times) | (
        {"solve_median": float(np.median(case.solves) * 1e6)} if case.solves else {}) for case in dof + tasks}
    base = stats[f"wbc {args.dofs[0]}"]["median"]
    dof_rows = []
    for n in args.dofs:
        s = stats[f"wbc {n}"]
        row = [n, fmt(s["median"]), fmt(s["p99"]), fmt(s["solve_median"]),
               f"{100 * s['solve_median'] / s['median']:.0f}", f"{s['median'] / base:.2f}"]
        if not args.no_peers:
            row += [fmt(stats[f"Pink {n}"]["median"]), fmt(stats[f"mink {n}"]["median"]),
                    f"{stats[f'Pink {n}']['median'] / s['median']:.2f}",
                    f"{stats[f'mink {n}']['median'] / s['median']:.2f}"]
        dof_rows.append(row)
    dof_header = ["DOF", "wbc median µs", "wbc p99 µs", "solve median µs", "solve %", f"vs {args.dofs[0]} DOF"]
    if not args.no_peers:
        dof_header += ["Pink median µs", "mink median µs", "Pink / wbc", "mink / wbc"]
    libraries = ["wbc"] + ([] if args.no_peers else ["Pink", "mink"])
    growth = {name: growth_exponents(args.dofs, [stats[f"{name} {n}"]["median"] for n in args.dofs])
              for name in libraries}
    growth_rows = [[name, *(fmt_exponent(value) for value in growth[name])] for name in libraries]
    base_t = stats[f"{args.tasks[0]} tasks"]["median"]
    task_rows = [[n, 6 * n + 21, fmt(stats[f"{n} tasks"]["median"]), fmt(stats[f"{n} tasks"]["p99"]),
                  fmt(stats[f"{n} tasks"]["solve_median"]), f"{stats[f'{n} tasks']['median'] / base_t:.2f}"]
                 for n in args.tasks]
    versions = package_versions(["wbc", "pin", "daqp", "pin-pink", "mink", "mujoco", "numpy"])
    lines = ["# Scaling of the tick", "", f"Measured {machine_note()}. Command: `{command}`.", "",
             "Versions: " + ", ".join(f"{k} {v}" for k, v in versions.items()) + ".", "",
             f"{args.ticks} measured ticks per case after {args.warmup} warm-up ticks, in one process. DOF "
             f"sweep: at each DOF the libraries alternate in blocks of {args.block} ticks (random order each round, "
             "seeded); task sweep: the cases tick by tick in a random order.", "",
             "## Tick latency vs DOF (FrameTask + PostureTask + position and velocity limits)", "",
             markdown_table(dof_header, dof_rows), "",
             "Growth exponent (slope of log median tick vs log DOF; the tick ~ DOF^exponent):", "",
             markdown_table(["library", f"{args.dofs[0]}–{args.dofs[-1]} DOF", f"{LARGE}+ DOF"], growth_rows), "",
             "## Tick latency vs number of FrameTasks (24 DOF, + PostureTask)", "",
             markdown_table(["FrameTasks", "task rows", "median µs", "p99 µs", "solve median µs",
                             f"vs {args.tasks[0]} task"], task_rows), "", "![scaling](scaling.png)", ""]
    (args.out / "report.md").write_text("\n".join(lines))
    (args.out / "results.json").write_text(json.dumps({"machine": machine_note(), "command": command,
                                                       "versions": versions, "stats": stats,
                                                       "growth_exponents": growth}, indent=2))
    _plot(args, stats, args.out / "scaling.png")
    print("\n".join(lines[8:-2]))
    print(f"report written to {args.out / 'report.md'}")
    return 0


#: the second growth exponent fits the sizes from this DOF on
LARGE = 32


def growth_exponents(dofs: list[int], medians: list[float]) -> tuple[float | None, float | None]:
    """Slopes of least-squares lines through (log DOF, log median): over every size, and over the
    sizes >= :data:`LARGE` (None where fewer than two sizes)."""
    def slope(pairs: list[tuple[int, float]]) -> float | None:
        if len(pairs) < 2:
            return None
        x, y = np.log([n for n, _ in pairs]), np.log([t for _, t in pairs])
        return float(np.polyfit(x, y, 1)[0])

    pairs = list(zip(dofs, medians, strict=True))
    return slope(pairs), slope([(n, t) for n, t in pairs if n >= LARGE])


def fmt_exponent(value: float | None) -> str:
    return "-" if value is None else f"{value:.2f}"


def _plot(args, stats: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (left, right) = plt.subplots(1, 2, figsize=(11, 4))
    names = ["wbc"] + ([] if args.no_peers else ["Pink", "mink"])
    for name in names:
        left.plot(args.dofs, [stats[f"{name} {n}"]["median"] for n in args.dofs], "o-", label=f"{name} median")
    left.plot(args.dofs, [stats[f"wbc {n}"]["p99"] for n in args.dofs], "o:", label="wbc p99")
    left.plot(args.dofs, [stats[f"wbc {n}"]["solve_median"] for n in args.dofs], "s--", label="wbc: DAQP solve median")
    left.set_xlabel("DOF (nv)")
    left.set_ylabel("tick latency [µs]")
    left.set_yscale("log")
    left.grid(True, which="both", alpha=0.3)
    left.legend(fontsize=8)
    left.set_title("tick vs DOF", fontsize=9)
    right.plot(args.tasks, [stats[f"{n} tasks"]["median"] for n in args.tasks], "o-", label="median")
    right.plot(args.tasks, [stats[f"{n} tasks"]["p99"] for n in args.tasks], "o:", label="p99")
    right.plot(args.tasks, [stats[f"{n} tasks"]["solve_median"] for n in args.tasks], "s--", label="DAQP solve median")
    right.set_xlabel("FrameTasks (24 DOF)")
    right.set_ylabel("tick latency [µs]")
    right.grid(True, alpha=0.3)
    right.legend(fontsize=8)
    right.set_title("wbc tick vs number of tasks", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


if __name__ == "__main__":
    sys.exit(main())
