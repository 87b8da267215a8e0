"""Endurance: many ticks of a scenario without memory growth and with a stable latency.

    python benchmarks/endurance.py [--ticks 1000000] [--scenario tasks/youbot_circle.toml]

The reference keeps going round (a circle scenario repeats itself), the loop is
kinematic (q <- integrate(q, v, dt)). Reports the latency p50/p99/p99.9/max of
``Controller.step`` over all ticks and per window, the resident set size at each window
boundary, and the number of non-optimal ticks. Numbers in benchmarks/README.md.

**The machine's own tail.** After every tick, a fixed pure-Python workload is timed the same way
(:func:`fixed_workload`: the same instructions every time, no allocation; its length fitted in
three rounds of 1000 warm-up ticks so that its median matches the tick's). Whatever lengthens
*its* slow calls -- interrupts, the hypervisor, the other processes -- lengthens the ticks alike,
so its p99 / p50 is a floor the machine sets under the tick's (a floor, not all of it: after an
interruption a tick may also find its data evicted from the caches, which a loop of additions
does not read); the report prints both side by side.

**The same tick, replayed.** After the workload, a second controller of the scenario, brought
through the loop's first 1000 ticks, steps that tick's ``q`` again (:func:`same_tick`): the same
target, the same warm start, hence the same path through the same memory every call. Its
p99 / p50 is the machine's tail *for this work*; what the loop's ticks show above it is theirs
(a path that changes with the tick: the solver's iterations, an active limit).
"""

from __future__ import annotations

import argparse
import functools
import gc
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from wbc.app.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[1]


def resident_kib() -> int:
    """Resident set size of this process [KiB] (Linux /proc)."""
    with open("/proc/self/statm") as stream:
        pages = int(stream.read().split()[1])
    return pages * 4


def fixed_workload(steps: int) -> Callable[[], None]:
    """A call that runs the same pure-Python loop of ``steps`` additions every time (no allocation)."""
    def loop(counts: range) -> None:
        total = 0
        for k in counts:
            total += k

    return functools.partial(loop, range(steps))


def same_tick(path: Path, ticks: int = 1000) -> Callable[[], np.ndarray]:
    """A call doing the same tick every time: a controller of the scenario at ``path`` brought
    through the first ``ticks`` ticks of the endurance loop, then stepped on that tick's ``q`` with
    its target again and again (same problem, same warm start: the same command, bit for bit)."""
    scenario = load_scenario(path)
    controller = scenario.make_controller()
    task, q = scenario.reference_task, scenario.q0.copy()
    for k in range(ticks):
        task.set_target(*scenario.reference(k * scenario.dt))
        q = scenario.robot.integrate(q, controller.step(q), scenario.dt)
    task.set_target(*scenario.reference(ticks * scenario.dt))
    return functools.partial(controller.step, q)


def _percentiles(seconds: np.ndarray) -> tuple[float, float, float, float]:
    """(p50, p99, p99.9, max) [µs]."""
    us = seconds * 1e6
    return float(np.median(us)), float(np.percentile(us, 99)), float(np.percentile(us, 99.9)), float(us.max())


def endurance(path: Path, ticks: int, windows: int = 10, control: bool = True) -> None:
    scenario = load_scenario(path)
    controller = scenario.make_controller()
    robot, dt, task, reference = scenario.robot, scenario.dt, scenario.reference_task, scenario.reference
    latency, fixed, replayed = np.empty(ticks), np.empty(ticks), np.empty(ticks)
    for times in (latency, fixed, replayed):
        times.fill(0.0)  # touch every page now, so RSS growth measures the controller, not these arrays
    steps = 100
    workload = fixed_workload(steps) if control else None
    replay = same_tick(path) if control else None

    def tick(k: int, q: np.ndarray) -> np.ndarray:
        """Tick ``k`` from ``q``: its command; the step's time into ``latency[k]``, then the
        workload's into ``fixed[k]`` and the replayed tick's into ``replayed[k]``."""
        task.set_target(*reference(k * dt))
        start = time.perf_counter()
        v = controller.step(q)
        latency[k] = time.perf_counter() - start
        if workload is not None and replay is not None:
            start = time.perf_counter()
            workload()
            fixed[k] = time.perf_counter() - start
            start = time.perf_counter()
            replay()
            replayed[k] = time.perf_counter() - start
        return v

    for _ in range(3 if control else 0):  # the workload's length fitted to the median tick, in the loop
        q = scenario.q0.copy()
        for k in range(1000):
            q = robot.integrate(q, tick(k, q), dt)
        steps = max(1, round(steps * float(np.median(latency[:1000]) / np.median(fixed[:1000]))))
        workload = fixed_workload(steps)
    failures = 0
    window = ticks // windows
    print(f"{scenario.name}: {ticks} ticks, {windows} windows; RSS {resident_kib()} KiB at start")
    print(f"{'window':>8s} {'p50 µs':>8s} {'p99 µs':>8s} {'p99.9 µs':>9s} {'max µs':>9s} {'RSS KiB':>9s}"
          + (f" {'fixed p50':>10s} {'fixed p99':>10s} {'same p50':>9s} {'same p99':>9s}" if control else ""))
    q = scenario.q0.copy()
    gc.collect()
    for k in range(ticks):
        v = tick(k, q)
        failures += not controller.last.success
        q = robot.integrate(q, v, dt)
        if (k + 1) % window == 0:
            p50, p99, p999, most = _percentiles(latency[k + 1 - window:k + 1])
            line = f"{(k + 1) // window:8d} {p50:8.1f} {p99:8.1f} {p999:9.1f} {most:9.1f} {resident_kib():9d}"
            if control:
                fixed_p50, fixed_p99, _, _ = _percentiles(fixed[k + 1 - window:k + 1])
                same_p50, same_p99, _, _ = _percentiles(replayed[k + 1 - window:k + 1])
                line += f" {fixed_p50:10.1f} {fixed_p99:10.1f} {same_p50:9.1f} {same_p99:9.1f}"
            print(line)
    p50, p99, p999, most = _percentiles(latency)
    print(f"all ticks: p50 {p50:.1f} µs, p99 {p99:.1f} µs, p99.9 {p999:.1f} µs, max {most:.1f} µs, "
          f"p99 / p50 {p99 / p50:.2f}; non-optimal ticks: {failures}")
    if control:
        for name, times in (("the fixed workload (the machine's tail)", fixed),
                            ("the same tick replayed (the machine's tail for this work)", replayed)):
            p50, p99, p999, most = _percentiles(times)
            print(f"{name}: p50 {p50:.1f} µs, p99 {p99:.1f} µs, p99.9 {p999:.1f} µs, max {most:.1f} µs, "
                  f"p99 / p50 {p99 / p50:.2f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--ticks", type=int, default=1_000_000)
    parser.add_argument("--scenario", default=str(ROOT / "tasks" / "youbot_circle.toml"))
    parser.add_argument("--no-control", action="store_true",
                        help="time the tick alone (not the fixed workload nor the replayed tick between ticks)")
    args = parser.parse_args()
    endurance(Path(args.scenario), args.ticks, control=not args.no_control)


if __name__ == "__main__":
    main()
