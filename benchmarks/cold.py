"""Cold costs: the first tick of a process and of a controller, building a controller, and the
first ``wbc run`` after an install.

    python -m benchmarks.cold [--scenario tasks/youbot_circle.toml] [--processes 5] [--first-runs 3] [--no-warm-up]

Each measurement runs in a fresh Python process (the first tick of a *process* pays for
code paths run once: Pinocchio's and numba's dispatch caches, first touches of memory):
``import wbc``, the scenario loaded, a controller built (the first one: it loads the
compiled kernels from numba's cache), its first tick, 2000 steady ticks of the closed loop
(median; ``q`` integrated as in ``wbc run``), then 50 more controllers built (median) and the
first tick of 20 of them (median, at the loop's last ``q``). Ratios are to
the steady tick of the same process; the table shows the median (min–max) over processes.
Controllers are built as by default, warmed up (``Controller(warm_up=True)``: a throwaway twin
ticks at build, wbc.control.warm_up); ``--no-warm-up`` builds them without it.

``--first-runs N``: N times, ``wbc run --no-progress <scenario>`` with ``NUMBA_CACHE_DIR`` set to
a fresh empty directory (a fresh install: every kernel the run uses compiles), then once more on
that cache (warm); wall clock and CPU time (user + system, of the process and its children).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]

_CHILD = """
import json, sys, time
start = time.perf_counter()
import numpy as np
import wbc
from wbc.app.scenario import load_scenario
imported = time.perf_counter()
scenario = load_scenario(sys.argv[1])
warm_up = sys.argv[2] == "1"
q = scenario.q0.copy()
scenario.reference_task.set_target(*scenario.reference(0.0))
a = time.perf_counter(); controller = scenario.make_controller(warm_up=warm_up); b = time.perf_counter()
controller.step(q); c = time.perf_counter()
ticks = []
for k in range(1, 2001):  # the closed loop (as wbc run): a fixed q would drive the QP into its limits
    scenario.reference_task.set_target(*scenario.reference(k * scenario.dt))
    t = time.perf_counter(); v = controller.step(q); ticks.append(time.perf_counter() - t)
    q = scenario.robot.integrate(q, v, scenario.dt)
builds, firsts = [], []
for k in range(50):
    t = time.perf_counter(); other = scenario.make_controller(warm_up=warm_up); builds.append(time.perf_counter() - t)
    if k < 20:
        t = time.perf_counter(); other.step(q); firsts.append(time.perf_counter() - t)
print(json.dumps(dict(import_s=imported - start, first_build_s=b - a, first_tick_s=c - b,
                      steady_s=float(np.median(ticks)), build_s=float(np.median(builds)),
                      later_first_tick_s=float(np.median(firsts)))))
"""


def measure(scenario: Path, warm_up: bool = True) -> dict:
    """One fresh process's cold costs (see the module docstring)."""
    result = subprocess.run([sys.executable, "-c", _CHILD, str(scenario), "1" if warm_up else "0"],
                            capture_output=True, text=True, check=True, cwd=Path.home())
    return json.loads(result.stdout.strip().splitlines()[-1])


def timed_run(scenario: Path, cache: Path) -> tuple[float, float]:
    """(wall [s], CPU [s]) of one ``wbc run`` of ``scenario`` in a fresh process on the numba cache ``cache``."""
    def cpu() -> float:
        usage = resource.getrusage(resource.RUSAGE_CHILDREN)
        return usage.ru_utime + usage.ru_stime

    start, start_cpu = time.perf_counter(), cpu()
    subprocess.run([sys.executable, "-m", "wbc", "run", "--no-progress", str(scenario)], check=True,
                   capture_output=True, cwd=Path.home(), env={**os.environ, "NUMBA_CACHE_DIR": str(cache)})
    return time.perf_counter() - start, cpu() - start_cpu


def first_runs(scenario: Path, count: int) -> list[tuple[float, float, float, float]]:
    """``count`` times (first wall, first CPU, warm wall, warm CPU) [s]: a run on an empty numba
    cache, then one on the cache it left."""
    results = []
    for _ in range(count):
        with tempfile.TemporaryDirectory(prefix="wbc-cold-") as cache:
            results.append((*timed_run(scenario, Path(cache)), *timed_run(scenario, Path(cache))))
    return results


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.cold", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scenario", type=Path, default=ROOT / "tasks" / "youbot_circle.toml")
    parser.add_argument("--processes", type=int, default=5)
    parser.add_argument("--first-runs", type=int, default=0, help="also time N first runs on an empty numba cache")
    parser.add_argument("--no-warm-up", action="store_true", help="build the controllers with warm_up=False")
    args = parser.parse_args(argv)
    if args.first_runs:
        runs = first_runs(args.scenario.resolve(), args.first_runs)
        print(f"wbc run {args.scenario.name}, {args.first_runs} times on an empty numba cache, then warm: "
              "wall / CPU [s]")
        for first_wall, first_cpu, warm_wall, warm_cpu in runs:
            print(f"  first {first_wall:5.1f} / {first_cpu:5.1f}   warm {warm_wall:5.1f} / {warm_cpu:5.1f}")
    if not args.processes:
        return 0
    runs = [measure(args.scenario.resolve(), not args.no_warm_up) for _ in range(args.processes)]

    def spread(values: list[float], unit: float, digits: int = 1) -> str:
        values = np.array(values) * unit
        return f"{np.median(values):.{digits}f} ({values.min():.{digits}f}–{values.max():.{digits}f})"

    steady = [r["steady_s"] for r in runs]
    rows = [("import wbc [s]", spread([r["import_s"] for r in runs], 1, 2)),
            ("first controller built [ms]", spread([r["first_build_s"] for r in runs], 1e3)),
            ("steady tick [µs]", spread(steady, 1e6)),
            ("first tick of the process [µs]", spread([r["first_tick_s"] for r in runs], 1e6)),
            ("… / steady tick", spread([r["first_tick_s"] / s for r, s in zip(runs, steady, strict=True)], 1)),
            ("a later controller built [ms]", spread([r["build_s"] for r in runs], 1e3, 2)),
            ("its first tick / steady tick",
             spread([r["later_first_tick_s"] / s for r, s in zip(runs, steady, strict=True)], 1))]
    print(f"{args.scenario.name}, {args.processes} fresh processes{', warm_up=False' if args.no_warm_up else ''}: "
          "median (min–max)")
    for name, value in rows:
        print(f"  {name:34s} {value}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
