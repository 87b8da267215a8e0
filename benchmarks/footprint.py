"""Cost of BaseFootprintAvoidance: the youBot tick with 0 / 1 000 / 10 000 obstacle points vs without.

    python -m benchmarks.footprint [--repeats 5] [--ticks 2000]

The stack (FrameTask + PostureTask, position, velocity and wheel limits) steps at a fixed q, with
and without ``wbc.BaseFootprintAvoidance`` (the platform's 0.58 x 0.38 m footprint, 16 rows), in
alternating order so that machine noise hits all alike. Two layouts of the points: ``dense``,
uniform in a 10 m x 10 m square outside a 0.6 m clearing (~100 points/m^2: many points within
reach of the base), and ``room``, a scan of the walls of a 6 m x 4 m room with the base 0.4 m from
one wall (few points within reach). Each line gives the median ratio of the tick to the tick
without the constraint over the repeats, with its spread; ``set_points`` is the grid build of one
scan of the largest size, in ticks without the constraint.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import wbc
from wbc.collision.footprint import wall_points

PLATFORM = [[-0.29, -0.19], [0.29, -0.19], [0.29, 0.19], [-0.29, 0.19]]
Q = np.array([0.0, 0.0, 0.0, 0.0, 0.5, 1.0, 1.2, 0.0])


def dense(n: int, rng: np.random.Generator) -> np.ndarray:
    points = rng.uniform(-5.0, 5.0, (4 * n, 2))
    return points[np.linalg.norm(points, axis=1) > 0.6][:n]


def room(n: int, rng: np.random.Generator) -> np.ndarray:
    corners = np.array([[-3.0, -0.6], [3.0, -0.6], [3.0, 3.4], [-3.0, 3.4]])
    walls = np.concatenate([wall_points(a, b, 0.001) for a, b in zip(corners, np.roll(corners, -1, 0), strict=True)])
    return walls[rng.choice(len(walls), n, replace=False)] + rng.normal(0.0, 0.005, (n, 2))


def controller(points: np.ndarray | None) -> wbc.Controller:
    robot = wbc.load_robot("youbot")
    task = wbc.FrameTask("ee", position_cost=1.0, orientation_cost=0.1, gain=0.2)
    task.set_target(robot.frame_pose(Q, "ee"))
    constraints = [wbc.JointPositionLimits(), wbc.JointVelocityLimits(), wbc.MecanumWheelLimits()]
    if points is not None:
        constraints.append(wbc.BaseFootprintAvoidance(PLATFORM, points=points, capacity=16))
    return wbc.Controller(robot, [task, wbc.PostureTask(1e-4)], constraints)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--ticks", type=int, default=2000)
    args = parser.parse_args(argv)
    rng = np.random.default_rng(0)
    clouds = {f"{layout.__name__} {n}": layout(n, rng) for layout in (dense, room) for n in (0, 1000, 10000)}
    setups = {"without": controller(None)} | {name: controller(points) for name, points in clouds.items()}
    for setup in setups.values():
        for _ in range(200):
            setup.step(Q)
    times: dict[str, list[float]] = {name: [] for name in setups}
    builds = []
    largest = setups["dense 10000"].constraints[-1]
    for _ in range(args.repeats):
        for name, setup in setups.items():
            start = time.perf_counter()
            for _ in range(args.ticks):
                setup.step(Q)
            times[name].append((time.perf_counter() - start) / args.ticks)
        start = time.perf_counter()
        for _ in range(50):
            largest.set_points(clouds["dense 10000"])
        builds.append((time.perf_counter() - start) / 50)
    without = np.array(times["without"])
    print(f"tick without the constraint: median {np.median(without) * 1e6:.1f} us")
    for name in clouds:
        ratio = np.array(times[name]) / without
        print(f"{name:>12} points: ratio {np.median(ratio):.2f} (min {ratio.min():.2f}, max {ratio.max():.2f})")
    ratio = np.array(builds) / without
    print(f"set_points(10 000): {np.median(ratio):.1f} ticks without (min {ratio.min():.1f}, max {ratio.max():.1f})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
