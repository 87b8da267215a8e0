"""Command line: ``wbc run SCENARIO [SCENARIO ...] [--plot FILE.png] [--sim mujoco]``, ``wbc solvers``,
``wbc singularities MODEL``, ``wbc bench SUITE``."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from .errors import WbcError


def _run(args: argparse.Namespace) -> int:
    from .closed_loop import run
    from .scenario import load_scenario

    scenarios = [load_scenario(path) for path in args.scenario]
    runs = [(scenario, run(scenario, solver=args.solver, duration=args.duration, progress=not args.no_progress,
                           simulation=_simulation(args, scenario)))
            for scenario in scenarios]
    summaries = [result.summary() for _, result in runs]
    if args.json:
        named = [{"scenario": scenario.name} | summary for (scenario, _), summary in zip(runs, summaries)]
        print(json.dumps(summaries[0] if len(runs) == 1 else named, indent=2))
    else:
        print("\n".join(format_summary(scenario.name, result.solver, summary)
                        for (scenario, result), summary in zip(runs, summaries)))
    if args.plot:
        from .plotting import manipulability_traces, plot_runs

        path = plot_runs([result for _, result in runs], args.plot, scenarios[0].robot.joint_names,
                         manipulability_traces(runs))
        print(f"plot written to {path}")
    return 0


def _simulation(args: argparse.Namespace, scenario):
    """The MuJoCo loop asked for by ``--sim mujoco``, or None for the kinematic loop."""
    if args.sim != "mujoco":
        return None
    from .simulation import MujocoSimulation

    return MujocoSimulation(scenario.robot, scenario.dt, noise=args.noise, delay=args.delay)


def format_summary(name: str, solver: str, s: dict) -> str:
    return "\n".join([
        f"scenario {name}  (solver {solver})",
        f"  ticks                      {s['ticks']}  ({s['fallback_ticks']} answered by a fallback)",
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


def _singularities(args: argparse.Namespace) -> int:
    import numpy as np

    from .robot import load_robot
    from .singularity import singular_systems, verify

    robot = load_robot(args.model)
    rng = np.random.default_rng(args.seed)
    all_agree = True
    for system in singular_systems(robot):
        print(f"{robot.name} / {system.name}: {system.description}")
        print(f"  frame {system.frame!r}, full rank {system.full_rank}; singular where any of:")
        for condition in system.conditions:
            print(f"  - {condition.name}  [rank {condition.rank}]\n      {condition.formula}")
        print("  numeric check (rank of the Pinocchio Jacobian vs the conditions):")
        for report in verify(robot, rng, samples=args.samples, on_set=args.on_set, subsystem=system.name):
            all_agree &= report.agree == report.total
            print(f"    {report.agree:6d} / {report.total:<6d} agree   {report.label}")
    print("all agree" if all_agree else "DISAGREEMENT: conditions not confirmed")
    return 0 if all_agree else 1


BENCH_SUITES = ("solvers", "peers", "scaling", "dataset")


def find_benchmarks() -> Path | None:
    """The source checkout holding ``benchmarks/`` (not part of the installed package):
    the current directory or one of its parents, else the checkout of an editable install."""
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
    run_parser = sub.add_parser("run", help="run scenarios (tasks/*.toml) in closed loop")
    run_parser.add_argument("scenario", nargs="+", help="path of a scenario TOML file; give several to compare")
    run_parser.add_argument("--plot", metavar="FILE.png", help="write a figure of the run(s), overlaid")
    run_parser.add_argument("--solver", help="override the scenario's QP solver")
    run_parser.add_argument("--duration", type=float, help="override the duration [s]")
    run_parser.add_argument("--json", action="store_true", help="print the summary as JSON")
    run_parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    run_parser.add_argument("--sim", choices=["kinematic", "mujoco"], default="kinematic",
                            help="close the loop by integrating v (default) or through MuJoCo velocity servos")
    run_parser.add_argument("--noise", type=float, default=0.0,
                            help="with --sim mujoco: std of the position measurement noise [rad, m]")
    run_parser.add_argument("--delay", type=int, choices=[0, 1], default=0,
                            help="with --sim mujoco: ticks between command and actuation")
    run_parser.set_defaults(handler=_run)
    solvers_parser = sub.add_parser("solvers", help="list the installed QP solvers")
    solvers_parser.set_defaults(handler=_solvers)
    sing_parser = sub.add_parser("singularities", help="print a model's certified singular conditions and check them")
    sing_parser.add_argument("model", help="shipped model name (e.g. youbot, scorbot_er4pc, puma560)")
    sing_parser.add_argument("--samples", type=int, default=2000, help="random configurations per subsystem")
    sing_parser.add_argument("--on-set", type=int, default=200, help="configurations on (and near) each set")
    sing_parser.add_argument("--seed", type=int, default=0, help="random seed")
    sing_parser.set_defaults(handler=_singularities)
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
