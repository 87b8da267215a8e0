"""Tick latency of a scenario, wbc's direct DAQP backend against DAQP through qpsolvers.

    python benchmarks/tick_latency.py [tasks/youbot_circle.toml] [--repeats 3]

Both controllers run the same closed loop interleaved tick by tick (same q, same
target), so machine noise hits both alike; the ratio is the number to read.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from wbc.app.scenario import load_scenario
from wbc.solvers import QpsolversBackend

ROOT = Path(__file__).resolve().parents[1]


def measure(path: Path, repeats: int) -> dict[str, np.ndarray]:
    scenario = load_scenario(path)
    direct = scenario.make_controller("daqp")
    generic = scenario.make_controller("daqp")
    generic.solver = QpsolversBackend("daqp")
    times = {"wbc (direct daqp)": [], "wbc (daqp via qpsolvers)": []}
    for _ in range(repeats):
        q = scenario.q0.copy()
        for k in range(scenario.ticks):
            scenario.reference_task.set_target(*scenario.reference(k * scenario.dt))
            for name, controller in (("wbc (direct daqp)", direct), ("wbc (daqp via qpsolvers)", generic)):
                start = time.perf_counter()
                v = controller.step(q)
                times[name].append(time.perf_counter() - start)
            q = scenario.robot.integrate(q, v, scenario.dt)
    return {name: np.array(values) for name, values in times.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("scenario", nargs="?", default=str(ROOT / "tasks" / "youbot_circle.toml"))
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    results = measure(Path(args.scenario), args.repeats)
    baseline = np.median(results["wbc (daqp via qpsolvers)"])
    print(f"{'controller':28s} {'median µs':>10s} {'p99 µs':>9s} {'max µs':>9s} {'median ratio':>13s}")
    for name, values in results.items():
        print(f"{name:28s} {np.median(values) * 1e6:10.1f} {np.percentile(values, 99) * 1e6:9.1f} "
              f"{values.max() * 1e6:9.1f} {np.median(values) / baseline:13.2f}")


if __name__ == "__main__":
    main()
