"""Command line: ``wbc run SCENARIO [SCENARIO ...] [--plot FILE.png] [--html FILE.html] [--view [PORT]]
[--sim mujoco]``, ``wbc ros SCENARIO --config FILE``, ``wbc scenarios``, ``wbc solvers``,
``wbc singularities MODEL``, ``wbc bench SUITE``, ``wbc warmup``."""

from __future__ import annotations

import argparse
import atexit
import contextlib
import importlib
import json
import math
import os
import sys
import threading
from collections.abc import Callable, Iterator, Mapping, Sequence
from pathlib import Path
from types import ModuleType
from typing import TYPE_CHECKING, Any, NoReturn, TextIO

from .. import __version__
from ..core.errors import WbcError

if TYPE_CHECKING:  # (imported when a command needs them: `wbc solvers` loads no simulation or viewer)
    from .closed_loop import RunResult
    from .scenario import Scenario
    from .simulation import MujocoSimulation
    from .view import LiveView

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib


class CommandLineError(WbcError, ValueError):
    """An option of the command line is invalid or needs something not installed."""


def _run(args: argparse.Namespace) -> int:
    from .closed_loop import collision_traces, manipulability_traces, run
    from .scenario import load_scenario

    _check_run_options(args)
    scenarios = [load_scenario(path) for path in args.scenario]
    if args.duration is not None:
        _check_duration(args.duration, scenarios)
    messages = sys.stderr if args.json else sys.stdout  # with --json, stdout holds the JSON alone
    try:
        with _live_view(args, scenarios, messages) as live:
            runs = [(scenario, run(scenario, solver=args.solver, duration=args.duration,
                                   progress=not args.no_progress,
                                   simulation=_simulation(args, scenario),
                                   on_tick=None if live is None else live.follow(k)))
                    for k, scenario in enumerate(scenarios)]
            trace, distances = manipulability_traces(runs), collision_traces(runs)
            summaries: list[dict[str, Any]] = [
                {"scenario": scenario.name, "solver": result.solver} | _loop(result) | result.summary()
                | ({} if trace is None else trace.summary(k)) | ({} if distances is None else distances.summary(k))
                | _conflicts(result) for k, (scenario, result) in enumerate(runs)]
            if args.json:
                print(json.dumps(summaries, indent=2))
            else:
                print("\n".join(format_summary(scenario.name, result.solver, summary)
                                for (scenario, result), summary in zip(runs, summaries, strict=True)))
            _write_outputs(args, runs, messages)
            if live is not None:
                _replay(live, messages)
    except KeyboardInterrupt:  # during a run or while a file is written (none is left half-written)
        print("wbc: interrupted", file=sys.stderr)
        return 130
    return 0


def _ros(args: argparse.Namespace) -> int:
    _require("cyclonedds", "wbc ros", "ros")
    from ..ros.launch import main as ros_main

    return ros_main(args.scenario, args.config, args.duration, args.solver, args.json)


def _loop(result: RunResult) -> dict[str, str]:
    """How a run closed its loop, for its summary: "kinematic", or "mujoco" and the servo settings."""
    return {"loop": result.loop} | ({"loop_details": result.loop_details} if result.loop_details else {})


def _write_outputs(args: argparse.Namespace, runs: Sequence[tuple[Scenario, RunResult]], messages: TextIO) -> None:
    """Write the ``--plot`` and ``--html`` files (their paths were checked before the runs),
    each atomically, and say where."""
    from .outputs import OutputError

    writers: list[tuple[str, str, Callable[[], Path]]] = []
    if args.plot is not None:
        from .plotting import plot_runs

        writers.append(("--plot", "plot", lambda: plot_runs(runs, args.plot)))
    if args.html is not None:
        from .view import scenario_obstacles, write_html

        obstacles = scenario_obstacles([scenario for scenario, _ in runs])
        writers.append(("--html", "3-D replay", lambda: write_html(runs, args.html, obstacles)))
    for option, what, write in writers:
        try:
            path = write()
        except (OSError, OutputError) as exc:  # e.g. the disk filled up, or the folder went away
            raise CommandLineError(f"{option}: the {what} was not written: {exc}") from exc
        print(f"{what} written to {path}", file=messages)


@contextlib.contextmanager
def _live_view(args: argparse.Namespace, scenarios: Sequence[Scenario], out: TextIO) -> Iterator[LiveView | None]:
    """With ``--view``: a LiveView of the runs to come, its URL printed before they start
    (they are then streamed into it in real time); else None."""
    if args.view is None:
        yield None
        return
    from .closed_loop import tick_count
    from .view import LiveView, scenario_obstacles

    with LiveView([(scenario, tick_count(scenario, args.duration)) for scenario in scenarios],
                  port=args.view, obstacles=scenario_obstacles(scenarios)) as live:
        print(f"3-D view at {live.url}: the run(s) stream live, then replay (Ctrl-C to stop)", file=out, flush=True)
        yield live


def _replay(live: LiveView, out: TextIO) -> None:
    """Serve the replay of the finished runs until Ctrl-C."""
    import threading

    try:
        print("3-D view: replaying the run(s) (Ctrl-C to stop)", file=out, flush=True)
        live.serve(threading.Event())
    except KeyboardInterrupt:
        pass


def _check_run_options(args: argparse.Namespace) -> None:
    """Everything that can be refused or prepared before the (possibly long) runs."""
    if args.duration is not None and not 0.0 < args.duration < math.inf:
        raise CommandLineError(f"--duration must be a finite number of seconds > 0, got {args.duration}")
    if args.sim != "mujoco" and (args.noise is not None or args.delay is not None):
        raise CommandLineError("--noise and --delay act on the MuJoCo loop only; add --sim mujoco")
    if args.noise is not None and not 0.0 <= args.noise < math.inf:
        raise CommandLineError(f"--noise is a standard deviation [rad, m]: finite and >= 0, got {args.noise}")
    if args.sim == "mujoco":
        _require("mujoco", "--sim mujoco", "sim")
    if args.plot is not None:
        _require("matplotlib", "--plot", "plot")
        from .plotting import PLOT_FORMATS

        _check_output("--plot", args.plot, PLOT_FORMATS)
    if args.view is not None and not 0 < args.view < 65536:
        raise CommandLineError(f"--view PORT must be a TCP port, 1 to 65535, got {args.view}")
    if args.html is not None or args.view is not None:
        _require("viser", "--html" if args.html is not None else "--view", "view")
    if args.html is not None:
        from .outputs import HTML_FORMATS

        _check_output("--html", args.html, HTML_FORMATS)


def _check_duration(duration: float, scenarios: Sequence[Scenario]) -> None:
    """``--duration`` gives every scenario 1 to MAX_TICKS ticks (the bound its own file is held to)."""
    from .closed_loop import tick_count
    from .scenario import MAX_TICKS

    for scenario in scenarios:
        ticks = tick_count(scenario, duration)
        if not 1 <= ticks <= MAX_TICKS:
            raise CommandLineError(f"--duration {duration:g} s is {ticks} ticks of {scenario.name} (dt = "
                                   f"{scenario.dt:g} s); give at least one tick and at most {MAX_TICKS:.0e} "
                                   f"(between {scenario.dt:g} and {MAX_TICKS * scenario.dt:g} s)")


def _check_output(option: str, path: str, formats: Mapping[str, str]) -> None:
    """Refuse now, before any run, a file ``option`` could not write (nothing is created:
    a missing folder is made when the file is written)."""
    from .outputs import OutputError, check_output

    try:
        check_output(path, formats)
    except OutputError as exc:
        raise CommandLineError(f"{option}: {exc}") from None


def _require(module: str, option: str, extra: str) -> None:
    """Import ``module`` now, or say which extra of wbc installs it."""
    try:
        importlib.import_module(module)
    except ImportError as exc:
        raise CommandLineError(f"{option} needs {module}, which is not installed: "
                               f'pip install "wbc[{extra}]"') from exc


def _simulation(args: argparse.Namespace, scenario: Scenario) -> MujocoSimulation | None:
    """The MuJoCo loop asked for by ``--sim mujoco``, or None for the kinematic loop."""
    if args.sim != "mujoco":
        return None
    from .simulation import MujocoSimulation

    return MujocoSimulation(scenario.robot, scenario.dt, noise=args.noise or 0.0, delay=args.delay or 0)


def _conflicts(result: RunResult) -> dict[str, list[dict[str, Any]]]:
    """The run's episodes of fallback ticks and the constraints in conflict at each (summary entry)."""
    return {"conflicts": [{"tick": episode.tick, "constraints": list(episode.constraints)}
                          for episode in result.conflicts]}


def format_summary(name: str, solver: str, s: Mapping[str, Any]) -> str:
    """The summary of one run as ``wbc run`` prints it (``s``: the run's summary, as in ``--json``:
    numbers, and strings for the loop and the manipulability's frame and rows)."""
    tracked = "orientation_error_rms_rad" in s
    lines = [
        f"scenario {name}  (solver {solver}, {_loop_text(s)})",
        f"  ticks                      {s['ticks']}  ({s['fallback_ticks']} answered by a fallback)",
        f"  position error   rms / max {s['position_error_rms_m'] * 1e3:.4f} / "
        f"{s['position_error_max_m'] * 1e3:.4f} mm",
        f"  orientation err  rms / max {s['orientation_error_rms_rad'] * 1e3:.4f} / "
        f"{s['orientation_error_max_rad'] * 1e3:.4f} mrad" if tracked else
        "  orientation err            not tracked (no orientation cost in the reference task)",
        f"  final error      pos / ori {s['final_position_error_m'] * 1e3:.2e} mm / "
        f"{s['final_orientation_error_rad'] * 1e3:.2e} mrad" if tracked else
        f"  final error      pos       {s['final_position_error_m'] * 1e3:.2e} mm",
        f"  worst limit violation      position {s['worst_position_limit_violation']:.2e}, "
        f"velocity {s['worst_velocity_limit_violation']:.2e}",
        f"  tick latency median / p99  {s['tick_latency_median_us']:.1f} / {s['tick_latency_p99_us']:.1f} µs"
        f"  (solve median {s['solve_time_median_us']:.1f} µs)",
    ]
    if "collision_distance_min_m" in s:
        sampled = (f"  (sampled: one tick in {s['collision_sampled_every_ticks']})"
                   if "collision_sampled_every_ticks" in s else "")
        lines.append(f"  collision distance min     {s['collision_distance_min_m'] * 1e3:.2f} mm  "
                     f"(min_distance {s['collision_margin_m'] * 1e3:g} mm){sampled}")
    for episode in s.get("conflicts", []):
        named = ", ".join(episode["constraints"]) or "none found (the backend failed on a feasible QP)"
        lines.append(f"  fallback from tick {episode['tick']:<8d} constraints in conflict: {named}")
    if "worst_wheel_speed_ratio" in s:
        lines.append(f"  worst wheel speed          {s['worst_wheel_speed_ratio'] * 100:.1f} % of its limit")
    if "max_lateral_slip_m_s" in s:
        lines.append(f"  max lateral base slip      {s['max_lateral_slip_m_s']:.2e} m/s")
    if "manipulability_min" in s:
        floor = f"  (barrier floor m_min {s['manipulability_floor']:g})" if "manipulability_floor" in s else ""
        sampled = (f"  (sampled: one tick in {s['manipulability_sampled_every_ticks']})"
                   if "manipulability_sampled_every_ticks" in s else "")
        lines.append(f"  manipulability   min       {s['manipulability_min']:.4g}  "
                     f"of '{s['manipulability_frame']}', {s['manipulability_rows']} rows{floor}{sampled}")
    return "\n".join(lines)


def _loop_text(s: Mapping[str, Any]) -> str:
    """How the run closed its loop, from its summary ("kinematic loop" when not said)."""
    if s.get("loop") == "mujoco":
        return f"MuJoCo loop: {s['loop_details']}" if s.get("loop_details") else "MuJoCo loop"
    return "kinematic loop"


def _solvers(args: argparse.Namespace) -> int:
    from ..solvers import available_solvers

    print("\n".join(available_solvers()))
    return 0


def _scenarios(args: argparse.Namespace) -> int:
    from ..model import shipped

    names = shipped.scenario_names()
    width = max(map(len, names))
    print("\n".join(f"{name:<{width}}  {shipped.scenario_description(name)}" for name in names))
    print(f"(run one by name: wbc run {names[0]}; the files are in {shipped.folder('scenarios')})")
    return 0


def _warmup(args: argparse.Namespace) -> int:
    """Load every compiled kernel -- compiling it if the cache is cold -- and say how long it took."""
    import time

    from ..collision.warm_up import warm_up as warm_up_collision
    from ..runtime import kernels

    start = time.perf_counter()
    kernels.warm_up()
    warm_up_collision()
    elapsed = time.perf_counter() - start
    where = kernels.cache_directory
    print(f"numba kernels ready in {elapsed:.1f} s ("
          + (f"cached in {where})" if where is not None else "not cached: numba found no writable cache directory)"))
    return 0


def _singularities(args: argparse.Namespace) -> int:
    import numpy as np

    from ..analysis.singularity import singular_systems, verify
    from ..model.robot import load_robot

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
            all_agree &= report.agree == report.total > 0  # a check that ran no case confirms nothing
            print(f"    {report.agree:6d} / {report.total:<6d} agree   {report.label}")
    print("all agree" if all_agree else "DISAGREEMENT: conditions not confirmed")
    return 0 if all_agree else 1


BENCH_SUITES = ("solvers", "peers", "scaling", "dataset")


def is_checkout(root: Path) -> bool:
    """Whether ``root`` is a source checkout of wbc: ``benchmarks/__init__.py`` next to a
    pyproject.toml of the project named "wbc"."""
    try:
        with open(root / "pyproject.toml", "rb") as stream:
            project = tomllib.load(stream).get("project", {})
    except (OSError, tomllib.TOMLDecodeError):
        return False
    return project.get("name") == "wbc" and (root / "benchmarks" / "__init__.py").is_file()


def find_benchmarks(checkout: Path | None = None) -> Path | None:
    """The source checkout holding ``benchmarks/`` (not part of the installed package):
    ``checkout`` if given, else the checkout of an editable install (the folder above the
    ``wbc`` package). The current directory is never searched: code found there would run."""
    root = Path(checkout) if checkout is not None else Path(__file__).resolve().parents[2]  # (wbc/app/cli.py)
    return root.resolve() if is_checkout(root) else None


def _bench(args: argparse.Namespace) -> int:
    root = find_benchmarks(args.checkout)
    if root is None:
        where = (f"--checkout {args.checkout} is not a wbc source checkout (benchmarks/ and a pyproject.toml "
                 "naming project wbc)" if args.checkout else
                 "the benchmarks live in the source repository, not in the installed package")
        raise CommandLineError(f"{where}; use an editable install (pip install -e .) or --checkout PATH")
    module = _import_suite(root, args.suite)
    return module.main(args.options)


def _import_suite(root: Path, suite: str) -> ModuleType:
    """``benchmarks.<suite>`` of ``root``, whatever else a ``benchmarks`` on sys.path holds."""
    loaded = sys.modules.get("benchmarks")
    if loaded is not None and Path(getattr(loaded, "__file__", "") or "").resolve().parent != root / "benchmarks":
        for name in [n for n in sys.modules if n == "benchmarks" or n.startswith("benchmarks.")]:
            del sys.modules[name]
    if sys.path[:1] != [str(root)]:
        sys.path.insert(0, str(root))
    return importlib.import_module(f"benchmarks.{suite}")


def _count(least: int) -> Callable[[str], int]:
    """An argparse type: an integer >= ``least`` (argparse turns the ValueError into a usage error)."""
    def parse(text: str) -> int:
        value = int(text)
        if value < least:
            raise ValueError(f"{value} < {least}")
        return value

    parse.__name__ = f"integer >= {least}"  # what argparse names in "invalid ... value"
    return parse


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="wbc", description="QP whole-body velocity control")
    parser.add_argument("--version", action="version", version=f"wbc {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    run_parser = sub.add_parser("run", help="run scenarios (TOML files, or shipped scenarios by name) in closed loop")
    run_parser.add_argument("scenario", nargs="+",
                            help="a scenario TOML file, or the name of a shipped scenario (wbc scenarios lists "
                                 "them); give several to compare")
    run_parser.add_argument("--plot", metavar="FILE.png", help="write a figure of the run(s), overlaid")
    run_parser.add_argument("--html", metavar="FILE.html",
                            help="write a 3-D replay of the run(s): one self-contained page, no server needed")
    run_parser.add_argument("--view", nargs="?", type=int, const=8080, metavar="PORT",
                            help="serve a 3-D view at http://127.0.0.1:PORT (default 8080, or the next free "
                                 "port): the run(s) stream into it in real time (held to real time, so a 20 s "
                                 "scenario takes 20 s), then replay until Ctrl-C")
    run_parser.add_argument("--solver", help="override the scenario's QP solver")
    run_parser.add_argument("--duration", type=float, help="override the duration [s]")
    run_parser.add_argument("--json", action="store_true",
                            help="print the summaries as JSON: always a list with one object per scenario, in "
                                 "the order given, each with 'scenario', 'solver' and the numbers of the text "
                                 "summary (units in the key names: _m, _rad, _us); stdout then holds the JSON alone")
    run_parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    run_parser.add_argument("--sim", choices=["kinematic", "mujoco"], default="kinematic",
                            help="close the loop by integrating v (default) or through MuJoCo velocity servos")
    run_parser.add_argument("--noise", type=float,
                            help="with --sim mujoco: std of the position measurement noise [rad, m] (default 0)")
    run_parser.add_argument("--delay", type=int, choices=[0, 1],
                            help="with --sim mujoco: ticks between command and actuation (default 0)")
    run_parser.set_defaults(handler=_run)
    ros_parser = sub.add_parser("ros", help="run a scenario's controller as a ROS 2 node over DDS (extra [ros])")
    ros_parser.add_argument("scenario", help="a scenario TOML file or the name of a shipped scenario")
    ros_parser.add_argument("--config", required=True, metavar="FILE",
                            help="the node's topics and joints (TOML), or a shipped configuration's name (youbot)")
    ros_parser.add_argument("--duration", type=float, help="stop after this many seconds (default: SIGINT/SIGTERM)")
    ros_parser.add_argument("--solver", help="override the scenario's QP solver")
    ros_parser.add_argument("--json", action="store_true", help="print the summary at exit as JSON on stdout")
    ros_parser.set_defaults(handler=_ros)
    scenarios_parser = sub.add_parser("scenarios", help="list the shipped scenarios (wbc run NAME runs one)")
    scenarios_parser.set_defaults(handler=_scenarios)
    solvers_parser = sub.add_parser("solvers", help="list the installed QP solvers")
    solvers_parser.set_defaults(handler=_solvers)
    warmup_parser = sub.add_parser("warmup", help="compile (or load) the numba kernels now and report the time",
                                   description="Pays the one-time compilation after an install (~20 s) up front, "
                                               "e.g. in an installer or a Docker build; later runs load the cache.")
    warmup_parser.set_defaults(handler=_warmup)
    sing_parser = sub.add_parser("singularities", help="print a model's certified singular conditions and check them")
    sing_parser.add_argument("model", help="shipped model name (e.g. youbot, scorbot_er4pc, puma560)")
    sing_parser.add_argument("--samples", type=_count(1), default=2000, help="random configurations per subsystem")
    sing_parser.add_argument("--on-set", type=_count(1), default=200, help="configurations on (and near) each set")
    sing_parser.add_argument("--seed", type=_count(0), default=0, help="random seed (an integer >= 0)")
    sing_parser.set_defaults(handler=_singularities)
    bench_parser = sub.add_parser("bench", help="run a benchmark suite of benchmarks/ (needs a source checkout)",
                                  description="Runs python -m benchmarks.SUITE; options after SUITE go to it "
                                              "(e.g. wbc bench solvers --ticks 50; wbc bench peers --help).")
    bench_parser.add_argument("--checkout", type=Path, metavar="PATH",
                              help="the wbc source checkout to take benchmarks/ from (default: the checkout of "
                                   "an editable install; the current directory is never searched)")
    bench_parser.add_argument("suite", choices=BENCH_SUITES)
    bench_parser.add_argument("options", nargs=argparse.REMAINDER, help="options of the suite")
    bench_parser.set_defaults(handler=_bench)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``wbc``: 0 on success, 2 with ``wbc: error: ...`` on stderr for a wbc
    error, 1 (quietly) when the reader of stdout goes away (``wbc ... | head``)."""
    args = build_parser().parse_args(argv)
    try:
        status = args.handler(args)
        sys.stdout.flush()
        return status
    except WbcError as exc:
        print(f"wbc: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:  # Ctrl-C in any command (wbc run handles its own, mid-run)
        print("wbc: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # Python's recipe: point stdout at devnull so the flush at exit does not fail again
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 1


def console() -> NoReturn:
    """The ``wbc`` executable (and ``python -m wbc``): :func:`main`, then the process ends without
    Python's teardown. Freeing every module and object at exit -- numba's and LLVM's compiled code,
    Pinocchio's models -- takes 0.2-0.35 s after a ``wbc run`` (measured in session 24), longer than
    many runs, and frees nothing the operating system does not reclaim anyway. What an exit must do
    still happens, in Python's order: non-daemon threads are waited for (then the ordinary exit is
    taken), the ``atexit`` handlers run (the compile workers are stopped, logging is flushed,
    ``weakref.finalize`` callbacks run), stdout and stderr are flushed; only then ``os._exit(status)``.
    Every file wbc writes is closed when written. (mypy ends the same way, ``mypy.util.hard_exit``.)"""
    status = main()
    if any(thread.is_alive() and not thread.daemon for thread in threading.enumerate()
           if thread is not threading.main_thread()):
        sys.exit(status)  # (Python's exit waits for them)
    atexit._run_exitfuncs()
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):  # (the reader went away: as main's BrokenPipeError)
            status = status or 1
    os._exit(status)


if __name__ == "__main__":
    console()
