"""Cost of collision avoidance: the youBot tick with self-collision and 10 obstacles vs without.

    python -m benchmarks.collision [tasks/youbot_circle.toml] [--repeats 5] [--ticks 2000]
    python -m benchmarks.collision --reference PATH   # against another checkout's plain tick

The scenario's controller ("today") and the same stack plus ``wbc.CollisionAvoidance`` (self-
collision and 10 spheres/boxes whose centres lie 0.5-0.85 m from the platform's centre, seeded;
the default capacity of one row per candidate pair, and ``capacity=16``) step the same closed
loop (today's q) tick by tick in alternating order, so machine noise hits all alike. Each repeat
reports the medians and the mean number of pairs given a row per tick (within the detection
distance and within reach of the speed limits: ``wbc.CollisionAvoidance``'s *Reach*); the
summary the median ratio over the repeats with its spread (min-max), for wbc (collision / today)
and, with ``--mink``, for mink (its ``CollisionAvoidanceLimit`` on the same scene / mink without
it) and mink's collision tick over wbc's.

``--reference PATH`` (a checkout of wbc, e.g. ``git worktree add --detach /tmp/ref b826357``, the
last commit before collision avoidance, the "today" of the issue that asked for it) also times, in
fresh processes alternating in order, that checkout's plain tick and this checkout's collision
tick, each along its own closed loop, and prints their ratio: the cost of collision avoidance
against a fixed tick rather than against today's, which gets faster.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

import wbc
from wbc.app.scenario import Scenario, load_scenario

from .peer_setups import MJCF, MinkSetup, spec_from_scenario

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


def mink_model(shapes: list[wbc.collision.Obstacle]) -> Any:
    """models/youbot/youbot.xml with the obstacles as world geoms, every geom able to collide."""
    import mujoco

    spec = mujoco.MjSpec.from_file(str(MJCF))
    for k, shape in enumerate(shapes):
        pose = shape.pose
        geom = spec.worldbody.add_geom(name=f"obstacle{k}", pos=pose[:3, 3])
        if isinstance(shape, wbc.Sphere):
            geom.type, geom.size = mujoco.mjtGeom.mjGEOM_SPHERE, [shape.radius, 0.0, 0.0]
        else:
            geom.type, geom.size = mujoco.mjtGeom.mjGEOM_BOX, shape.size / 2.0
    for geom in spec.geoms:
        geom.contype, geom.conaffinity = 1, 1
    return spec.compile()


def mink_setups(scenario: Scenario) -> dict[str, MinkSetup]:
    """mink on the same stack, without and with its CollisionAvoidanceLimit on the same scene
    (min distance 0.02 m, detection 0.3 m, the robot's geoms against the obstacles and each other)."""
    import mink

    spec = spec_from_scenario(scenario)
    model = mink_model(obstacles())
    plain, guarded = MinkSetup(spec, "mink", model=model), MinkSetup(spec, "mink collision", model=model)
    names = [model.geom(i).name for i in range(model.ngeom)]
    robot = [i for i, name in enumerate(names) if model.geom_bodyid[i] != 0]
    world = [i for i, name in enumerate(names) if name.startswith("obstacle")]
    guarded.limits.append(mink.CollisionAvoidanceLimit(model, [(robot, world), (robot, robot)],
                                                       minimum_distance_from_collisions=0.02,
                                                       collision_detection_distance=0.3))
    return {"mink": plain, "mink collision": guarded}


def controllers(scenario: Scenario) -> dict[str, tuple[wbc.Controller, wbc.CollisionAvoidance | None]]:
    settings = dict(solver=scenario.solver, dt=scenario.dt, damping=scenario.damping, reduced=scenario.reduced)
    result: dict[str, tuple[wbc.Controller, wbc.CollisionAvoidance | None]] = {
        "today": (wbc.Controller(scenario.robot, scenario.tasks, scenario.constraints, **settings), None)}
    for name, capacity in (("collision", None), ("collision cap 16", 16)):
        avoidance = wbc.CollisionAvoidance(obstacles(), self_collision=True, capacity=capacity)
        result[name] = (wbc.Controller(scenario.robot, scenario.tasks, [*scenario.constraints, avoidance],
                                       **settings), avoidance)
    return result


def measure(scenario: Scenario, ticks: int, with_mink: bool) -> tuple[dict[str, np.ndarray], float, int]:
    """Tick times [s] of every controller (and mink's setups) along today's closed loop, the mean
    number of pairs given a row, and the collision controllers' rows."""
    stack: dict[str, Any] = dict(controllers(scenario))
    peers = mink_setups(scenario) if with_mink else {}
    stack.update({name: (setup, None) for name, setup in peers.items()})
    names = list(stack)
    times = {name: np.zeros(ticks) for name in names}
    close, rows = 0, 0
    q = scenario.q0.copy()
    for k in range(ticks):
        pose, twist = scenario.reference(k * scenario.dt)
        scenario.reference_task.set_target(pose, twist)
        for setup in peers.values():
            setup.set_target(pose)
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


#: one process's median tick [us] along its own closed loop: argv = scenario, "plain" or "collision", ticks,
#: warm-up; runs with the wbc of PYTHONPATH (any checkout since 2026-11-25: wbc.scenario before wbc.app)
_OWN_LOOP = """
import sys, time
import numpy as np
import wbc
try:
    from wbc.app.scenario import load_scenario
except ImportError:
    from wbc.scenario import load_scenario
scenario = load_scenario(sys.argv[1])
constraints = list(scenario.constraints)
if sys.argv[2] == "collision":
    from benchmarks.collision import obstacles
    constraints.append(wbc.CollisionAvoidance(obstacles(), self_collision=True))
controller = wbc.Controller(scenario.robot, scenario.tasks, constraints, solver=scenario.solver, dt=scenario.dt,
                            damping=scenario.damping, reduced=scenario.reduced)
ticks, warmup = int(sys.argv[3]), int(sys.argv[4])
times, q = np.zeros(ticks), scenario.q0.copy()
for k in range(ticks):
    pose, twist = scenario.reference(k * scenario.dt)
    scenario.reference_task.set_target(pose, twist)
    start = time.perf_counter()
    v = controller.step(q)
    times[k] = time.perf_counter() - start
    q = scenario.robot.integrate(q, v, scenario.dt)
print(float(np.median(times[warmup:])) * 1e6)
"""


def own_loop(checkout: Path, scenario: str, kind: str, ticks: int, warmup: int) -> float:
    """Median tick [us] of ``kind`` ("plain" or "collision") along its own closed loop, in a fresh
    process running the wbc of ``checkout``."""
    env = {**os.environ, "PYTHONPATH": str(checkout)}
    result = subprocess.run([sys.executable, "-c", _OWN_LOOP, scenario, kind, str(ticks), str(warmup)], env=env,
                            cwd=checkout, capture_output=True, text=True, check=True)
    return float(result.stdout.split()[-1])


def reference_ratios(reference: Path, scenario: str, repeats: int, ticks: int, warmup: int) -> list[float]:
    """This checkout's collision tick over ``reference``'s plain tick, one ratio per repeat (the two
    processes alternate in order)."""
    ratios = []
    for repeat in range(repeats):
        runs = [(reference, "plain"), (ROOT, "collision")]
        medians = {kind: own_loop(checkout, scenario, kind, ticks, warmup)
                   for checkout, kind in (runs if repeat % 2 == 0 else runs[::-1])}
        ratios.append(medians["collision"] / medians["plain"])
        print(f"reference repeat {repeat + 1}: {reference.name} plain {medians['plain']:.1f} µs, this checkout's "
              f"collision {medians['collision']:.1f} µs")
    return ratios


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("scenario", nargs="?", default=str(ROOT / "tasks" / "youbot_circle.toml"))
    parser.add_argument("--repeats", type=int, default=5, help="closed loops, each measuring all (default 5)")
    parser.add_argument("--ticks", type=int, default=2000, help="ticks per repeat (default 2000)")
    parser.add_argument("--warmup", type=int, default=200, help="first ticks of each repeat left out (default 200)")
    parser.add_argument("--mink", action="store_true", help="also time mink without and with CollisionAvoidanceLimit")
    parser.add_argument("--reference", type=Path, help="a wbc checkout whose plain tick the collision tick is also "
                        "compared with, each in its own processes")
    args = parser.parse_args(argv)
    scenario = load_scenario(args.scenario)
    print(f"{scenario.name}: {args.repeats} repeats x {args.ticks} ticks, first {args.warmup} left out; "
          f"solver {scenario.solver}")
    ratios: dict[str, list[float]] = {"collision": [], "collision cap 16": []}
    for repeat in range(args.repeats):
        times, close, rows = measure(scenario, args.ticks, args.mink)
        medians = {name: float(np.median(values[args.warmup:])) * 1e6 for name, values in times.items()}
        for name in ("collision", "collision cap 16"):
            ratios[name].append(medians[name] / medians["today"])
        if args.mink:
            ratios.setdefault("mink collision / mink", []).append(medians["mink collision"] / medians["mink"])
            ratios.setdefault("mink collision / wbc collision", []).append(medians["mink collision"]
                                                                          / medians["collision"])
        print(f"repeat {repeat + 1}: " + ", ".join(f"{name} {value:.1f} µs" for name, value in medians.items())
              + f"; pairs with a row per tick {close:.1f} of {rows} rows (within 0.3 m and within reach)")
    print("summary (median over the repeats, min-max):")
    for name, values in ratios.items():
        label = name if "/" in name else f"{name} / today"
        side = "mink" if name.startswith("mink") else "wbc"
        print(f"  {side}: median ratio {label}: {np.median(values):.2f} (min {min(values):.2f}, "
              f"max {max(values):.2f})")
    if not args.mink:
        print("  mink: not measured (add --mink for mink's CollisionAvoidanceLimit on the same scene)")
    if args.reference is not None:
        values = reference_ratios(args.reference.resolve(), str(Path(args.scenario).resolve()), args.repeats,
                                  args.ticks, args.warmup)
        print(f"  wbc: median ratio collision / {args.reference.name}'s plain tick (own processes and loops): "
              f"{np.median(values):.2f} (min {min(values):.2f}, max {max(values):.2f})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
