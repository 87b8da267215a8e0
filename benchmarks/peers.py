"""wbc vs Pink vs mink on the same youBot task stack, interleaved tick by tick in one process.

    python -m benchmarks.peers [--scenarios youbot_circle youbot_reach] [--repeats 3]
                               [--out benchmarks/output/peers]

For each scenario (FrameTask + PostureTask + position limits + velocity limits, taken
from ``tasks/<name>.toml``; see :mod:`benchmarks.peer_setups` for how every peer is set
up to solve the same QP) two passes run:

1. **shared q** (timed, ``--repeats`` times after a warm-up): at every tick all
   controllers get the same target and the same configuration q (driven by wbc's
   command), in an order rotated each tick; the wall time of each ``step(q)`` call is
   recorded (kinematics update + QP assembly + DAQP solve + whatever the library adds)
   and every command is compared with wbc's;
2. **own closed loop**: each controller integrates its own commands (interleaved as
   well); tracking error of the tool (position, orientation) against the reference.

Controllers: ``wbc`` (stock FrameTask, world-axis speed box), ``wbc (log6 task)``
(FrameTask with the peers' log6 error: the peers' exact QP), ``wbc (scenario stack)``
(the scenario's own constraints: base-frame speed rows + mecanum wheel limits; timed
only, to show what the full stack costs), ``hand-rolled`` (Pinocchio + DAQP in 30 lines:
a floor for a Python tick), ``Pink``, ``mink``. Targets are poses only (no feed-forward
twist, which the peers' FrameTask does not take).

Output: ``report.md``, ``results.json``, ``latency.png``, ``agreement.png`` in ``--out``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
import pinocchio as pin

import wbc
from wbc.scenario import load_scenario

from .common import OUTPUT, TASKS, fmt, machine_note, markdown_table, package_versions, percentiles_us, progress
from .peer_setups import HandRolledSetup, Log6FrameTask, MinkSetup, PinkSetup, StackSpec, WbcSetup, spec_from_scenario

WBC, LOG6, FULL, HAND = "wbc", "wbc (log6 task)", "wbc (scenario stack)", "hand-rolled pinocchio + daqp"
BARRIER = "wbc (scenario stack + barrier)"


def _with_barrier(scenario) -> wbc.Controller:
    """The scenario's controller (own task objects) plus a manipulability barrier on its frame
    task, with m_min small enough to stay inactive on these motions: its cost is what is measured."""
    fresh = load_scenario(scenario.source)
    barrier = wbc.ManipulabilityBarrier(fresh.reference_task.frame, min_value=1e-3, gain=0.3)
    return wbc.Controller(fresh.robot, fresh.tasks, fresh.constraints + [barrier], solver="daqp",
                          dt=fresh.dt, damping=fresh.damping)


def make_setups(scenario, spec: StackSpec, peers: bool = True) -> list:
    setups = [WbcSetup(spec, WBC), WbcSetup(spec, LOG6, Log6FrameTask),
              WbcSetup(spec, FULL, controller=scenario.make_controller("daqp")),
              WbcSetup(spec, BARRIER, controller=_with_barrier(scenario)), HandRolledSetup(spec, HAND)]
    if peers:
        setups += [PinkSetup(spec), MinkSetup(spec)]
    return setups


def shared_q_pass(scenario, setups: list, ticks: int, record: bool = True) -> dict:
    """All setups step the same q (driven by wbc) each tick; times and commands per setup."""
    robot, dt = scenario.robot, scenario.dt
    names = [s.name for s in setups]
    times = {name: np.zeros(ticks) for name in names}
    commands = {name: np.zeros((ticks, robot.nv)) for name in names}
    errors = np.zeros((ticks, 2))  # world-aligned position / orientation error of wbc's tool
    configurations = np.zeros((ticks, robot.nq))
    q = scenario.q0.copy()
    clock = time.perf_counter
    for k in range(ticks):
        pose = np.array(scenario.reference(k * dt)[0])
        shift = k % len(setups)
        for setup in setups[shift:] + setups[:shift]:
            setup.set_target(pose)
            start = clock()
            v = setup.step(q)
            elapsed = clock() - start
            times[setup.name][k] = elapsed
            commands[setup.name][k] = v
        if record:
            errors[k] = _pose_error(robot, q, pose)
            configurations[k] = q
        q = robot.integrate(q, commands[WBC][k], dt)
    return {"times": times, "commands": commands, "errors": errors, "q": configurations}


def own_loop_pass(scenario, setups: list, ticks: int) -> dict:
    """Each setup integrates its own command; tracking errors per setup."""
    robot, dt = scenario.robot, scenario.dt
    qs = {s.name: scenario.q0.copy() for s in setups}
    errors = {s.name: np.zeros((ticks, 2)) for s in setups}
    failures: dict[str, str] = {}
    for k in range(ticks):
        pose = np.array(scenario.reference(k * dt)[0])
        for setup in setups:
            if setup.name in failures:
                continue
            q = qs[setup.name]
            errors[setup.name][k] = _pose_error(robot, q, pose)
            setup.set_target(pose)
            try:
                v = setup.step(q)
            except Exception as exc:  # noqa: BLE001 - a failing peer is reported, not fatal
                failures[setup.name] = f"tick {k}: {type(exc).__name__}: {exc}"
                continue
            qs[setup.name] = robot.integrate(q, v, dt)
    return {"errors": errors, "failures": failures}


def _pose_error(robot, q: np.ndarray, pose: np.ndarray) -> tuple[float, float]:
    current = robot.frame_pose(q, "ee")
    return (float(np.linalg.norm(pose[:3, 3] - current[:3, 3])),
            float(np.linalg.norm(pin.log3(pose[:3, :3] @ current[:3, :3].T))))


def run_scenario(path: Path, repeats: int, warmup: int, peers: bool, show_progress: bool) -> dict:
    from wbc.scenario import load_scenario

    scenario = load_scenario(path)
    spec = spec_from_scenario(scenario)
    setups = make_setups(scenario, spec, peers)
    names = [s.name for s in setups]
    shared_q_pass(scenario, setups, min(warmup, scenario.ticks), record=False)  # warm-up, discarded
    times = {name: [] for name in names}
    shared = None
    iterator = range(repeats)
    if show_progress:
        iterator = progress(iterator, desc=f"peers {scenario.name}", unit="run")
    for _ in iterator:
        shared = shared_q_pass(scenario, setups, scenario.ticks)
        for name in names:
            times[name].append(shared["times"][name])
    # the closed loop starts the peers from scratch (fresh setups, same spec)
    own = own_loop_pass(scenario, make_setups(scenario, spec, peers), scenario.ticks)
    return {"scenario": scenario, "spec": spec, "names": names,
            "times": {name: np.concatenate(values) for name, values in times.items()},
            "commands": shared["commands"], "wbc_errors": shared["errors"], "q": shared["q"], "own": own,
            "diagnosis": diagnose(scenario, spec, shared, peers)}


#: below this orientation error mink 1.3's SE3.jlog() takes its small-angle branch (theta^2 < 1e-10)
MINK_SMALL_ANGLE = 1e-5


def _mink_exact_jlog_task(spec: StackSpec):
    """mink's FrameTask with the exact SE(3) log Jacobian (pinocchio's Jlog6), for the diagnosis only."""
    import mink

    class ExactJlogFrameTask(mink.FrameTask):
        def compute_jacobian(self, configuration):
            body = configuration.get_frame_jacobian(self.frame_name, self.frame_type)
            pose = configuration.get_transform_frame_to_world(self.frame_name, self.frame_type).as_matrix()
            target_to_body = pin.SE3(self.transform_target_to_world.as_matrix()).actInv(pin.SE3(pose))
            return -pin.Jlog6(target_to_body) @ body

        def _error_and_jacobian(self, configuration):  # mink's fused path (used by build_ik)
            return self.compute_error(configuration), self.compute_jacobian(configuration)

    return ExactJlogFrameTask(spec.mjcf_site, "site", position_cost=float(np.sqrt(spec.position_cost)),
                              orientation_cost=float(np.sqrt(spec.orientation_cost)), gain=spec.gain, lm_damping=0.0)


def diagnose(scenario, spec: StackSpec, shared: dict, peers: bool, threshold: float = 1e-9,
             max_ticks: int = 300) -> dict:
    """Explain the peers' differences to ``wbc (log6 task)`` (their exact QP in wbc).

    * re-solve each peer's own QP (``build_ik``) at the ticks where it differs by more than
      ``threshold``, with DAQP's primal tolerance tightened from 1e-6 to 1e-9 (the peers
      solve for dq = v dt, so the default 1e-6 on dq allows 1e-6/dt on v);
    * split the remaining difference by the tool's orientation error (mink's small-angle branch).
    """
    if not peers:
        return {}
    import mink
    import pink
    import qpsolvers

    out = {}
    commands, theta = shared["commands"], shared["errors"][:, 1]
    for setup in (PinkSetup(spec), MinkSetup(spec)):
        diff = np.abs(commands[setup.name] - commands[LOG6]).max(axis=1)
        ticks = np.flatnonzero(diff > threshold)
        sample = ticks[np.linspace(0, ticks.size - 1, min(ticks.size, max_ticks)).astype(int)] if ticks.size else ticks
        tight = np.zeros(sample.size)
        build = pink.build_ik if setup.name == "Pink" else mink.build_ik
        for i, k in enumerate(sample):
            setup.set_target(np.array(scenario.reference(k * scenario.dt)[0]))
            setup.configuration.update(shared["q"][k])
            problem = build(setup.configuration, setup.tasks, spec.dt, damping=spec.damping, limits=setup.limits)
            solution = qpsolvers.solve_problem(problem, "daqp", primal_tol=1e-9)
            tight[i] = np.abs(solution.x / spec.dt - commands[LOG6][k]).max()
        small = theta < MINK_SMALL_ANGLE
        exact = np.zeros(sample.size)
        if setup.name == "mink":  # same QP with pinocchio's Jlog6 in place of mink's SE3.jlog()
            setup.task = setup.tasks[0] = _mink_exact_jlog_task(spec)
            for i, k in enumerate(sample):
                setup.set_target(np.array(scenario.reference(k * scenario.dt)[0]))
                setup.configuration.update(shared["q"][k])
                problem = mink.build_ik(setup.configuration, setup.tasks, spec.dt, damping=spec.damping,
                                        limits=setup.limits)
                solution = qpsolvers.solve_problem(problem, "daqp", primal_tol=1e-9)
                exact[i] = np.abs(solution.x / spec.dt - commands[LOG6][k]).max()
        out[setup.name] = {
            "max_tight_tol_exact_jlog": float(exact.max()) if setup.name == "mink" and sample.size else None,
            "ticks_above_threshold": int(ticks.size), "resolved_ticks": int(sample.size),
            "max_default_tol": float(diff[sample].max()) if sample.size else 0.0,
            "max_tight_tol": float(tight.max()) if sample.size else 0.0,
            "max_tight_tol_small_angle": float(tight[small[sample]].max()) if np.any(small[sample]) else 0.0,
            "max_tight_tol_large_angle": float(tight[~small[sample]].max()) if np.any(~small[sample]) else 0.0,
            "ticks_small_angle": int(small.sum()),
        }
    return out


# ------------------------------------------------------------------------ report
def agreement(commands: dict, name: str, against: str) -> dict:
    diff = np.abs(commands[name] - commands[against]).max(axis=1)
    scale = np.maximum(np.abs(commands[against]).max(axis=1), 1e-12)
    return {"max": float(diff.max()), "median": float(np.median(diff)), "p99": float(np.percentile(diff, 99)),
            "relative_max": float((diff / scale).max()), "argmax_tick": int(diff.argmax()), "per_tick": diff}


def scenario_summary(result: dict) -> dict:
    times, names = result["times"], result["names"]
    base = percentiles_us(times[WBC])
    latency = {}
    for name in names:
        stats = percentiles_us(times[name])
        stats["median_ratio_vs_wbc"] = stats["median"] / base["median"]
        stats["p99_ratio_vs_wbc"] = stats["p99"] / base["p99"]
        # per-tick ratio on the same q at the same moment: robust to drifts of the machine
        stats["per_tick_ratio_median"] = float(np.median(times[name] / times[WBC]))
        latency[name] = stats
    commands = result["commands"]
    agree = {name: {"vs_wbc": agreement(commands, name, WBC), "vs_log6": agreement(commands, name, LOG6)}
             for name in names}
    tracking = {}
    for name, errors in result["own"]["errors"].items():
        tracking[name] = {"position_rms_mm": float(np.sqrt(np.mean(errors[:, 0] ** 2)) * 1e3),
                          "position_max_mm": float(errors[:, 0].max() * 1e3),
                          "orientation_rms_mrad": float(np.sqrt(np.mean(errors[:, 1] ** 2)) * 1e3),
                          "final_position_mm": float(errors[-1, 0] * 1e3)}
    return {"latency": latency, "agreement": agree, "tracking": tracking, "failures": result["own"]["failures"]}


def report_scenario(result: dict, summary: dict) -> list[str]:
    sc, names = result["scenario"], result["names"]
    lat = summary["latency"]
    lines = [f"## {sc.name}", "",
             f"{sc.ticks} ticks × {len(result['times'][WBC]) // sc.ticks} repeats, dt = {sc.dt} s, "
             f"damping {sc.damping}; costs/gains from `tasks/{sc.source.name}`.", "",
             "### Tick latency (shared q, interleaved)", "",
             markdown_table(["controller", "min µs", "median µs", "p90 µs", "p99 µs", "max µs",
                             "median / wbc", "p99 / wbc", "per-tick ratio (median)"],
                            [[n, fmt(lat[n]["min"]), fmt(lat[n]["median"]), fmt(lat[n]["p90"]), fmt(lat[n]["p99"]),
                              fmt(lat[n]["max"]), f"{lat[n]['median_ratio_vs_wbc']:.2f}",
                              f"{lat[n]['p99_ratio_vs_wbc']:.2f}", f"{lat[n]['per_tick_ratio_median']:.2f}"]
                             for n in names]), ""]
    agree = summary["agreement"]
    lines += ["### Command agreement (shared q; ‖Δv‖∞ per tick, [m/s, rad/s])", "",
              markdown_table(["controller", "vs wbc: max", "median", "p99", "max relative",
                              "vs wbc (log6 task): max", "median"],
                             [[n, f"{agree[n]['vs_wbc']['max']:.1e}", f"{agree[n]['vs_wbc']['median']:.1e}",
                               f"{agree[n]['vs_wbc']['p99']:.1e}", f"{agree[n]['vs_wbc']['relative_max']:.1e}",
                               f"{agree[n]['vs_log6']['max']:.1e}", f"{agree[n]['vs_log6']['median']:.1e}"]
                              for n in names]), ""]
    track = summary["tracking"]
    lines += ["### Tracking (each controller in its own closed loop)", "",
              markdown_table(["controller", "position rms mm", "position max mm", "orientation rms mrad",
                              "final position mm"],
                             [[n, f"{track[n]['position_rms_mm']:.3f}", f"{track[n]['position_max_mm']:.3f}",
                               f"{track[n]['orientation_rms_mrad']:.3f}", f"{track[n]['final_position_mm']:.2e}"]
                              for n in names]), ""]
    diagnosis = result.get("diagnosis") or {}
    if diagnosis:
        lines += ["### Diagnosis of the peers' differences to `wbc (log6 task)`", "",
                  "Each peer's own QP (`build_ik`) re-solved at the ticks where it differs by more than 1e-9, "
                  "with DAQP's primal tolerance 1e-9 instead of its default 1e-6 (which applies to dq = v·dt "
                  f"in the peers, i.e. {1e-6 / sc.dt:.0e} on v); the rest split by the tool's orientation error "
                  f"(below {MINK_SMALL_ANGLE:g} rad mink's SE3 `jlog` takes its small-angle branch).", "",
                  markdown_table(["peer", "ticks > 1e-9", "re-solved", "max ‖Δv‖∞ default tol",
                                  "max ‖Δv‖∞ primal_tol 1e-9", f"… ticks with θ < {MINK_SMALL_ANGLE:g}",
                                  f"… ticks with θ ≥ {MINK_SMALL_ANGLE:g}", "… with exact Jlog6 (mink)"],
                                 [[name, d["ticks_above_threshold"], d["resolved_ticks"],
                                   f"{d['max_default_tol']:.1e}", f"{d['max_tight_tol']:.1e}",
                                   f"{d['max_tight_tol_small_angle']:.1e}", f"{d['max_tight_tol_large_angle']:.1e}",
                                   "-" if d["max_tight_tol_exact_jlog"] is None
                                   else f"{d['max_tight_tol_exact_jlog']:.1e}"]
                                  for name, d in diagnosis.items()]), ""]
    for name, failure in summary["failures"].items():
        lines += [f"- {name} failed in its own closed loop at {failure}"]
    return lines


def plot(results: list[dict], out: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(results), figsize=(6.5 * len(results), 4.2), squeeze=False)
    for ax, result in zip(axes[0], results, strict=True):
        for name in result["names"]:
            values = np.sort(result["times"][name]) * 1e6
            ax.plot(values, np.linspace(0, 1, values.size), label=name)
        ax.set_xscale("log")
        ax.set_xlabel("tick latency [µs]")
        ax.set_ylabel("fraction of ticks")
        ax.set_title(f"{result['scenario'].name}: latency CDF (shared q, interleaved)", fontsize=9)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out / "latency.png", dpi=120)
    plt.close(fig)

    fig, axes = plt.subplots(2, len(results), figsize=(6.5 * len(results), 6.5), squeeze=False)
    for column, result in enumerate(results):
        sc, commands = result["scenario"], result["commands"]
        t = np.arange(sc.ticks) * sc.dt
        for row, against in enumerate((WBC, LOG6)):
            ax = axes[row, column]
            for name in result["names"]:
                if name in (against, FULL):
                    continue
                diff = np.abs(commands[name] - commands[against]).max(axis=1)
                ax.semilogy(t, np.maximum(diff, 1e-17), label=name, lw=0.8)
            ax.set_title(f"{sc.name}: ‖v − v[{against}]‖∞", fontsize=9)
            ax.set_xlabel("t [s]")
            ax.grid(True, which="both", alpha=0.3)
            ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out / "agreement.png", dpi=120)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.peers", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scenarios", nargs="+", default=["youbot_circle", "youbot_reach"],
                        help="youBot scenario names in tasks/ (default: %(default)s)")
    parser.add_argument("--repeats", type=int, default=3, help="timed runs of each scenario (default 3)")
    parser.add_argument("--warmup", type=int, default=200, help="warm-up ticks, discarded (default 200)")
    parser.add_argument("--no-peers", action="store_true", help="wbc variants only (Pink/mink not installed)")
    parser.add_argument("--out", type=Path, default=OUTPUT / "peers")
    parser.add_argument("--no-progress", action="store_true")
    args = parser.parse_args(argv)
    command = "python -m benchmarks.peers " + " ".join(argv if argv is not None else sys.argv[1:])
    args.out.mkdir(parents=True, exist_ok=True)
    results, summaries = [], {}
    for name in args.scenarios:
        result = run_scenario(TASKS / f"{name}.toml", args.repeats, args.warmup, not args.no_peers,
                              not args.no_progress)
        results.append(result)
        summaries[name] = scenario_summary(result)
    versions = package_versions(["wbc", "pin", "pin-pink", "mink", "mujoco", "qpsolvers", "daqp", "numpy"])
    lines = ["# wbc vs Pink vs mink", "", f"Measured {machine_note()}. Command: `{command}`.", "",
             "Versions: " + ", ".join(f"{k} {v}" for k, v in versions.items()) + ".", "",
             "Same task stack, gains, costs, dt, damping and solver (DAQP) in every controller; all stepped on "
             "the same q in one process, order rotated each tick. Ratios > 1: slower than wbc. "
             "'per-tick ratio' is the median over ticks of (controller time / wbc time at the same tick). "
             "See benchmarks/README.md for the setup mapping and the explained differences.", ""]
    for result in results:
        lines += report_scenario(result, summaries[result["scenario"].name])
    lines += ["![latency](latency.png)", "", "![agreement](agreement.png)", ""]
    (args.out / "report.md").write_text("\n".join(lines))
    serial = {name: {"latency": s["latency"], "tracking": s["tracking"], "failures": s["failures"],
                     "diagnosis": next(r["diagnosis"] for r in results if r["scenario"].name == name),
                     "agreement": {n: {k: {m: x for m, x in a.items() if m != "per_tick"} for k, a in d.items()}
                                   for n, d in s["agreement"].items()}}
              for name, s in summaries.items()}
    (args.out / "results.json").write_text(json.dumps({"machine": machine_note(), "command": command,
                                                       "versions": versions, "scenarios": serial}, indent=2))
    plot(results, args.out)
    print("\n".join(lines[6:-4]))
    print(f"report written to {args.out / 'report.md'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
