"""Command line: ``wbc run SCENARIO [--plot FILE.png]``, ``wbc solvers``, ``wbc singularities MODEL``."""

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
    ])


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
    sing_parser = sub.add_parser("singularities", help="print a model's certified singular conditions and check them")
    sing_parser.add_argument("model", help="shipped model name (e.g. youbot, scorbot_er4pc, puma560)")
    sing_parser.add_argument("--samples", type=int, default=2000, help="random configurations per subsystem")
    sing_parser.add_argument("--on-set", type=int, default=200, help="configurations on (and near) each set")
    sing_parser.add_argument("--seed", type=int, default=0, help="random seed")
    sing_parser.set_defaults(handler=_singularities)
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
