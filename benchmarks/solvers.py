"""QP solver comparison on wbc's control QPs: qpbenchmark on the wbc test set, then wbc's tables.

    python -m benchmarks.solvers [--ticks 200] [--settings default high_accuracy ...]
                                 [--solvers daqp osqp ...] [--scenarios ...] [--qpbenchmark-only]
                                 [--starts N] [--workers N | --scheduler ADDRESS]
                                 [--out benchmarks/output/solvers]

1. The test set is :class:`benchmarks.wbc_qpbenchmark.WbcQpbenchmark`: ``--ticks`` ticks of
   every scenario of :mod:`benchmarks.dataset` (recorded first if missing), half with an active
   bound or inequality where the scenario has both.
2. qpbenchmark runs it (``qpbenchmark.run``: every installed solver it knows, at its settings
   ``default``, ``high_accuracy`` (1e-9), ``low_accuracy`` (1e-3), ``mid_accuracy`` (1e-6),
   one timed cold solve per problem, solver and settings, in that order), part by part
   (``PART_TICKS`` ticks: its results table grows by a pandas concatenation per solve,
   quadratic in the set's size). Output: ``results.csv`` (qpbenchmark's format) and
   qpbenchmark's own report ``wbc_qpbenchmark.md`` in ``--out``.
3. wbc's back-to-back pass: per problem, every solver and settings cold, and warm from the
   previous tick's reference solution for the backends whose qpsolvers wrapper uses
   ``initvals`` (qpbenchmark is cold-start only), all in a random order, with nothing run in
   between (qpbenchmark records each result in pandas between two solves).
4. ``report.md``: qpbenchmark's metrics (success rate, shifted geometric mean of runtimes with
   shift 10 s, failures at the time limit, and of residuals), plus what they leave out on
   µs-scale QPs (the same mean with shift 10 µs, median, p99, solves slower than the control
   period, largest residuals, distance to the reference solution), per scenario and with /
   without active constraints; the back-to-back pass next to qpbenchmark's; plots.

5. Sweeps: ``--starts N`` adds N - 1 seeded perturbed starts of every scenario
   (:mod:`benchmarks.starts`). Steps 2 and 3 run as work units (one scenario and start, at most
   ``UNIT_PROBLEMS`` QPs, both passes) here one after another, or with ``--workers N`` on a local
   Dask cluster of N processes, with ``--scheduler ADDRESS`` on an existing one
   (:mod:`benchmarks.sweep`, extra ``[distributed]``); gathered in the test set's order, every
   column but the timings equals the serial run's. Timings of a parallel run share the cores:
   take timing tables from a serial run.

Conventions and where they differ from qpbenchmark's: benchmarks/README.md, section 2.
"""

from __future__ import annotations

import argparse
import csv
import inspect
import logging
import os
import sys
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas
import qpbenchmark
import qpsolvers
from qpbenchmark.utils import time_solve_problem

from wbc.solvers import make_solver

from . import dataset as ds
from . import sweep
from .common import OUTPUT, fmt, machine_note, markdown_table, package_versions, shifted_geometric_mean
from .wbc_qpbenchmark import SETTINGS, TICKS, WbcProblem, WbcQpbenchmark

#: problems per call of ``qpbenchmark.run`` (its cost per solve grows with its results table)
PART_TICKS = 25
#: problems per work unit at most (a unit holds the QPs of one scenario and start)
UNIT_PROBLEMS = 50
#: qpbenchmark's shift [s] (its report's runtime and residual means)
SHIFT_S = 10.0
#: wbc's shift [µs]: the same 10, in the unit of these runtimes
SHIFT_US = 10.0
#: does the qpsolvers wrapper (4.x) pass ``initvals`` on to the backend? (read from its source)
WARM_START = {
    "daqp": "primal_start", "osqp": "warm_start(x)", "proxqp": "x (WARM_START)", "scs": "warm start x",
    "cvxopt": "initvals", "qpoases": None,
    "quadprog": None, "clarabel": None, "piqp": None, "highs": None, "ecos": None,
}
_DIST = {"proxqp": "proxsuite", "highs": "highspy"}
#: qpbenchmark >= 2.4 draws a progress bar per run unless ``verbose`` (then it logs each solve at INFO)
_QUIET_RUN = {"verbose": True} if "verbose" in inspect.signature(qpbenchmark.run).parameters else {}


class ExtendedResults(qpbenchmark.Results):
    """qpbenchmark's results table, plus per solve what it leaves out: the distance to the
    reference solution and qpsolvers' ``solve_time`` (without its build phase)."""

    def __init__(self, file_path: Path, test_set: WbcQpbenchmark) -> None:
        super().__init__(str(file_path), test_set)
        self.extras: dict[tuple[str, str, str], dict] = {}

    def update(self, problem: WbcProblem, solver: str, settings: str, solution: qpsolvers.Solution,
               runtime: float) -> None:
        super().update(problem, solver, settings, solution, runtime)
        self.extras[problem.name, solver, settings] = solution_extras(problem, solution)


def solution_extras(problem: WbcProblem, solution: qpsolvers.Solution) -> dict:
    """``ref_error`` = max |x - x_ref| (inf when nothing finite was found), ``solve_time`` [s]."""
    x = solution.x if solution.found else None
    finite = x is not None and bool(np.all(np.isfinite(x)))
    solve_time = getattr(solution, "solve_time", None)
    return {"ref_error": float(np.max(np.abs(x - problem.x_ref))) if finite else np.inf,
            "solve_time": np.nan if solve_time is None else float(solve_time)}


@contextmanager
def _quiet_logging() -> Iterator[None]:
    """qpbenchmark logs to the root logger at INFO: keep its warnings, drop the chatter."""
    root = logging.getLogger()
    level = root.level
    root.setLevel(logging.WARNING)
    try:
        yield
    finally:
        root.setLevel(level)


def run_qpbenchmark(test_set: WbcQpbenchmark) -> tuple[pandas.DataFrame, dict]:
    """``qpbenchmark.run`` over ``test_set``, part by part: (its results table, the extras). The
    table's rows in the test set's order: problem, solver by name, settings in the set's order
    (``qpbenchmark.run`` goes through the solvers in the order of a ``set``, which differs between
    processes)."""
    frames, extras = [], {}
    with tempfile.TemporaryDirectory() as folder, _quiet_logging():
        for i, part in enumerate(test_set.parts(PART_TICKS)):
            results = ExtendedResults(Path(folder) / f"part{i}.csv", part)
            qpbenchmark.run(part, results, **_QUIET_RUN)
            frames.append(results.df)
            extras.update(results.extras)
    df = pandas.concat(frames, ignore_index=True)
    problem_rank = {problem.name: i for i, problem in enumerate(test_set)}
    settings_rank = {settings: i for i, settings in enumerate(test_set.solver_settings)}
    order = sorted(range(len(df)), key=lambda i: (problem_rank[df["problem"].iat[i]], df["solver"].iat[i],
                                                  settings_rank[df["settings"].iat[i]]))
    return df.iloc[order].reset_index(drop=True), extras


def make_rows(df: pandas.DataFrame, extras: dict, test_set: WbcQpbenchmark) -> list[dict]:
    """One row per solve: qpbenchmark's columns, the problem's origin, success, the extras."""
    problems = {problem.name: problem for problem in test_set}
    rows = []
    for record in df.to_dict("records"):
        problem = problems[record["problem"]]
        key = (record["problem"], record["solver"], record["settings"])
        residuals = (record["primal_residual"], record["dual_residual"], record["duality_gap"])
        rows.append(result_row("qpbenchmark", problem, record["solver"], record["settings"], False,
                               bool(record["found"]), record["runtime"], residuals, extras[key], test_set))
    return rows


def result_row(source: str, problem: WbcProblem, solver: str, settings: str, warm: bool, found: bool,
               runtime: float, residuals: tuple[float, float, float], extras: dict, test_set: WbcQpbenchmark) -> dict:
    """A result row of pass ``source``; success as qpbenchmark counts it (found, residuals below
    the settings' tolerances)."""
    tolerance = test_set.tolerances[settings]
    primal, dual, gap = (float(np.nan if value is None else value) for value in residuals)
    success = found and primal < tolerance.primal and dual < tolerance.dual and gap < tolerance.gap
    return {"pass": source, "problem": problem.name, "scenario": problem.scenario, "start": problem.start,
            "tick": problem.tick, "active": problem.active, "solver": solver, "settings": settings, "warm": warm,
            "found": found,
            "success": bool(success), "runtime": float(runtime), "time_limit": tolerance.runtime,
            "primal_residual": primal, "dual_residual": dual, "duality_gap": gap, **extras}


def back_to_back_configs(test_set: WbcQpbenchmark) -> list[tuple[str, str, bool]]:
    """(solver, settings, warm) of the back-to-back pass: every solver and settings cold, and warm for
    the backends whose qpsolvers wrapper uses ``initvals``."""
    return [(solver, settings, warm) for solver in sorted(test_set.solvers) for settings in test_set.solver_settings
            for warm in ((False, True) if WARM_START.get(solver) else (False,))]


def pass_orders(test_set: WbcQpbenchmark, seed: int) -> list[np.ndarray]:
    """The back-to-back pass's random order of :func:`back_to_back_configs` for every problem of the
    set, drawn here once (seeded), so that a work unit runs its problems in the serial run's order."""
    rng = np.random.default_rng(seed)
    count = len(back_to_back_configs(test_set))
    return [rng.permutation(count) for _ in test_set]


def back_to_back_pass(test_set: WbcQpbenchmark, orders: list[np.ndarray]) -> list[dict]:
    """Per problem, every solver and settings cold, and warm (``initvals`` = the previous tick's
    reference solution) for the backends whose qpsolvers wrapper uses it, in the order ``orders``
    (one permutation of :func:`back_to_back_configs` per problem)."""
    configs = back_to_back_configs(test_set)
    rows: list[dict] = []
    with _quiet_logging():
        for problem, order in zip(test_set, orders, strict=True):
            for i in order:
                solver, settings, warm = configs[i]
                options = dict(test_set.solver_settings[settings][solver])
                if warm:
                    options["initvals"] = problem.x_previous.copy()
                solution, runtime = time_solve_problem(problem, solver, **options)
                residuals = (solution.primal_residual(), solution.dual_residual(), solution.duality_gap())
                rows.append(result_row("back to back", problem, solver, settings, warm, bool(solution.found),
                                       runtime, residuals, solution_extras(problem, solution), test_set))
    return rows


# ------------------------------------------------------------------------ work units
@dataclass
class Unit:
    """A piece of the sweep: consecutive problems of one scenario and start, both passes."""

    label: str
    test_set: WbcQpbenchmark  #: a subset: the problems' arrays and the settings, no recorded scenario
    orders: list[np.ndarray] | None  #: the back-to-back pass's order per problem; None: no back-to-back pass


@dataclass
class UnitResult:
    """What a unit gives back: qpbenchmark's results table and wbc's rows of both passes."""

    df: pandas.DataFrame
    rows: list[dict]
    second: list[dict]


def make_units(test_set: WbcQpbenchmark, seed: int, back_to_back: bool = True,
               size: int = UNIT_PROBLEMS) -> list[Unit]:
    """The test set cut into units in its order: per scenario and start, at most ``size`` problems each."""
    problems = list(test_set)
    orders = pass_orders(test_set, seed) if back_to_back else None
    units, first = [], 0
    while first < len(problems):
        origin = (problems[first].scenario, problems[first].start)
        last = first + 1
        while last < len(problems) and last - first < size and (problems[last].scenario,
                                                                 problems[last].start) == origin:
            last += 1
        label = f"{origin[0]} start {origin[1]} ticks {problems[first].tick}-{problems[last - 1].tick}"
        units.append(Unit(label, test_set.subset(problems[first:last]),
                          orders[first:last] if orders is not None else None))
        first = last
    return units


def run_unit(unit: Unit) -> UnitResult:
    """qpbenchmark's pass, then the back-to-back pass, on the unit's problems (here or on a worker)."""
    for name in unit.test_set.solvers:  # each backend's first use in this process, silenced (wbc.core.quiet)
        make_solver(name)
    df, extras = run_qpbenchmark(unit.test_set)
    rows = make_rows(df, extras, unit.test_set)
    return UnitResult(df, rows, [] if unit.orders is None else back_to_back_pass(unit.test_set, unit.orders))


def run_units(units: list[Unit], run: sweep.Mapper) -> tuple[pandas.DataFrame, list[dict], list[dict]]:
    """Every unit through ``run``; qpbenchmark's table and both passes' rows concatenated in the units' order."""
    results = run(run_unit, units, [unit.label for unit in units])
    return (pandas.concat([r.df for r in results], ignore_index=True), [row for r in results for row in r.rows],
            [row for r in results for row in r.second])


# ------------------------------------------------------------------------ metrics
def shgeom_floor(values: list[float], floor: float) -> float:
    """qpbenchmark's residual mean: values clipped from below at the tolerance, shift 10."""
    return shifted_geometric_mean(np.maximum(np.asarray(values, dtype=float), floor), SHIFT_S)


def summarize(rows: list[dict], tolerances: dict[str, qpbenchmark.Tolerance]) -> dict:
    """Aggregate metrics of one configuration (solver, settings, warm) over ``rows``."""
    tolerance = tolerances[rows[0]["settings"]]
    found = [r for r in rows if r["found"]]
    # qpbenchmark: the runtime of a solve that found nothing counts as the time limit
    runtime = np.array([r["runtime"] if r["found"] else r["time_limit"] for r in rows])
    solve_time = [r["solve_time"] * 1e6 for r in found if np.isfinite(r["solve_time"])]

    def residual_mean(key: str, tol: float) -> float:  # qpbenchmark: not found -> the tolerance
        return shgeom_floor([r[key] if r["found"] else tol for r in rows], tol)

    def largest(key: str) -> float:
        return float(np.max([r[key] for r in found])) if found else float("nan")

    return {
        "n": len(rows), "success": 100.0 * np.mean([r["success"] for r in rows]),
        "shm_s": shifted_geometric_mean(runtime, SHIFT_S),
        "shm_us": shifted_geometric_mean(runtime * 1e6, SHIFT_US),
        "median_us": float(np.median([r["runtime"] for r in rows]) * 1e6),
        "p99_us": float(np.percentile([r["runtime"] for r in rows], 99) * 1e6),
        "over_limit": 100.0 * np.mean([r["runtime"] > r["time_limit"] for r in rows]),
        "solve_shm_us": shifted_geometric_mean(solve_time, SHIFT_US) if solve_time else float("nan"),
        "primal_shm": residual_mean("primal_residual", tolerance.primal),
        "dual_shm": residual_mean("dual_residual", tolerance.dual),
        "gap_shm": residual_mean("duality_gap", tolerance.gap),
        "primal_max": largest("primal_residual"), "dual_max": largest("dual_residual"),
        "gap_max": largest("duality_gap"),
        "ref_median": float(np.median([r["ref_error"] for r in found])) if found else float("nan"),
        "ref_max": largest("ref_error"),
    }


def _label(key: tuple[str, bool]) -> str:
    return f"{key[0]} (warm)" if key[1] else key[0]


def config_stats(rows: list[dict], settings: str,
                 tolerances: dict[str, qpbenchmark.Tolerance]) -> dict[tuple[str, bool], dict]:
    """``summarize`` per (solver, warm) of the rows of ``settings``."""
    selected = [r for r in rows if r["settings"] == settings]
    keys = sorted({(r["solver"], r["warm"]) for r in selected})
    return {key: summarize([r for r in selected if (r["solver"], r["warm"]) == key], tolerances) for key in keys}


def settings_table(rows: list[dict], settings: str, tolerances: dict[str, qpbenchmark.Tolerance]) -> str:
    """Markdown table of every solver at ``settings``, fastest first (shm with shift 10 µs)."""
    stats = config_stats(rows, settings, tolerances)
    best_s = min(s["shm_s"] for s in stats.values())
    best_us = min(s["shm_us"] for s in stats.values())
    body = []
    for key in sorted(stats, key=lambda key: stats[key]["shm_us"]):
        s = stats[key]
        residual_ratios = [s[f"{name}_shm"] / min(t[f"{name}_shm"] for t in stats.values())
                           for name in ("primal", "dual", "gap")]
        body.append([
            _label(key), f"{s['success']:.1f}", f"{s['shm_s'] / best_s:.2f}", fmt(s["shm_s"] * 1e6),
            f"{fmt(s['shm_us'])} ({s['shm_us'] / best_us:.2f})", fmt(s["median_us"]), fmt(s["p99_us"]),
            fmt(s["solve_shm_us"]), fmt(s["over_limit"], 2),
            " / ".join(f"{ratio:.1f}" for ratio in residual_ratios),
            f"{s['primal_max']:.0e} / {s['dual_max']:.0e} / {s['gap_max']:.0e}",
            f"{s['ref_median']:.0e} / {s['ref_max']:.0e}"])
    return markdown_table(
        ["solver", "success %", "runtime shm ratio (shift 10 s)", "shm µs (shift 10 s)",
         "shm µs (shift 10 µs) (ratio)", "median µs", "p99 µs", "solve-only shm µs", "> time limit %",
         "residual shm ratios p / d / gap", "largest residual p / d / gap", "‖x − x_ref‖∞ median / max"], body)


def active_table(rows: list[dict], settings: str, tolerances: dict[str, qpbenchmark.Tolerance]) -> str:
    """Success, runtime and distance to the reference on QPs with and without an active constraint."""
    groups = {flag: config_stats([r for r in rows if r["active"] == flag], settings, tolerances)
              for flag in (True, False)}
    body = []
    for key in sorted(set(groups[True]) | set(groups[False])):
        cells = [_label(key)]
        for metric, form in (("n", "{:d}"), ("success", "{:.1f}"), ("shm_us", "{:.1f}"), ("ref_max", "{:.0e}")):
            cells.append(" / ".join(form.format(groups[flag][key][metric]) if key in groups[flag] else "-"
                                    for flag in (True, False)))
        body.append(cells)
    return markdown_table(["solver", "QPs", "success %", "shm µs (shift 10 µs)", "‖x − x_ref‖∞ max"], body)


def back_to_back_table(rows: list[dict], second: list[dict], settings: str,
                       tolerances: dict[str, qpbenchmark.Tolerance]) -> str:
    """The back-to-back pass (cold, warm where it runs) next to qpbenchmark's pass (``rows``)."""
    first, stats = config_stats(rows, settings, tolerances), config_stats(second, settings, tolerances)
    best = min(s["shm_us"] for key, s in stats.items() if not key[1])
    body = []
    for solver in sorted({key[0] for key in stats}, key=lambda solver: stats[solver, False]["shm_us"]):
        cold, warm = stats[solver, False], stats.get((solver, True))
        qpb = first[solver, False]
        body.append([solver, f"{fmt(cold['shm_us'])} ({cold['shm_us'] / best:.2f})", fmt(cold["median_us"]),
                     fmt(qpb["shm_us"]), f"{qpb['shm_us'] / cold['shm_us']:.2f}",
                     fmt(warm["shm_us"]) if warm else "-", f"{warm['shm_us'] / cold['shm_us']:.2f}" if warm else "-",
                     fmt(cold["solve_shm_us"]) + (f" / {fmt(warm['solve_shm_us'])}" if warm else ""),
                     f"{cold['success']:.1f}" + (f" / {warm['success']:.1f}" if warm else "")])
    return markdown_table(["solver", "cold shm µs (ratio)", "cold median µs", "qpbenchmark's pass shm µs",
                           "qpbenchmark's / back to back", "warm shm µs", "warm / cold",
                           "solve-only shm µs cold / warm", "success % cold / warm"], body)


# ------------------------------------------------------------------------ report
def write_report(rows: list[dict], second: list[dict], test_set: WbcQpbenchmark, args: argparse.Namespace,
                 out: Path, elapsed: float, loads: tuple[float, float], where: str) -> Path:
    """``out/report.md``: both passes, per settings, scenario and active / inactive; its path."""
    tolerances = test_set.tolerances
    index = test_set.index
    solvers = sorted({r["solver"] for r in rows})
    versions = package_versions(["qpbenchmark", "qpsolvers"] + [_DIST.get(s, s) for s in solvers])
    composition = ", ".join(
        f"{c['scenario']} {c['selected']}/{c['recorded']} ticks (n={c['n']}, {c['n_ineq']} ineq, {c['n_eq']} eq "
        f"rows; {c['active']} with an active constraint)" for c in test_set.composition())
    lines = [
        "# Solver comparison on recorded control QPs", "",
        f"Measured {machine_note()}; load average {loads[0]:.2f} at the start, {loads[1]:.2f} at the end. "
        f"Command: `{args.command_line}` ({elapsed:.0f} s); run {where}." + (
            "" if args.workers is None and args.scheduler is None else
            " The work units ran side by side, sharing the machines' cores: the runtimes below are those of "
            "solves competing for the cores, for an accuracy / robustness sweep; timing tables come from a "
            "serial run."), "",
        f"Dataset v{index['version']} (`{index['generator']}`, commit {index['git_commit']}). Test set "
        f"`benchmarks/wbc_qpbenchmark.py`: {len(test_set.selection)} QPs: {composition}.", "",
        "Versions: " + ", ".join(f"{k} {v}" for k, v in versions.items()) + ".", "",
        "Solved by `qpbenchmark.run` (one timed cold solve per QP, solver and settings, settings in the order "
        "default, high, low, mid; the dense to sparse conversion of the sparse backends is not timed, qpsolvers' "
        "setup is), then by wbc's back-to-back pass (below). qpbenchmark's own report: "
        "`wbc_qpbenchmark.md`, its results: `results.csv`. Success (qpbenchmark's): found, primal and dual "
        "residual and duality gap below the settings' tolerance (default 1, high_accuracy 1e-9, mid_accuracy "
        "1e-6, low_accuracy 1e-3" + (", wbc 1e-9" if "wbc" in tolerances else "") + "). Runtime "
        "shm: shifted geometric mean, a solve that found nothing counted at the time limit (the control period, "
        f"{test_set.time_limit:g} s); qpbenchmark's shift is 10 s, which on µs runtimes is an arithmetic mean "
        "(shown as its ratio to the best solver, as qpbenchmark reports it, and in µs), the shift 10 µs "
        "keeps it a geometric mean. Residual shm ratios: qpbenchmark's (shift 10, residuals floored at "
        "the tolerance), 1.0 = best. Largest residuals and the distance to the reference solution: over "
        "found solutions. 'solve-only': qpsolvers' `solve_time` (without its build phase).", "",
        "## All scenarios", ""]
    for settings in tolerances:
        lines += [f"### settings: {settings}", "", settings_table(rows, settings, tolerances), ""]
    lines += ["### With / without an active bound or inequality at the reference", "",
              "Each cell: QPs with an active constraint / without."]
    for settings in tolerances:
        lines += ["", f"settings: {settings}", "", active_table(rows, settings, tolerances)]
    lines += [""]
    if second:
        lines += ["## Back to back (wbc's pass)", "",
                  "Every solver and settings on each QP in a random order, nothing run in between (in qpbenchmark's "
                  "pass the solves of a QP go solver by solver, settings in the order default, high, low, mid, with "
                  "pandas bookkeeping after each). Warm = `initvals` = the previous tick's reference solution, for "
                  "the backends whose qpsolvers wrapper uses it (" + ", ".join(
                      f"{s}: {WARM_START[s]}" for s in solvers if WARM_START.get(s)) + "; ignored by " + ", ".join(
                      s for s in solvers if not WARM_START.get(s)) + "). shm: shift 10 µs.", ""]
        for settings in tolerances:
            lines += [f"### back to back, settings: {settings}", "",
                      back_to_back_table(rows, second, settings, tolerances), ""]
    for sc in [sc for sc in test_set.scenarios if sc.start == 0]:  # a scenario's section holds all its starts
        sc_rows = [r for r in rows if r["scenario"] == sc.name]
        lines += [f"## {sc.name}", "", f"n = {sc.n}, {sc.n_ineq} inequality and {sc.n_eq} equality rows"
                  + (f"; its {test_set.starts} starts together." if test_set.starts > 1 else "."), ""]
        for settings in tolerances:
            lines += [f"### {sc.name}, settings: {settings}", "", settings_table(sc_rows, settings, tolerances), ""]
    lines += ["## Plots", "", "![runtime distributions](runtime_distributions.png)", "",
              "![performance profiles](performance_profiles.png)", ""]
    path = out / "report.md"
    path.write_text("\n".join(lines))
    return path


def plot(rows: list[dict], out: Path) -> None:
    """Runtime distributions and performance profiles (success within τ × the best) per settings."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    settings = list(dict.fromkeys(r["settings"] for r in rows))
    solvers = sorted({r["solver"] for r in rows})

    fig, axes = plt.subplots(len(settings), 1, figsize=(10, 3.2 * len(settings)), squeeze=False)
    for ax, setting in zip(axes[:, 0], settings, strict=True):
        data = [[r["runtime"] * 1e6 for r in rows if r["settings"] == setting and r["solver"] == solver]
                for solver in solvers]
        ax.boxplot(data, whis=(1, 99), showfliers=True, flierprops={"markersize": 2})
        ax.set_xticks(range(1, len(solvers) + 1), solvers, fontsize=8)
        ax.set_yscale("log")
        ax.set_ylabel("runtime [µs]")
        ax.set_title(f"settings: {setting} (box: quartiles, whiskers: 1–99 %)", fontsize=9)
        ax.grid(True, axis="y", which="both", alpha=0.3)
    fig.tight_layout()
    fig.savefig(out / "runtime_distributions.png", dpi=120)
    plt.close(fig)

    fig, axes = plt.subplots(1, len(settings), figsize=(5.2 * len(settings), 4.2), squeeze=False)
    for ax, setting in zip(axes[0], settings, strict=True):
        selected = [r for r in rows if r["settings"] == setting]
        problems = sorted({r["problem"] for r in selected})
        position = {p: i for i, p in enumerate(problems)}
        times = np.full((len(solvers), len(problems)), np.inf)
        for r in selected:
            if r["success"]:
                times[solvers.index(r["solver"]), position[r["problem"]]] = r["runtime"]
        best = np.min(times, axis=0)
        ratios = times / np.where(np.isfinite(best), best, np.nan)
        tau = np.logspace(0, 3, 300)
        for i, solver in enumerate(solvers):
            if np.any(times[i] < np.inf):
                ax.plot(tau, [(np.nan_to_num(ratios[i], nan=np.inf) <= t).mean() for t in tau], label=solver)
        ax.set_xscale("log")
        ax.set_ylim(0, 1.02)
        ax.set_xlabel("τ (runtime / best runtime on the problem)")
        ax.set_ylabel("fraction of problems solved within τ")
        ax.set_title(f"performance profile, settings: {setting}", fontsize=9)
        ax.grid(True, which="both", alpha=0.3)
    axes[0, -1].legend(fontsize=7, loc="lower right")
    fig.tight_layout()
    fig.savefig(out / "performance_profiles.png", dpi=120)
    plt.close(fig)


def write_rows(rows: list[dict], path: Path) -> None:
    """One CSV row per solve."""
    with open(path, "w", newline="") as stream:
        writer = csv.DictWriter(stream, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)


def main(argv: list[str] | None = None) -> int:
    """``python -m benchmarks.solvers`` / ``wbc bench solvers``: 0 when the report is written."""
    parser = argparse.ArgumentParser(prog="python -m benchmarks.solvers", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--dataset", type=Path, default=OUTPUT / "dataset",
                        help="dataset folder (default: %(default)s)")
    parser.add_argument("--regenerate", action="store_true", help="record the dataset again first")
    parser.add_argument("--out", type=Path, default=OUTPUT / "solvers", help="report folder (default: %(default)s)")
    parser.add_argument("--ticks", type=int, default=TICKS,
                        help="ticks per scenario, half with an active constraint; 0 = all (default %(default)s)")
    parser.add_argument("--settings", nargs="+", default=list(SETTINGS), choices=list(SETTINGS) + ["wbc"],
                        help="qpbenchmark's settings; wbc = wbc.solvers.DEFAULT_SETTINGS (default: qpbenchmark's)")
    parser.add_argument("--solvers", nargs="+", help="default: every installed backend qpbenchmark knows")
    parser.add_argument("--scenarios", nargs="+", help="scenario names (default: all in the dataset)")
    parser.add_argument("--qpbenchmark-only", action="store_true", help="skip wbc's back-to-back pass")
    parser.add_argument("--time-limit", type=float, help="[s] (default: the control period of the scenarios)")
    parser.add_argument("--author", default="anonymous", help="GitHub user named in qpbenchmark's report")
    parser.add_argument("--seed", type=int, default=0, help="order of the back-to-back pass")
    parser.add_argument("--starts", type=int, default=1, metavar="N",
                        help="per scenario the recording from its initial configuration and from N - 1 seeded "
                             "perturbations of it (benchmarks/starts.py; default %(default)s: unperturbed only)")
    parser.add_argument("--start-seed", type=int, default=0, help="seed of the perturbed starts (default %(default)s)")
    where = parser.add_mutually_exclusive_group()
    where.add_argument("--workers", type=int, metavar="N",
                       help="run the work units on a local Dask cluster of N worker processes of 1 thread "
                            f"(needs {sweep.INSTALL}); results as in the serial run, timings not (they share cores)")
    where.add_argument("--scheduler", metavar="ADDRESS",
                       help="run the work units on an existing Dask cluster, e.g. tcp://host:8786 (same versions "
                            "of wbc, numpy, qpsolvers, qpbenchmark and the backends on every worker, checked first)")
    parser.add_argument("--connect-timeout", type=float, default=10.0, metavar="S",
                        help="[s] to reach the scheduler and find a worker (default %(default)s)")
    parser.add_argument("--no-progress", action="store_true")
    args = parser.parse_args(argv)
    args.command_line = "python -m benchmarks.solvers " + " ".join(argv if argv is not None else sys.argv[1:])
    if args.starts < 1:
        parser.error(f"--starts {args.starts}: give 1 (the scenarios' own initial configuration) or more")
    try:
        args.workers = sweep.checked_options(args.workers, args.scheduler, args.connect_timeout)
    except sweep.SweepError as exc:
        parser.error(str(exc))

    if args.regenerate:
        print(f"recording the dataset into {args.dataset} ...", file=sys.stderr)
        ds.record_all(args.dataset, show_progress=not args.no_progress)
    backends = [_DIST.get(solver, solver) for solver in sorted(qpsolvers.available_solvers)]
    try:
        with sweep.executor(args.workers, args.scheduler, args.connect_timeout, backends,
                            not args.no_progress) as run:
            try:
                test_set = WbcQpbenchmark(args.dataset, args.ticks, args.scenarios, args.settings, args.solvers,
                                          args.time_limit, args.starts, args.start_seed, run, not args.no_progress)
            except ValueError as exc:
                parser.error(str(exc))
            for sc in test_set.scenarios:
                if sc.meta["status"] != "ok":
                    print(f"warning: dataset scenario {sc.label}: {sc.meta['status']}", file=sys.stderr)
            args.out.mkdir(parents=True, exist_ok=True)
            start, load_start = time.perf_counter(), os.getloadavg()[0]
            df, rows, second = run_units(make_units(test_set, args.seed, not args.qpbenchmark_only), run)
            elapsed = time.perf_counter() - start
    except sweep.SweepError as exc:
        parser.exit(1, f"{parser.prog}: error: {exc}\n")
    complete = qpbenchmark.Results(None, test_set)
    complete.df = df
    complete.write(str(args.out / "results.csv"))
    with _quiet_logging():
        qpbenchmark.Report(args.author, qpbenchmark.Results(str(args.out / "results.csv"), test_set)).write(
            str(args.out / "wbc_qpbenchmark.md"))
    write_rows(rows + second, args.out / "solves.csv")
    report = write_report(rows, second, test_set, args, args.out, elapsed, (load_start, os.getloadavg()[0]),
                          run.description)
    plot(rows, args.out)
    for settings in test_set.tolerances:
        print(f"settings: {settings}\n{settings_table(rows, settings, test_set.tolerances)}\n")
    print(f"report written to {report}; qpbenchmark's: {args.out / 'wbc_qpbenchmark.md'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
