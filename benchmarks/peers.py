"""wbc vs Pink, mink and placo on the same youBot task stack, interleaved tick by tick in one process.

    python -m benchmarks.peers [--scenarios youbot_circle youbot_reach] [--repeats 3]
                               [--placo-python PATH] [--out benchmarks/output/peers]

For each scenario (FrameTask + PostureTask + position limits + velocity limits, taken
from ``tasks/<name>.toml``; see :mod:`benchmarks.peer_setups` for how every peer is set
up to solve the same QP) two passes run:

1. **shared q** (timed, ``--repeats`` times after a warm-up): at every tick all
   controllers get the same target and the same configuration q (driven by wbc's
   command), in a random order each tick (seeded; every controller follows every other
   equally often: under a fixed rotation wbc always followed mink, whose Python and
   MuJoCo work evicts the caches, and paid ~3 µs a tick for it); the wall time of each
   ``step(q)`` call is recorded (kinematics update + QP assembly + DAQP solve + whatever
   the library adds) and every command is compared with wbc's;
2. **own closed loop**: each controller integrates its own commands (interleaved as
   well); tracking error of the tool (position, orientation) against the reference.

Controllers: ``wbc`` (stock FrameTask, world-axis speed box), ``wbc (log6 task)``
(FrameTask with the peers' log6 error: the peers' exact QP), ``wbc (scenario stack)``
(the scenario's own constraints: base-frame speed rows + mecanum wheel limits; timed
only, to show what the full stack costs), ``hand-rolled`` (Pinocchio + DAQP in 30 lines:
a floor for a Python tick), ``Pink``, ``mink``. Targets are poses only (no feed-forward
twist, which the peers' FrameTask does not take).

**placo** runs in this process when ``import placo`` works here (it then joins both passes
like Pink and mink); else in the interpreter given by ``--placo-python`` (default: the
environment variable ``WBC_PLACO_PYTHON``), e.g. a venv of its own, since placo ships its own
Pinocchio build (:mod:`benchmarks.placo_peer`); else it is reported as "not run" with the
reason. When it runs, ``wbc (placo's QP)`` (wbc with placo's fixed gains 1: the same QP)
joins both passes, and a third pass runs:

3. **placo alternation** (``--repeats`` times): tight-loop runs over the shared pass's
   configurations and targets, alternating ``wbc``, ``wbc (placo's QP)`` and placo (in its
   own process: a fresh one per run); a tick is ``set_target`` + ``step(q)`` (placo: set the
   target, q in, ``update_kinematics``, ``solve(True)``, which integrates). The first placo
   run also gives placo's commands (agreement) and its own closed loop (tracking).

Output: ``report.md``, ``results.json``, ``latency.png``, ``agreement.png`` in ``--out``.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin

import wbc
from wbc.app.scenario import load_scenario

from . import placo_peer
from .common import OUTPUT, ROOT, TASKS, fmt, machine_note, markdown_table, package_versions, percentiles_us, progress
from .peer_setups import (
    HandRolledSetup,
    Log6FrameTask,
    MinkSetup,
    PinkSetup,
    PlacoSetup,
    StackSpec,
    WbcSetup,
    placo_gains,
    placo_stack,
    spec_from_scenario,
)

WBC, LOG6, FULL, HAND = "wbc", "wbc (log6 task)", "wbc (scenario stack)", "hand-rolled pinocchio + daqp"
BARRIER = "wbc (scenario stack + barrier)"
PLACO, PLACO_QP = "placo", "wbc (placo's QP)"


@dataclass(frozen=True)
class Placo:
    """Where placo runs: ``python`` None = in this process; ``status`` says how, or why not."""

    status: str
    python: str | None = None
    version: str = "-"

    @property
    def runs(self) -> bool:
        return not self.status.startswith("not run")

    @property
    def in_process(self) -> bool:
        return self.runs and self.python is None


_PROBE = "import numpy, placo\nfrom importlib.metadata import version\nprint(version('placo'))"


def find_placo(python: str | None) -> Placo:
    """placo in this interpreter if ``import placo`` works, else in ``python``, else not run (with the reason)."""
    try:
        import placo  # noqa: F401
    except Exception as exc:  # noqa: BLE001 - any failure to import means: not here
        here = f"{type(exc).__name__}: {exc}"
    else:
        return Placo("in this process", None, package_versions(["placo"])["placo"])
    if not python:
        return Placo(f"not run: `import placo` fails here ({here}) and neither --placo-python nor "
                     "WBC_PLACO_PYTHON names a Python with placo")
    try:
        probe = subprocess.run([python, "-c", _PROBE], capture_output=True, text=True, timeout=300, cwd=ROOT)
    except (OSError, subprocess.TimeoutExpired) as exc:
        return Placo(f"not run: {python}: {type(exc).__name__}: {exc}")
    if probe.returncode != 0:
        last = (probe.stderr.strip().splitlines() or [f"exit status {probe.returncode}"])[-1]
        return Placo(f"not run: {python} cannot import placo ({last})")
    return Placo(f"own process: {python}", python, probe.stdout.strip())


def reference_poses(scenario) -> np.ndarray:
    """(ticks, 4, 4) target poses of the scenario (the reference's buffer is reused: copied per tick)."""
    return np.array([np.array(scenario.reference(k * scenario.dt)[0]) for k in range(scenario.ticks)])


def _with_barrier(scenario) -> wbc.Controller:
    """The scenario's controller (own task objects) plus a manipulability barrier on its frame
    task, with m_min small enough to stay inactive on these motions: its cost is what is measured."""
    fresh = load_scenario(scenario.source)
    barrier = wbc.ManipulabilityBarrier(fresh.reference_task.frame, min_value=1e-3, gain=0.3)
    return wbc.Controller(fresh.robot, fresh.tasks, fresh.constraints + [barrier], solver="daqp",
                          dt=fresh.dt, damping=fresh.damping)


def make_setups(scenario, spec: StackSpec, peers: bool = True, placo: Placo | None = None) -> list:
    """The interleaved controllers; with placo running, also wbc on placo's QP (and placo if in process)."""
    setups = [WbcSetup(spec, WBC), WbcSetup(spec, LOG6, Log6FrameTask),
              WbcSetup(spec, FULL, controller=scenario.make_controller("daqp")),
              WbcSetup(spec, BARRIER, controller=_with_barrier(scenario)), HandRolledSetup(spec, HAND)]
    if placo is not None and placo.runs:
        setups.append(WbcSetup(placo_gains(spec), PLACO_QP))
    if peers:
        setups += [PinkSetup(spec), MinkSetup(spec)]
    if placo is not None and placo.in_process:
        setups.append(PlacoSetup(spec, PLACO))
    return setups


def shared_q_pass(scenario, setups: list, ticks: int, record: bool = True) -> dict:
    """All setups step the same q (driven by wbc) each tick, in a random order; times and commands per setup."""
    robot, dt = scenario.robot, scenario.dt
    order = np.random.default_rng(0)
    names = [s.name for s in setups]
    times = {name: np.zeros(ticks) for name in names}
    commands = {name: np.zeros((ticks, robot.nv)) for name in names}
    errors = np.zeros((ticks, 2))  # world-aligned position / orientation error of wbc's tool
    configurations = np.zeros((ticks, robot.nq))
    q = scenario.q0.copy()
    clock = time.perf_counter
    for k in range(ticks):
        pose = np.array(scenario.reference(k * dt)[0])
        for index in order.permutation(len(setups)):
            setup = setups[index]
            setup.set_target(pose)
            start = clock()
            v = setup.step(q)
            setup.integrate(q, v)  # each library integrates its own command (its result unused here)
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


def wbc_user_loop(setup: WbcSetup, q0: np.ndarray, ticks: int) -> tuple[np.ndarray, np.ndarray]:
    """wbc's loop as the README teaches it, from ``q0``: the circle target of
    :func:`benchmarks.placo_peer.user_loop` computed in the loop, ``set_target``, ``step``,
    ``robot.integrate``. The wall time of each tick, and the configuration after it (untimed)."""
    controller, task, robot, clock = setup.controller, setup.task, setup.controller.robot, time.perf_counter
    dt = controller.dt
    pose = robot.frame_pose(q0, task.frame)
    (cx, cy, radius, angle_step), sin, cos = placo_peer.circle(pose, dt), math.sin, math.cos
    times, configurations = np.zeros(ticks), np.zeros((ticks, q0.size))
    q = q0.copy()
    for k in range(ticks):
        start = clock()
        pose[0, 3] = cx + radius * sin(angle_step * k)
        pose[1, 3] = cy - radius * cos(angle_step * k)
        task.set_target(pose)
        v = controller.step(q)
        q = robot.integrate(q, v, dt)
        times[k] = clock() - start
        configurations[k] = q
    return times, configurations


def placo_input(spec: StackSpec, configurations: np.ndarray, targets: np.ndarray, warmup: int,
                closed_loop: bool, user_loop: int = 0) -> dict:
    """The input document of :mod:`benchmarks.placo_peer` (JSON-ready: lists, no arrays)."""
    return {"stack": placo_stack(spec),
            "run": {"configurations": configurations.tolist(), "targets": targets.tolist(), "warmup": warmup,
                    "closed_loop": closed_loop, "user_loop": user_loop}}


def run_placo(placo: Placo, spec: StackSpec, configurations: np.ndarray, targets: np.ndarray, warmup: int,
              closed_loop: bool, user_loop: int = 0) -> dict:
    """One placo run of :func:`benchmarks.placo_peer.run` (in this process or in placo's interpreter)."""
    if placo.in_process:
        return placo_peer.run(placo_stack(spec), {"configurations": configurations, "targets": targets,
                                                  "warmup": warmup, "closed_loop": closed_loop,
                                                  "user_loop": user_loop})
    document = placo_input(spec, configurations, targets, warmup, closed_loop, user_loop)
    process = subprocess.run([placo.python, "-m", "benchmarks.placo_peer"], input=json.dumps(document),
                             capture_output=True, text=True, cwd=ROOT)
    if process.returncode != 0:
        raise RuntimeError(f"placo_peer exited with {process.returncode}: {process.stderr.strip()[-2000:]}")
    return json.loads(process.stdout)


def placo_alternation(scenario, spec: StackSpec, placo: Placo, configurations: np.ndarray, repeats: int,
                      warmup: int) -> dict:
    """Tight-loop runs alternating wbc, wbc on placo's QP and placo, on the same q and targets.

    Returns the tick times per run (``runs``), placo's commands and closed loop of its first
    run, its versions, or ``failure`` when a placo run raised.
    """
    targets = reference_poses(scenario)
    warmup = min(warmup, len(targets))
    wbc_setups = [WbcSetup(spec, WBC), WbcSetup(placo_gains(spec), PLACO_QP)]
    runs: dict[str, list[np.ndarray]] = {WBC: [], PLACO_QP: [], PLACO: []}
    loops: dict[str, list[np.ndarray]] = {WBC: [], PLACO_QP: [], PLACO: []}
    out: dict = {"runs": runs, "user_loop": loops}
    q0, ticks = configurations[0], len(configurations)
    for repeat in range(repeats):
        for setup in wbc_setups:
            placo_peer.timed_ticks(setup, configurations[:warmup], targets[:warmup])
            runs[setup.name].append(placo_peer.timed_ticks(setup, configurations, targets)[0])
            wbc_user_loop(setup, q0, warmup)
            times, loop_q = wbc_user_loop(setup, q0, ticks)
            loops[setup.name].append(times)
            if setup.name == PLACO_QP:
                wbc_loop_q = loop_q
        try:
            result = run_placo(placo, spec, configurations, targets, warmup, closed_loop=repeat == 0,
                               user_loop=ticks)
        except Exception as exc:  # noqa: BLE001 - a failing peer is reported, not fatal
            out["failure"] = f"run {repeat + 1}: {type(exc).__name__}: {exc}"
            break
        runs[PLACO].append(np.asarray(result["times"]))
        loops[PLACO].append(np.asarray(result["user_loop_times"]))
        # the same work: wbc on placo's QP and placo follow the same configurations
        difference = float(np.abs(np.asarray(result["user_loop_q"]) - wbc_loop_q).max())
        out["user_loop_max_q_difference"] = max(out.get("user_loop_max_q_difference", 0.0), difference)
        if repeat == 0:
            out.update(commands=np.asarray(result["commands"]), versions=result["versions"],
                       closed_loop_q=result.get("closed_loop_q"))
    return out


def run_scenario(path: Path, repeats: int, warmup: int, peers: bool, show_progress: bool,
                 placo: Placo | None = None) -> dict:
    from wbc.app.scenario import load_scenario

    scenario = load_scenario(path)
    spec = spec_from_scenario(scenario)
    setups = make_setups(scenario, spec, peers, placo)
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
    own = own_loop_pass(scenario, make_setups(scenario, spec, peers, placo), scenario.ticks)
    commands = dict(shared["commands"])
    alternation = None
    if placo is not None and placo.runs:
        alternation = placo_alternation(scenario, spec, placo, shared["q"], repeats, warmup)
        if not placo.in_process and "commands" in alternation:  # in process, placo took part in both passes
            commands[PLACO] = alternation["commands"]
            reference = reference_poses(scenario)
            own["errors"][PLACO] = np.array([_pose_error(scenario.robot, np.asarray(q), pose)
                                             for q, pose in zip(alternation["closed_loop_q"], reference, strict=True)])
    return {"scenario": scenario, "spec": spec, "names": names,
            "times": {name: np.concatenate(values) for name, values in times.items()},
            "commands": commands, "wbc_errors": shared["errors"], "q": shared["q"], "own": own,
            "diagnosis": diagnose(scenario, spec, shared, peers), "placo": alternation}


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
             for name in commands}
    if PLACO_QP in commands:
        for name in commands:
            agree[name]["vs_placo_qp"] = agreement(commands, name, PLACO_QP)
    tracking = {}
    for name, errors in result["own"]["errors"].items():
        tracking[name] = {"position_rms_mm": float(np.sqrt(np.mean(errors[:, 0] ** 2)) * 1e3),
                          "position_max_mm": float(errors[:, 0].max() * 1e3),
                          "orientation_rms_mrad": float(np.sqrt(np.mean(errors[:, 1] ** 2)) * 1e3),
                          "final_position_mm": float(errors[-1, 0] * 1e3)}
    return {"latency": latency, "agreement": agree, "tracking": tracking, "failures": result["own"]["failures"],
            "placo": placo_summary(result["placo"])}


def placo_summary(alternation: dict | None) -> dict | None:
    """Percentiles per run and over all runs, and the per-run ratios of wbc's medians and p99 to placo's."""
    if alternation is None:
        return None
    out = {"failure": alternation.get("failure"), "versions": alternation.get("versions", {}),
           **_runs_summary(alternation["runs"])}
    out["user_loop"] = _runs_summary(alternation["user_loop"])
    out["user_loop"]["max_q_difference"] = alternation.get("user_loop_max_q_difference")
    return out


def _runs_summary(runs: dict[str, list[np.ndarray]]) -> dict:
    out = {"runs": {name: [percentiles_us(times) for times in values] for name, values in runs.items()},
           "all": {name: percentiles_us(np.concatenate(values)) for name, values in runs.items() if values},
           "median_ratio_vs_placo": {}, "p99_ratio_vs_placo": {}, "fastest_ratio_vs_placo": {}}
    placo_runs = out["runs"][PLACO]
    for name in (WBC, PLACO_QP):
        for key in ("median", "p99"):
            # strict=False: a placo run that failed leaves its wbc runs without a partner
            out[f"{key}_ratio_vs_placo"][name] = [run[key] / placo[key] for run, placo
                                                  in zip(out["runs"][name], placo_runs, strict=False)]
        # a host whose speed swings between runs only ever slows one: the fastest run of each side is
        # the nearest to its own speed, whichever runs the slow stretches fell on
        if placo_runs and out["runs"][name]:
            out["fastest_ratio_vs_placo"][name] = (min(run["median"] for run in out["runs"][name])
                                                   / min(run["median"] for run in placo_runs))
    return out


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
    lines += report_placo(result, summary["placo"])
    agree = summary["agreement"]
    extra = [("vs_placo_qp", f"vs {PLACO_QP}: max", "median")] if PLACO_QP in result["commands"] else []
    lines += ["### Command agreement (shared q; ‖Δv‖∞ per tick, [m/s, rad/s])", "",
              markdown_table(["controller", "vs wbc: max", "median", "p99", "max relative",
                              "vs wbc (log6 task): max", "median"] + [h for _, *hs in extra for h in hs],
                             [[n, f"{agree[n]['vs_wbc']['max']:.1e}", f"{agree[n]['vs_wbc']['median']:.1e}",
                               f"{agree[n]['vs_wbc']['p99']:.1e}", f"{agree[n]['vs_wbc']['relative_max']:.1e}",
                               f"{agree[n]['vs_log6']['max']:.1e}", f"{agree[n]['vs_log6']['median']:.1e}"]
                              + [f"{agree[n][key][m]:.1e}" for key, *_ in extra for m in ("max", "median")]
                              for n in agree]), ""]
    track = summary["tracking"]
    lines += ["### Tracking (each controller in its own closed loop)", "",
              markdown_table(["controller", "position rms mm", "position max mm", "orientation rms mrad",
                              "final position mm"],
                             [[n, f"{track[n]['position_rms_mm']:.3f}", f"{track[n]['position_max_mm']:.3f}",
                               f"{track[n]['orientation_rms_mrad']:.3f}", f"{track[n]['final_position_mm']:.2e}"]
                              for n in track]), ""]
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


def _spread(values: list[float]) -> str:
    return f"{np.median(values):.2f} ({min(values):.2f}–{max(values):.2f})" if values else "-"


def _fastest(value: float | None) -> str:
    return "-" if value is None else f"{value:.2f}"


def report_placo(result: dict, summary: dict | None) -> list[str]:
    """The alternating runs of wbc and placo (the user's loop, then the tight loop on the shared
    pass's q), with the per-run ratios' spread."""
    if summary is None:
        return []
    ticks, loop = result["scenario"].ticks, summary["user_loop"]
    lines = ["### placo: the user's loop, alternating runs", "",
             f"{len(loop['runs'][PLACO])} runs of {ticks} ticks each (after a warm-up), order {WBC} → {PLACO_QP} → "
             f"{PLACO} (its own process). Each integrates its own command from the scenario's start, the target "
             f"computed in the loop: a {placo_peer.CIRCLE_RADIUS} m horizontal circle (period "
             f"{placo_peer.CIRCLE_PERIOD} s) from the tool's start pose. Tick: wbc `set_target(pose)` + "
             "`v = step(q)` + `q = robot.integrate(q, v, dt)` (the README's loop); placo `T_world_frame = pose` + "
             "`solve(True)` (which integrates) + `update_kinematics()`. "
             f"`{PLACO_QP}` is wbc with placo's fixed gains (1): the same QP; the largest difference of its "
             f"configurations to placo's over all runs: {_max_difference(loop['max_q_difference'])}.", ""]
    lines += _runs_table(loop, summary["failure"])
    lines += ["### placo: alternating tight-loop runs on the shared q", "",
              "The same alternation on the shared pass's configurations and targets. Tick: `set_target` + "
              "`step(q)` + the library's own integration (wbc `robot.integrate`; placo `T_world_frame` + q in + "
              "`update_kinematics()` + `solve(True)`, which integrates).", ""]
    return lines + _runs_table(summary, summary["failure"])


def _max_difference(value: float | None) -> str:
    return "-" if value is None else f"{value:.1e}"


def _runs_table(summary: dict, failure: str | None) -> list[str]:
    runs = summary["runs"]
    if not runs[PLACO]:
        return [f"placo failed: {failure}", ""]
    header = ["run"] + [f"{name} {key} µs" for name in (WBC, PLACO_QP, PLACO) for key in ("median", "p99")]
    rows = [[str(i + 1)] + [fmt(runs[name][i][key]) for name in (WBC, PLACO_QP, PLACO) for key in ("median", "p99")]
            for i in range(len(runs[PLACO]))]
    rows.append(["all"] + [fmt(summary["all"][name][key]) for name in (WBC, PLACO_QP, PLACO)
                           for key in ("median", "p99")])
    lines = [markdown_table(header, rows), ""]
    for name in (WBC, PLACO_QP):
        lines.append(f"- {name} / placo, median of the runs (min–max): median tick "
                     f"{_spread(summary['median_ratio_vs_placo'][name])}, p99 "
                     f"{_spread(summary['p99_ratio_vs_placo'][name])}; the fastest run of each "
                     f"{_fastest(summary['fastest_ratio_vs_placo'].get(name))}")
    if failure:
        lines.append(f"- placo failed at {failure}")
    return lines + [""]


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
            for name in commands:
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
    parser.add_argument("--placo-python", default=os.environ.get("WBC_PLACO_PYTHON"), metavar="PATH",
                        help="a Python that imports placo, when this one does not (default: $WBC_PLACO_PYTHON); "
                             "e.g. python3 -m venv /work/venv-placo && /work/venv-placo/bin/pip install placo numpy")
    parser.add_argument("--out", type=Path, default=OUTPUT / "peers")
    parser.add_argument("--no-progress", action="store_true")
    args = parser.parse_args(argv)
    command = "python -m benchmarks.peers " + " ".join(argv if argv is not None else sys.argv[1:])
    args.out.mkdir(parents=True, exist_ok=True)
    placo = find_placo(args.placo_python)
    results, summaries = [], {}
    for name in args.scenarios:
        result = run_scenario(TASKS / f"{name}.toml", args.repeats, args.warmup, not args.no_peers,
                              not args.no_progress, placo)
        results.append(result)
        summaries[name] = scenario_summary(result)
    versions = package_versions(["wbc", "pin", "pin-pink", "mink", "mujoco", "qpsolvers", "daqp", "numpy"])
    versions["placo"] = placo.version
    placo_versions = next((s["placo"]["versions"] for s in summaries.values() if s["placo"] and s["placo"]["versions"]),
                          {})
    placo_note = f"placo: {placo.status}" + (
        f" (placo {placo_versions.get('placo')}, pin {placo_versions.get('pin')}, "
        f"numpy {placo_versions.get('numpy')})" if placo_versions and not placo.in_process else "")
    lines = ["# wbc vs Pink, mink and placo", "", f"Measured {machine_note()}. Command: `{command}`.", "",
             "Versions: " + ", ".join(f"{k} {v}" for k, v in versions.items()) + ".", "", placo_note + ".", "",
             "Same task stack, gains, costs, dt, damping and solver (DAQP) in every controller; all stepped on "
             "the same q in one process, in a random order each tick. Ratios > 1: slower than wbc. "
             "'per-tick ratio' is the median over ticks of (controller time / wbc time at the same tick). "
             "See benchmarks/README.md for the setup mapping and the explained differences.", ""]
    for result in results:
        lines += report_scenario(result, summaries[result["scenario"].name])
    lines += ["![latency](latency.png)", "", "![agreement](agreement.png)", ""]
    (args.out / "report.md").write_text("\n".join(lines))
    serial = {name: {"latency": s["latency"], "tracking": s["tracking"], "failures": s["failures"],
                     "placo": s["placo"],
                     "diagnosis": next(r["diagnosis"] for r in results if r["scenario"].name == name),
                     "agreement": {n: {k: {m: x for m, x in a.items() if m != "per_tick"} for k, a in d.items()}
                                   for n, d in s["agreement"].items()}}
              for name, s in summaries.items()}
    (args.out / "results.json").write_text(json.dumps(
        {"machine": machine_note(), "command": command, "versions": versions,
         "placo": {"status": placo.status, "python": placo.python, "versions": placo_versions}, "scenarios": serial},
        indent=2))
    plot(results, args.out)
    print("\n".join(lines[6:-4]))
    print(f"report written to {args.out / 'report.md'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
