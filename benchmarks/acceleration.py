"""Do acceleration limits oscillate? Sign changes of every joint's acceleration, per scenario.

    python -m benchmarks.acceleration [tasks/*.toml ...] [--threshold 1e-6] [--json FILE]

Every scenario runs in closed loop (``wbc.app.closed_loop.run``, kinematic) three ways:
``wbc`` (its own stack, without acceleration limits), ``wbc + accel`` (the same stack plus
``wbc.AccelerationLimits``) and, on the youBot scenarios whose stack Pink can reproduce
(:mod:`benchmarks.peer_setups`: FrameTask + PostureTask + position and velocity limits, a pose
reference), ``Pink`` and ``Pink + accel`` (``pink.limits.AccelerationLimit`` with the same limits,
fed the previous command through ``set_last_integration``). The limits: the model's sidecar
``[acceleration]`` table when it has one (youBot), else ``velocity_limit / 0.5 s`` (each joint
reaches its speed limit in half a second).

For each joint the acceleration ``a_k = (v_k - v_{k-1}) / dt`` (from rest) is reduced to its
signs where ``|v_k - v_{k-1}| > threshold`` (solver noise below it is no motion), and the sign
changes are counted: a smooth rest-to-rest move has one per joint (speed up, slow down), a
chattering joint one per tick. Reported per scenario: the sum over joints and the worst joint,
the largest ``|v_k - v_{k-1}| / (a_max dt)`` over the joints but the base x, y (<= 1 when the
limits held), ticks answered by a fallback (wbc: ``ELASTIC``, soft rows relaxed) or refused as
infeasible (Pink: the run stops there).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
from pathlib import Path
from typing import Any

import numpy as np

import wbc
from wbc.app.closed_loop import run
from wbc.app.scenario import Scenario, load_scenario

from .common import TASKS, scenario_files

SECONDS_TO_TOP_SPEED = 0.5  #: [s] the limits of a model without an [acceleration] table


def acceleration_limit(robot: wbc.Robot) -> np.ndarray | None:
    """None for the sidecar's table, else ``velocity_limit / SECONDS_TO_TOP_SPEED``."""
    if "acceleration" in robot.parameters:
        return None
    return robot.velocity_limit / SECONDS_TO_TOP_SPEED


def resolved_limit(robot: wbc.Robot) -> np.ndarray:
    """The per-coordinate limits AccelerationLimits uses (for the ratio and Pink)."""
    data = wbc.AccelerationLimits(acceleration_limit(robot)).bind(robot)
    limit = np.full(robot.nv, np.inf)  # base x, y: inf (base-frame rows)
    limit[data._joints] = data._accel[: data._n_joints]
    return limit


def pink_limit(robot: wbc.Robot, limit: np.ndarray) -> np.ndarray:
    """Pink's per-coordinate vector: the base-frame linear limit on the world x, y rates (Pink
    has no base-frame rows)."""
    pink = limit.copy()
    if robot.base.is_mobile:
        x, y, _ = robot.base.indices
        data = wbc.AccelerationLimits(acceleration_limit(robot)).bind(robot)
        if data._n_base:
            pink[[x, y]] = data._accel[data._n_joints:data._n_joints + 2]
    return np.where(np.isfinite(pink), pink, 1e30)


def sign_changes(vs: np.ndarray, threshold: float) -> np.ndarray:
    """Per joint: sign changes of ``v_k - v_{k-1}`` (from rest) over the steps above ``threshold``."""
    steps = np.diff(np.vstack([np.zeros(vs.shape[1]), vs]), axis=0)
    counts = np.zeros(vs.shape[1], dtype=int)
    for j in range(vs.shape[1]):
        signs = np.sign(steps[np.abs(steps[:, j]) > threshold, j])
        counts[j] = int(np.count_nonzero(signs[1:] != signs[:-1]))
    return counts


def worst_step_ratio(vs: np.ndarray, limit: np.ndarray, dt: float) -> float:
    """Largest ``|v_k - v_{k-1}| / (a_max dt)`` over the joints with a finite limit but the base x, y
    (their limit holds in the base frame, checked by tests/test_acceleration_limits.py)."""
    steps = np.abs(np.diff(np.vstack([np.zeros(vs.shape[1]), vs]), axis=0))
    finite = np.isfinite(limit)
    return float(np.max(steps[:, finite] / (limit[finite] * dt)))


def wbc_runs(path: Path) -> dict[str, tuple[np.ndarray, float, int]]:
    """(commands, dt, fallback ticks) of the scenario without and with AccelerationLimits."""
    runs = {}
    for name, accelerate in (("wbc", False), ("wbc + accel", True)):
        scenario = load_scenario(path)
        constraints = [c for c in scenario.constraints if not isinstance(c, wbc.AccelerationLimits)]
        if accelerate:
            constraints.append(wbc.AccelerationLimits(acceleration_limit(scenario.robot)))
        result = run(dataclasses.replace(scenario, constraints=constraints), max_rows=None)
        runs[name] = (result.v, scenario.dt, result.fallback_ticks)
    return runs


def pink_runs(path: Path, limit: np.ndarray) -> dict[str, tuple[np.ndarray, float, int]]:
    """Pink's own closed loop on the same stack, without and with its AccelerationLimit; {} when
    Pink is not installed or cannot reproduce the stack."""
    try:
        import pink  # noqa: F401
        from pink.limits import AccelerationLimit

        from .peer_setups import PinkSetup, spec_from_scenario
    except ImportError:
        return {}
    scenario = load_scenario(path)
    if scenario.robot.name != "youbot" or scenario.reference is None:
        return {}
    try:
        spec = spec_from_scenario(scenario)
    except (StopIteration, ValueError):
        return {}
    if np.shape(scenario.reference(0.0)[0]) != (4, 4):
        return {}
    runs = {}
    for name, accelerate in (("Pink", False), ("Pink + accel", True)):
        setup = PinkSetup(spec, name)
        accel = AccelerationLimit(setup.configuration.model, pink_limit(scenario.robot, limit))
        if accelerate:
            setup.limits.append(accel)
        q, vs, refused = scenario.q0.copy(), [], 0
        for k in range(scenario.ticks):
            setup.set_target(np.array(scenario.reference(k * scenario.dt)[0]))
            try:
                v = setup.step(q)
            except Exception:  # Pink raises NoSolutionFound on an infeasible QP: the run stops there
                refused = scenario.ticks - k
                break
            accel.set_last_integration(v, scenario.dt)
            vs.append(v)
            q = scenario.robot.integrate(q, v, scenario.dt)
        runs[name] = (np.array(vs).reshape(-1, scenario.robot.nv), scenario.dt, refused)
    return runs


def measure(path: Path, threshold: float) -> dict[str, Any]:
    scenario: Scenario = load_scenario(path)
    limit = resolved_limit(scenario.robot)
    runs = {**wbc_runs(path), **pink_runs(path, limit)}
    rows = {}
    for name, (vs, dt, failed) in runs.items():
        counts = sign_changes(vs, threshold)
        rows[name] = {"sign_changes": int(counts.sum()), "worst_joint": int(counts.max()) if counts.size else 0,
                      "worst_joint_name": scenario.robot.joint_names[int(np.argmax(counts))] if counts.size else "",
                      "max_step_over_a_dt": worst_step_ratio(vs, limit, dt) if len(vs) else float("nan"),
                      "failed_ticks": failed, "ticks": len(vs)}
    return {"scenario": scenario.name, "robot": scenario.robot.name, "runs": rows}


def report(results: list[dict[str, Any]]) -> str:
    lines = ["| scenario | controller | sign changes (sum) | worst joint | max abs(dv)/(a dt) | failed ticks |",
             "|---|---|---:|---:|---:|---:|"]
    for result in results:
        for name, row in result["runs"].items():
            lines.append(f"| {result['scenario']} | {name} | {row['sign_changes']} | {row['worst_joint']} "
                         f"({row['worst_joint_name']}) | {row['max_step_over_a_dt']:.2f} | {row['failed_ticks']} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scenarios", nargs="*", type=Path, help="scenario files (default: every tasks/*.toml)")
    parser.add_argument("--threshold", type=float, default=1e-6, help="smallest |v_k - v_{k-1}| counted [unit/s]")
    parser.add_argument("--json", type=Path, help="also write the results as JSON")
    args = parser.parse_args(argv)
    results = [measure(path, args.threshold) for path in (args.scenarios or scenario_files(TASKS))]
    print(report(results))
    if args.json:
        args.json.write_text(json.dumps(results, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
