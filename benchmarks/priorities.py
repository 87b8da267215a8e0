"""Cost of strict priorities: the same youBot stack as one weighted level and as two (or three) levels.

    python -m benchmarks.priorities [tasks/youbot_circle.toml] [--repeats 5] [--ticks 2000] [--levels 3]

The scenario's reference task (the gripper's FrameTask) is level 0 of the strict controller and
every other task is level 1; the weighted controller has the same tasks in one level. With
``--levels 3`` every controller also has a second ``PostureTask(1e-4)`` -- in its last level, which for
the three-level controller is a level of its own. All step the same closed loop (the weighted
controller's q) tick by tick, in alternating order, so machine noise hits them alike; each
repeat reports the medians and their ratios to the one-level tick (the numbers to read), and
the summary the median ratio over the repeats with its spread.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

import wbc
from wbc.app.scenario import Scenario, load_scenario

ROOT = Path(__file__).resolve().parents[1]


def controllers(scenario: Scenario, levels: int = 2) -> dict[str, wbc.Controller]:
    """The scenario's tasks as one weighted level, and as two (the reference task over the rest);
    with ``levels = 3`` all three with a second PostureTask in their last level (its own level in the third)."""
    first = scenario.reference_task
    rest = [task for task in scenario.tasks if task is not first]
    extra = [wbc.PostureTask(1e-4, gain=0.02)] if levels == 3 else []  # compiled, as the rest of the stack
    settings = dict(solver=scenario.solver, dt=scenario.dt, damping=scenario.damping, reduced=scenario.reduced)
    robot, constraints = scenario.robot, scenario.constraints
    stacks = {"1 level": scenario.tasks + extra, "2 levels": [[first], rest + extra]}
    if levels == 3:
        stacks["3 levels"] = [[first], rest, extra]
    return {name: wbc.Controller(robot, tasks, constraints, **settings) for name, tasks in stacks.items()}


def measure(scenario: Scenario, ticks: int, levels: int = 2) -> tuple[dict[str, np.ndarray], dict[str, int]]:
    """Tick times [s] of the controllers along one closed loop of ``ticks`` ticks, and how many
    of their ticks the fallback chain answered."""
    pair = controllers(scenario, levels)
    names = list(pair)
    times = {name: np.zeros(ticks) for name in names}
    fallbacks = dict.fromkeys(names, 0)
    q = scenario.q0.copy()
    for k in range(ticks):
        scenario.reference_task.set_target(*scenario.reference(k * scenario.dt))
        order = names if k % 2 == 0 else names[::-1]
        for name in order:
            start = time.perf_counter()
            v = pair[name].step(q)
            times[name][k] = time.perf_counter() - start
            fallbacks[name] += not pair[name].last.success
            if name == names[0]:
                command = v
        q = scenario.robot.integrate(q, command, scenario.dt)
    return times, fallbacks


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("scenario", nargs="?", default=str(ROOT / "tasks" / "youbot_circle.toml"))
    parser.add_argument("--repeats", type=int, default=5, help="closed loops, each measuring both (default 5)")
    parser.add_argument("--ticks", type=int, default=2000, help="ticks per repeat (default 2000)")
    parser.add_argument("--warmup", type=int, default=200, help="first ticks of each repeat left out (default 200)")
    parser.add_argument("--levels", type=int, choices=(2, 3), default=2, help="strict levels compared (default 2)")
    args = parser.parse_args(argv)
    scenario = load_scenario(args.scenario)
    print(f"{scenario.name}: {args.repeats} repeats x {args.ticks} ticks, first {args.warmup} left out; "
          f"solver {scenario.solver}")
    ratios: dict[str, list[float]] = {}
    for repeat in range(args.repeats):
        times, fallbacks = measure(scenario, args.ticks, args.levels)
        medians = {name: float(np.median(values[args.warmup:])) * 1e6 for name, values in times.items()}
        p99 = {name: float(np.percentile(values[args.warmup:], 99)) * 1e6 for name, values in times.items()}
        one = medians["1 level"]
        for name in list(medians)[1:]:
            ratios.setdefault(name, []).append(medians[name] / one)
        print(f"repeat {repeat + 1}: " + ", ".join(f"{name} {medians[name]:.2f} µs (p99 {p99[name]:.1f})"
                                                   for name in medians)
              + "; ratios " + ", ".join(f"{ratios[name][-1]:.2f}" for name in ratios)
              + "; fallback ticks " + " / ".join(map(str, fallbacks.values())))
    for name, values in ratios.items():
        print(f"median ratio {name} / 1 level: {np.median(values):.2f} (min {min(values):.2f}, max {max(values):.2f})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
