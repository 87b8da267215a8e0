"""Endurance: many ticks of a scenario without memory growth and with a stable latency.

    python benchmarks/endurance.py [--ticks 1000000] [--scenario tasks/youbot_circle.toml]

The reference keeps going round (a circle scenario repeats itself), the loop is
kinematic (q <- integrate(q, v, dt)). Reports the latency p50/p99/p99.9/max of
``Controller.step`` over all ticks and per window, the resident set size at each window
boundary, and the number of non-optimal ticks. Numbers in benchmarks/README.md.
"""

from __future__ import annotations

import argparse
import gc
import time
from pathlib import Path

import numpy as np

from wbc.app.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[1]


def resident_kib() -> int:
    """Resident set size of this process [KiB] (Linux /proc)."""
    with open("/proc/self/statm") as stream:
        pages = int(stream.read().split()[1])
    return pages * 4


def endurance(path: Path, ticks: int, windows: int = 10) -> None:
    scenario = load_scenario(path)
    controller = scenario.make_controller()
    robot, dt, task, reference = scenario.robot, scenario.dt, scenario.reference_task, scenario.reference
    latency = np.empty(ticks)
    latency.fill(0.0)  # touch every page now, so RSS growth measures the controller, not this array
    q = scenario.q0.copy()
    failures = 0
    window = ticks // windows
    print(f"{scenario.name}: {ticks} ticks, {windows} windows; RSS {resident_kib()} KiB at start")
    print(f"{'window':>8s} {'p50 µs':>8s} {'p99 µs':>8s} {'p99.9 µs':>9s} {'max µs':>9s} {'RSS KiB':>9s}")
    gc.collect()
    for k in range(ticks):
        task.set_target(*reference(k * dt))
        start = time.perf_counter()
        v = controller.step(q)
        latency[k] = time.perf_counter() - start
        failures += not controller.last.success
        q = robot.integrate(q, v, dt)
        if (k + 1) % window == 0:
            part = latency[k + 1 - window:k + 1] * 1e6
            print(f"{(k + 1) // window:8d} {np.median(part):8.1f} {np.percentile(part, 99):8.1f} "
                  f"{np.percentile(part, 99.9):9.1f} {part.max():9.1f} {resident_kib():9d}")
    us = latency * 1e6
    print(f"all ticks: p50 {np.median(us):.1f} µs, p99 {np.percentile(us, 99):.1f} µs, "
          f"p99.9 {np.percentile(us, 99.9):.1f} µs, max {us.max():.1f} µs; non-optimal ticks: {failures}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--ticks", type=int, default=1_000_000)
    parser.add_argument("--scenario", default=str(ROOT / "tasks" / "youbot_circle.toml"))
    args = parser.parse_args()
    endurance(Path(args.scenario), args.ticks)


if __name__ == "__main__":
    main()
