"""Command line: ``wbc run SCENARIO [--plot FILE.png]``, ``wbc solvers``, ``wbc bench SUITE``."""

from __future__ import annotations

import argparse
import json
import sys

from .errors import WbcError


def _run(args: argparse.Namespace) -> int:
    from .closed_loop import run
    from .scenario import load_scenario

    scenario = load_scenario(args.scenario)
    result = run(scenario, solver=args.solver, duration=args.duration, progress=not args.no_progress)
    summary = result.summary()
    if args.json:
        print(json.dumps(summary, indent=2))
    else:
        print(format_summary(scenario.name, result.solver, summary))
    if args.plot:
        from .plotting import plot_run

        print(f"plot written to {plot_run(result, args.plot, scenario.robot.joint_names)}")
    return 0


def format_summary(name: str, solver: str, s: dict) -> str:
    return "\n".join([
        f"scenario {name}  (solver {solver})",
        f"  ticks                      {s['ticks']}",
        f"  position error   rms / max {s['position_error_rms_m'] * 1e3:.4f} / {s['position_error_max_m'] * 1e3:.4f} mm",
        f"  orientation err  rms / max {s['orientation_error_rms_rad'] * 1e3:.4f} / "
        f"{s['orientation_error_max_rad'] * 1e3:.4f} mrad",
        f"  final error      pos / ori {s['final_position_error_m'] * 1e3:.2e} mm / "
        f"{s['final_orientation_error_rad'] * 1e3:.2e} mrad",
        f"  worst limit violation      position {s['worst_position_limit_violation']:.2e}, "
        f"velocity {s['worst_velocity_limit_violation']:.2e}",
        f"  tick latency median / p99  {s['tick_latency_median_us']:.1f} / {s['tick_latency_p99_us']:.1f} µs"
        f"  (solve median {s['solve_time_median_us']:.1f} µs)",
    ] + ([f"  worst wheel speed          {s['worst_wheel_speed_ratio'] * 100:.1f} % of its limit"]
         if "worst_wheel_speed_ratio" in s else [])
      + ([f"  max lateral base slip      {s['max_lateral_slip_m_s']:.2e} m/s"]
         if "max_lateral_slip_m_s" in s else []))


def _solvers(args: argparse.Namespace) -> int:
    from .solvers import available_solvers

    print("\n".join(available_solvers()))
    return 0


BENCH_SUITES = ("solvers", "peers", "scaling", "dataset")


def find_benchmarks() -> "Path | None":
    """The source checkout holding ``benchmarks/`` (not part of the installed package):
    the current directory or one of its parents, else the checkout of an editable install."""
    from pathlib import Path

    here = Path.cwd().resolve()
    for candidate in (here, *here.parents, Path(__file__).resolve().parents[1]):
        if (candidate / "benchmarks" / "__init__.py").is_file() and (candidate / "tasks").is_dir():
            return candidate
    return None


def _bench(args: argparse.Namespace) -> int:
    import importlib

    root = find_benchmarks()
    if root is None:
        print("wbc: error: the benchmarks live in the source repository, not in the installed package; "
              "run `wbc bench` from a checkout (or use an editable install: pip install -e .)", file=sys.stderr)
        return 2
    if str(root) not in sys.path:
        sys.path.insert(0, str(root))
    module = importlib.import_module(f"benchmarks.{args.suite}")
    return module.main(args.options)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="wbc", description="QP whole-body velocity control")
    sub = parser.add_subparsers(dest="command", required=True)
    run_parser = sub.add_parser("run", help="run a scenario (tasks/*.toml) in closed loop")
    run_parser.add_argument("scenario", help="path of a scenario TOML file")
    run_parser.add_argument("--plot", metavar="FILE.png", help="write a figure of the run")
    run_parser.add_argument("--solver", help="override the scenario's QP solver")
    run_parser.add_argument("--duration", type=float, help="override the duration [s]")
    run_parser.add_argument("--json", action="store_true", help="print the summary as JSON")
    run_parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    run_parser.set_defaults(handler=_run)
    solvers_parser = sub.add_parser("solvers", help="list the installed QP solvers")
    solvers_parser.set_defaults(handler=_solvers)
    bench_parser = sub.add_parser("bench", help="run a benchmark suite of benchmarks/ (needs a source checkout)",
                                  description="Runs python -m benchmarks.SUITE; options after SUITE go to it "
                                              "(e.g. wbc bench solvers --ticks 50; wbc bench peers --help).")
    bench_parser.add_argument("suite", choices=BENCH_SUITES)
    bench_parser.add_argument("options", nargs=argparse.REMAINDER, help="options of the suite")
    bench_parser.set_defaults(handler=_bench)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.handler(args)
    except WbcError as exc:
        print(f"wbc: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
