"""Cost of strict priorities: the same youBot stack as one weighted level and as two levels.

    python -m benchmarks.priorities [tasks/youbot_circle.toml] [--repeats 5] [--ticks 2000]

The scenario's reference task (the gripper's FrameTask) is level 0 of the strict controller and
every other task is level 1; the weighted controller has the same tasks in one level. Both
step the same closed loop (the weighted controller's q) tick by tick, in alternating order, so
machine noise hits both alike; each repeat reports both medians and their ratio (the number
to read), and the summary the median ratio over the repeats with its spread.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

import wbc
from wbc.app.scenario import Scenario, load_scenario

ROOT = Path(__file__).resolve().parents[1]


def controllers(scenario: Scenario) -> dict[str, wbc.Controller]:
    """The scenario's tasks as one weighted level, and as two (the reference task over the rest)."""
    first = scenario.reference_task
    rest = [task for task in scenario.tasks if task is not first]
    settings = dict(solver=scenario.solver, dt=scenario.dt, damping=scenario.damping, reduced=scenario.reduced)
    return {"1 level (weighted)": wbc.Controller(scenario.robot, scenario.tasks, scenario.constraints, **settings),
            "2 levels (strict)": wbc.Controller(scenario.robot, [[first], rest], scenario.constraints, **settings)}


def measure(scenario: Scenario, ticks: int) -> tuple[dict[str, np.ndarray], dict[str, int]]:
    """Tick times [s] of both controllers along one closed loop of ``ticks`` ticks, and how many
    of their ticks the fallback chain answered."""
    pair = controllers(scenario)
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
    args = parser.parse_args(argv)
    scenario = load_scenario(args.scenario)
    print(f"{scenario.name}: {args.repeats} repeats x {args.ticks} ticks, first {args.warmup} left out; "
          f"solver {scenario.solver}")
    print(f"{'repeat':>6s} {'1 level µs':>11s} {'2 levels µs':>12s} {'ratio':>7s} {'p99 1 / 2 µs':>16s} "
          f"{'fallback ticks 1 / 2':>21s}")
    ratios = []
    for repeat in range(args.repeats):
        times, fallbacks = measure(scenario, args.ticks)
        one, two = (values[args.warmup:] * 1e6 for values in times.values())
        ratios.append(np.median(two) / np.median(one))
        counts = " / ".join(map(str, fallbacks.values()))
        print(f"{repeat + 1:6d} {np.median(one):11.2f} {np.median(two):12.2f} {ratios[-1]:7.2f} "
              f"{np.percentile(one, 99):7.1f} / {np.percentile(two, 99):6.1f} {counts:>21s}")
    print(f"median ratio 2 levels / 1 level: {np.median(ratios):.2f} (min {min(ratios):.2f}, max {max(ratios):.2f})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
