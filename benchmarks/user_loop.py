"""Where wbc's user loop goes: ``set_target``, ``step``, ``robot.integrate``, the native call, the solve.

    python -m benchmarks.user_loop [--processes 3] [--ticks 5000] [--warmup 200]

The loop of the peer comparison's headline (:func:`benchmarks.peers.wbc_user_loop`: the youBot
peer stack of ``tasks/youbot_circle.toml``, the tool's start pose moved on a 0.2 m circle
computed in the loop, the command integrated), with each of the three calls timed on its own
(``perf_counter_ns`` around it, the median cost of an empty pair of clock reads in the same
process subtracted). After every :data:`SAMPLE_EVERY`-th tick, untimed, ``controller.last`` gives
the two inner times of that tick (reading it builds the diagnostics record, which would slow the
next tick's calls by ~0.05 µs: the ticks right after a read are left out of the three calls'
times):

* the **native call** (``last.tick_time`` on the one-call path: the tick program from ``q``'s copy
  to the checked answer -- forward kinematics, every row, the normal equations, the solve, the
  answer check; timed by the program itself): the floor of ``step``;
* the **solve** (``last.solve_time``): DAQP's own solve through its C API, or the unconstrained
  minimiser when it is the QP's answer (docs/solvers.md).

Each repeat is a fresh process (a controller built, ``warmup`` ticks, then ``ticks`` timed).
Issue 26 §1's goals: ``robot.integrate`` ≤ 0.5 µs, ``set_target`` (4×4 array) ≤ 0.3 µs,
``step`` ≤ 1.5× the native call. Numbers in benchmarks/README.md §3.
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import time

import numpy as np

from benchmarks.common import ROOT, TASKS, machine_note, markdown_table

#: the columns of a child's report, in the order of the table
PARTS = ("set_target", "step", "integrate", "native call", "solve")
#: ``controller.last`` is read after every SAMPLE_EVERY-th tick (the native call's and the solve's times)
SAMPLE_EVERY = 10


def clock_pair_ns(samples: int = 20000) -> float:
    """Median cost [ns] of two back-to-back ``perf_counter_ns`` reads (subtracted from each part)."""
    clock = time.perf_counter_ns
    pairs = np.empty(samples)
    for k in range(samples):
        start = clock()
        pairs[k] = clock() - start
    return float(np.median(pairs))


def split_loop(ticks: int, warmup: int) -> dict:
    """The user loop in this process after ``warmup`` untimed ticks: per part, its times [s] --
    the three calls' (clock overhead subtracted) of the ticks that do not follow a read of
    ``controller.last``, the native call's and the solve's of the ticks after which it was read
    (every :data:`SAMPLE_EVERY`-th); ``clock_pair_ns``; ``q``, the configuration after the last
    tick (the loop is :func:`benchmarks.peers.wbc_user_loop`'s)."""
    from benchmarks import placo_peer
    from benchmarks.peer_setups import WbcSetup, spec_from_scenario
    from wbc.app.scenario import load_scenario

    scenario = load_scenario(TASKS / "youbot_circle.toml")
    setup = WbcSetup(spec_from_scenario(scenario))
    controller, task, robot, clock = setup.controller, setup.task, setup.controller.robot, time.perf_counter_ns
    dt = controller.dt
    pose = robot.frame_pose(scenario.q0, task.frame)
    cx, cy, radius, angle_step = placo_peer.circle(pose, dt)
    times = np.zeros((warmup + ticks, len(PARTS)))
    q = scenario.q0.copy()
    for k in range(warmup + ticks):
        pose[0, 3] = cx + radius * math.sin(angle_step * k)
        pose[1, 3] = cy - radius * math.cos(angle_step * k)
        a = clock()
        task.set_target(pose)
        b = clock()
        v = controller.step(q)
        c = clock()
        q = robot.integrate(q, v, dt)
        d = clock()
        times[k, :3] = (b - a, c - b, d - c)
        if k % SAMPLE_EVERY == 0:
            last = controller.last
            times[k, 3:] = (last.tick_time * 1e9, last.solve_time * 1e9)
    overhead = clock_pair_ns()
    times[:, :3] -= overhead  # the clock reads around each call (the native times are the program's own)
    timed = np.arange(warmup, warmup + ticks)
    calls, sampled = timed[timed % SAMPLE_EVERY != 1], timed[timed % SAMPLE_EVERY == 0]
    return ({part: (times[calls if i < 3 else sampled, i] * 1e-9).tolist() for i, part in enumerate(PARTS)}
            | {"clock_pair_ns": overhead, "q": q.tolist()})


def run_process(ticks: int, warmup: int) -> dict:
    """:func:`split_loop` in a fresh Python process."""
    result = subprocess.run([sys.executable, "-m", "benchmarks.user_loop", "--child", "--ticks", str(ticks),
                             "--warmup", str(warmup)], capture_output=True, text=True, check=True, cwd=ROOT)
    return json.loads(result.stdout)


def summary(runs: list[dict]) -> tuple[list[list[str]], list[float]]:
    """Table rows (one per process: median µs of each part, p99 of the step) and the
    ``step / native call`` ratio of each process (ratio of the medians: the step's of the ticks
    that do not follow a read of ``last``, the native call's of those after which it was read)."""
    rows, ratios = [], []
    for number, run in enumerate(runs, 1):
        medians = {part: float(np.median(run[part])) * 1e6 for part in PARTS}
        ratios.append(medians["step"] / medians["native call"])
        loop = medians["set_target"] + medians["step"] + medians["integrate"]
        rows.append([str(number), *(f"{medians[part]:.2f}" for part in PARTS), f"{loop:.2f}",
                     f"{np.percentile(run['step'], 99) * 1e6:.1f}", f"{ratios[-1]:.2f}",
                     f"{run['clock_pair_ns']:.0f}"])
    return rows, ratios


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.user_loop", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--processes", type=int, default=3, help="fresh processes, one run each")
    parser.add_argument("--ticks", type=int, default=5000)
    parser.add_argument("--warmup", type=int, default=200)
    parser.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child:
        print(json.dumps(split_loop(args.ticks, args.warmup)))
        return 0
    runs = [run_process(args.ticks, args.warmup) for _ in range(args.processes)]
    rows, ratios = summary(runs)
    print(f"wbc's user loop (youbot_circle peer stack), {args.processes} fresh processes × {args.ticks} ticks "
          f"after {args.warmup}; {machine_note()}")
    print("median µs per call (clock reads subtracted); the native call and the solve are the program's own times\n")
    print(markdown_table(["process", *(f"{part} µs" for part in PARTS), "set_target + step + integrate µs",
                          "step p99 µs", "step / native call", "clock pair ns"], rows))
    print(f"\nstep / native call: median {np.median(ratios):.2f} ({min(ratios):.2f}–{max(ratios):.2f})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
