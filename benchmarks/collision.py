"""Cost of collision avoidance: the youBot tick with self-collision and 10 obstacles vs without.

    python -m benchmarks.collision [tasks/youbot_circle.toml] [--repeats 5] [--ticks 2000]

The scenario's controller ("today") and the same stack plus ``wbc.CollisionAvoidance`` (self-
collision and 10 spheres/boxes whose centres lie 0.5-0.85 m from the platform's centre, seeded;
the default capacity of one row per candidate pair, and ``capacity=16``) step the same closed
loop (today's q) tick by tick in alternating order, so machine noise hits all alike. Each repeat
reports the medians and their ratios to today's (the numbers to read); the summary the median
ratio over the repeats with its spread, and the mean number of pairs within the detection
distance per tick.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

import wbc
from wbc.scenario import Scenario, load_scenario

ROOT = Path(__file__).resolve().parents[1]


def obstacles(count: int = 10, seed: int = 0) -> list[wbc.collision.Obstacle]:
    """Spheres and boxes (alternating) 0.5-0.85 m from the origin horizontally, 0.1-0.6 m high."""
    rng = np.random.default_rng(seed)
    shapes: list[wbc.collision.Obstacle] = []
    for k in range(count):
        angle, reach, height = rng.uniform(-np.pi, np.pi), rng.uniform(0.5, 0.85), rng.uniform(0.1, 0.6)
        centre = (reach * np.cos(angle), reach * np.sin(angle), height)
        if k % 2 == 0:
            shapes.append(wbc.Sphere(centre, rng.uniform(0.04, 0.1)))
        else:
            pose = np.eye(4)
            pose[:3, 3] = centre
            shapes.append(wbc.Box(pose, rng.uniform(0.05, 0.2, size=3)))
    return shapes


def controllers(scenario: Scenario) -> dict[str, tuple[wbc.Controller, wbc.CollisionAvoidance | None]]:
    settings = dict(solver=scenario.solver, dt=scenario.dt, damping=scenario.damping, reduced=scenario.reduced)
    result: dict[str, tuple[wbc.Controller, wbc.CollisionAvoidance | None]] = {
        "today": (wbc.Controller(scenario.robot, scenario.tasks, scenario.constraints, **settings), None)}
    for name, capacity in (("collision", None), ("collision cap 16", 16)):
        avoidance = wbc.CollisionAvoidance(obstacles(), self_collision=True, capacity=capacity)
        result[name] = (wbc.Controller(scenario.robot, scenario.tasks, [*scenario.constraints, avoidance],
                                       **settings), avoidance)
    return result


def measure(scenario: Scenario, ticks: int) -> tuple[dict[str, np.ndarray], float, int]:
    """Tick times [s] of every controller along today's closed loop, the mean number of pairs
    within the detection distance, and the collision controllers' rows."""
    stack = controllers(scenario)
    names = list(stack)
    times = {name: np.zeros(ticks) for name in names}
    close, rows = 0, 0
    q = scenario.q0.copy()
    for k in range(ticks):
        scenario.reference_task.set_target(*scenario.reference(k * scenario.dt))
        order = names if k % 2 == 0 else names[::-1]
        for name in order:
            controller, _ = stack[name]
            start = time.perf_counter()
            v = controller.step(q)
            times[name][k] = time.perf_counter() - start
            if name == "today":
                command = v
        controller, avoidance = stack["collision"]
        data = controller.data(avoidance)
        close += data.pairs.count
        rows = data.n_inequalities
        q = scenario.robot.integrate(q, command, scenario.dt)
    return times, close / ticks, rows


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("scenario", nargs="?", default=str(ROOT / "tasks" / "youbot_circle.toml"))
    parser.add_argument("--repeats", type=int, default=5, help="closed loops, each measuring all (default 5)")
    parser.add_argument("--ticks", type=int, default=2000, help="ticks per repeat (default 2000)")
    parser.add_argument("--warmup", type=int, default=200, help="first ticks of each repeat left out (default 200)")
    args = parser.parse_args(argv)
    scenario = load_scenario(args.scenario)
    print(f"{scenario.name}: {args.repeats} repeats x {args.ticks} ticks, first {args.warmup} left out; "
          f"solver {scenario.solver}")
    ratios: dict[str, list[float]] = {"collision": [], "collision cap 16": []}
    for repeat in range(args.repeats):
        times, close, rows = measure(scenario, args.ticks)
        medians = {name: float(np.median(values[args.warmup:])) * 1e6 for name, values in times.items()}
        for name in ratios:
            ratios[name].append(medians[name] / medians["today"])
        print(f"repeat {repeat + 1}: " + ", ".join(f"{name} {value:.1f} µs" for name, value in medians.items())
              + f"; pairs within 0.3 m per tick {close:.1f} of {rows} rows")
    for name, values in ratios.items():
        print(f"median ratio {name} / today: {np.median(values):.2f} (min {min(values):.2f}, max {max(values):.2f})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
