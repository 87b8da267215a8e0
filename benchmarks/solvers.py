"""QP solver comparison on the QPs of real control ticks (qpbenchmark methodology).

    python -m benchmarks.solvers [--ticks 400] [--repeats 3] [--settings default high low]
                                 [--solvers daqp osqp ...] [--out benchmarks/output/solvers]

Every installed qpsolvers backend solves the recorded QPs of :mod:`benchmarks.dataset`
(generated first if missing) through ``qpsolvers.solve_problem``, at three accuracy
settings, cold started and — for the backends that use qpsolvers' ``initvals`` — warm
started from the previous tick's reference solution (what a controller holds as its
last command).

Methodology (after qpbenchmark, https://github.com/qpsolvers/qpbenchmark):

* settings ``default`` (the solver's own defaults), ``high`` (absolute tolerances 1e-9,
  relative 0) and ``low`` (1e-3); ``wbc`` (``wbc.solvers.DEFAULT_SETTINGS``) on request;
* success = solution found **and** primal residual, dual residual and duality gap below
  the tolerance of the settings (default 1, high 1e-9, low 1e-3) **and** runtime within
  the time limit (default: the scenario's control period dt — a control QP slower than
  one tick is useless);
* runtime = wall time of ``qpsolvers.solve_problem`` (matrix conversion included, as
  a caller pays it), the minimum of ``--repeats`` back-to-back solves; aggregated as
  the shifted geometric mean with shift 10 **in microseconds** (qpbenchmark applies
  shift 10 to seconds for problems of milliseconds to minutes; on µs-scale control QPs a
  10 s shift would turn the mean into an arithmetic one), failures counted at the
  time limit; also reported as the ratio to the best configuration;
* residuals as qpsolvers defines them (absolute, infinity norm), plus the distance
  ``|x - x_ref|_inf`` to the dataset's high-accuracy reference solution, reported as
  median and maximum over the found solutions;
* all configurations solve the same problem back to back in a random order per
  problem (interleaved: machine noise hits all alike).

Ticks are subsampled evenly per scenario (``--ticks``, default 400; ``--ticks 0`` = all)
to keep the run to a few minutes on a laptop. Output: ``report.md``, ``results.csv``,
``runtime_distributions.png``, ``performance_profiles.png`` in ``--out``.
"""

from __future__ import annotations

import argparse
import csv
import sys
import time
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import qpsolvers

from . import dataset as ds
from .common import OUTPUT, fmt, machine_note, markdown_table, package_versions, progress, shifted_geometric_mean

#: solvers the issue asks for (others found installed are added)
SOLVERS = ("daqp", "proxqp", "osqp", "quadprog", "clarabel", "piqp", "highs")
TOLERANCES = {"default": 1.0, "high": 1e-9, "low": 1e-3, "wbc": 1e-9}
SHIFT_US = 10.0

#: does the qpsolvers wrapper (4.x) pass ``initvals`` on to the backend? (read from its source)
WARM_START = {
    "daqp": "primal_start", "osqp": "warm_start(x)", "proxqp": "x (WARM_START)", "scs": "warm start x",
    "cvxopt": "initvals", "qpoases": None,
    "quadprog": None, "clarabel": None, "piqp": None, "highs": None, "ecos": None,
}


def accuracy_settings(solver: str, eps: float) -> dict:
    """Options asking ``solver`` for absolute primal/dual/gap accuracy ``eps`` (relative 0)."""
    table = {
        "daqp": {"primal_tol": eps, "dual_tol": eps},
        "osqp": {"eps_abs": eps, "eps_rel": 0.0},
        "proxqp": {"eps_abs": eps, "eps_rel": 0.0, "eps_duality_gap_abs": eps, "eps_duality_gap_rel": 0.0},
        "clarabel": {"tol_feas": eps, "tol_gap_abs": eps, "tol_gap_rel": 0.0},
        "piqp": {"eps_abs": eps, "eps_rel": 0.0, "check_duality_gap": True, "eps_duality_gap_abs": eps,
                 "eps_duality_gap_rel": 0.0},
        "highs": {"primal_feasibility_tolerance": eps, "dual_feasibility_tolerance": eps},
        "scs": {"eps_abs": eps, "eps_rel": 0.0},
        "ecos": {"feastol": eps, "abstol": eps, "reltol": 0.0},
        "cvxopt": {"feastol": eps},
        "quadprog": {},  # no tolerance parameter: a dual active-set method run to completion
    }
    return dict(table.get(solver, {}))


def solver_options(solver: str, settings: str) -> dict:
    if settings == "default":
        return {}
    if settings == "wbc":
        from wbc.solvers import DEFAULT_SETTINGS

        return dict(DEFAULT_SETTINGS.get(solver, {}))
    return accuracy_settings(solver, TOLERANCES[settings])


@dataclass(frozen=True)
class Config:
    solver: str
    settings: str
    warm: bool

    @property
    def label(self) -> str:
        return f"{self.solver} ({'warm' if self.warm else 'cold'})"


def make_configs(solvers: list[str], settings: list[str], warm: bool = True) -> list[Config]:
    configs = []
    for setting in settings:
        for solver in solvers:
            configs.append(Config(solver, setting, False))
            if warm and WARM_START.get(solver):
                configs.append(Config(solver, setting, True))
    return configs


def run_one(problem: qpsolvers.Problem, config: Config, options: dict, initvals, repeats: int) -> tuple:
    """Solve ``repeats`` times; return (min wall time, backend time of that run, solution)."""
    best, solution, backend = np.inf, None, np.nan
    for _ in range(repeats):
        start = time.perf_counter()
        try:
            result = qpsolvers.solve_problem(problem, solver=config.solver, initvals=initvals, **options)
        except Exception:  # noqa: BLE001 - a raising backend is a failure, never a crash of the benchmark
            result = None
        elapsed = time.perf_counter() - start
        if elapsed < best:
            best, solution = elapsed, result
            backend = getattr(result, "solve_time", None) if result is not None else None
            backend = np.nan if backend is None else backend
    return best, backend, solution


def benchmark(scenarios: list[ds.ScenarioQPs], configs: list[Config], ticks: int, repeats: int,
              time_limit: float | None, seed: int = 0, show_progress: bool = True) -> list[dict]:
    """Solve every sampled tick with every configuration; one result row per (tick, config)."""
    rng = np.random.default_rng(seed)
    jobs = []
    for sc in scenarios:
        sample = np.arange(sc.ticks) if ticks <= 0 or ticks >= sc.ticks else \
            np.unique(np.linspace(0, sc.ticks - 1, ticks).round().astype(int))
        jobs += [(sc, int(k)) for k in sample]
    options = {(c.solver, c.settings): solver_options(c.solver, c.settings) for c in configs}
    rows = []
    iterator = progress(jobs, desc="solvers", unit="QP") if show_progress else jobs
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for sc, k in iterator:
            problem = sc.problem(k)
            x_ref = sc.x_ref[k]
            f_ref = sc.objective(k, x_ref)
            previous = sc.x_ref[k - 1] if k > 0 else np.zeros(sc.n)
            limit = time_limit if time_limit is not None else sc.meta.get("dt", 0.01)
            n_active = int(sc.active[k, :sc.n + sc.n_ineq].sum())
            for i in rng.permutation(len(configs)):
                config = configs[i]
                runtime, backend, solution = run_one(problem, config, options[config.solver, config.settings],
                                                     previous.copy() if config.warm else None, repeats)
                found = bool(solution is not None and solution.found and solution.x is not None
                             and np.all(np.isfinite(solution.x)))
                if found:
                    primal, dual, gap = ds.kkt_residuals(problem, solution)
                    ref_error = float(np.max(np.abs(solution.x - x_ref)))
                    cost_error = abs(sc.objective(k, solution.x) - f_ref)
                else:
                    primal = dual = gap = ref_error = cost_error = np.inf
                tol = TOLERANCES[config.settings]
                success = found and primal < tol and dual < tol and gap < tol and runtime <= limit
                rows.append({
                    "scenario": sc.name, "tick": k, "n": sc.n, "n_ineq": sc.n_ineq, "n_eq": sc.n_eq,
                    "n_active": n_active, "solver": config.solver, "settings": config.settings,
                    "warm": config.warm, "found": found, "success": success, "runtime": runtime,
                    "backend_time": backend, "time_limit": limit, "primal_residual": primal,
                    "dual_residual": dual, "duality_gap": gap, "ref_error": ref_error, "cost_error": cost_error,
                })
    return rows


# ------------------------------------------------------------------------ report
def summarize(rows: list[dict]) -> dict:
    """Aggregate metrics of one configuration over ``rows``."""
    found = [r for r in rows if r["found"]]
    runtime = [r["runtime"] * 1e6 if r["success"] else r["time_limit"] * 1e6 for r in rows]
    backend = [r["backend_time"] * 1e6 for r in rows if r["success"] and np.isfinite(r["backend_time"])]

    def stat(key, fn):
        values = [r[key] for r in found]
        return float(fn(values)) if values else float("nan")

    return {
        "n": len(rows), "success": 100.0 * np.mean([r["success"] for r in rows]),
        "found": 100.0 * np.mean([r["found"] for r in rows]),
        "sgm_us": shifted_geometric_mean(runtime, SHIFT_US),
        "median_us": float(np.median([r["runtime"] for r in rows]) * 1e6),
        "p99_us": float(np.percentile([r["runtime"] for r in rows], 99) * 1e6),
        "backend_sgm_us": shifted_geometric_mean(backend, SHIFT_US) if backend else float("nan"),
        "primal_median": stat("primal_residual", np.median), "primal_max": stat("primal_residual", np.max),
        "dual_median": stat("dual_residual", np.median), "dual_max": stat("dual_residual", np.max),
        "gap_median": stat("duality_gap", np.median), "gap_max": stat("duality_gap", np.max),
        "ref_median": stat("ref_error", np.median), "ref_max": stat("ref_error", np.max),
    }


def _config_key(row: dict) -> tuple:
    return row["solver"], row["warm"]


def settings_table(rows: list[dict], settings: str) -> str:
    selected = [r for r in rows if r["settings"] == settings]
    keys = sorted({_config_key(r) for r in selected})
    stats = {key: summarize([r for r in selected if _config_key(r) == key]) for key in keys}
    best = min(s["sgm_us"] for s in stats.values())
    order = sorted(keys, key=lambda key: stats[key]["sgm_us"])
    body = []
    for key in order:
        s = stats[key]
        body.append([f"{key[0]} ({'warm' if key[1] else 'cold'})", f"{s['success']:.1f}", fmt(s["sgm_us"]),
                     f"{s['sgm_us'] / best:.2f}", fmt(s["median_us"]), fmt(s["p99_us"]), fmt(s["backend_sgm_us"]),
                     f"{s['primal_median']:.1e} / {s['primal_max']:.1e}",
                     f"{s['dual_median']:.1e} / {s['dual_max']:.1e}", f"{s['gap_median']:.1e} / {s['gap_max']:.1e}",
                     f"{s['ref_median']:.1e} / {s['ref_max']:.1e}"])
    return markdown_table(
        ["solver", "success %", "runtime sgm µs", "ratio", "median µs", "p99 µs", "solve-only sgm µs",
         "primal res. med / max", "dual res. med / max", "gap med / max", "‖x − x_ref‖∞ med / max"], body)


def warm_table(rows: list[dict], settings: list[str]) -> str:
    body = []
    for setting in settings:
        for solver in sorted({r["solver"] for r in rows if r["warm"]}):
            cold = summarize([r for r in rows if r["settings"] == setting and r["solver"] == solver and not r["warm"]])
            warm = summarize([r for r in rows if r["settings"] == setting and r["solver"] == solver and r["warm"]])
            body.append([setting, solver, fmt(cold["sgm_us"]), fmt(warm["sgm_us"]),
                         f"{warm['sgm_us'] / cold['sgm_us']:.2f}",
                         fmt(cold["backend_sgm_us"]), fmt(warm["backend_sgm_us"]),
                         f"{warm['backend_sgm_us'] / cold['backend_sgm_us']:.2f}",
                         f"{cold['success']:.1f} / {warm['success']:.1f}"])
    return markdown_table(["settings", "solver", "cold sgm µs", "warm sgm µs", "warm / cold", "cold solve-only",
                           "warm solve-only", "warm / cold (solve-only)", "success % cold / warm"], body)


def write_report(rows: list[dict], scenarios: list[ds.ScenarioQPs], index: dict, args, out: Path,
                 elapsed: float) -> Path:
    settings = list(dict.fromkeys(r["settings"] for r in rows))
    solvers = sorted({r["solver"] for r in rows})
    versions = package_versions(["qpsolvers"] + [_DIST.get(s, s) for s in solvers])
    lines = [
        "# Solver comparison on recorded control QPs", "",
        f"Measured {machine_note()}. Command: `{args.command_line}` ({elapsed:.0f} s).", "",
        f"Dataset v{index['version']} (`{index['generator']}`, commit {index['git_commit']}); "
        f"{len({(r['scenario'], r['tick']) for r in rows})} QPs: "
        + ", ".join(f"{sc.name} {len({r['tick'] for r in rows if r['scenario'] == sc.name})}/{sc.ticks} ticks "
                    f"(n={sc.n}, {sc.n_ineq} ineq, {sc.n_eq} eq rows)" for sc in scenarios) + ".", "",
        "Versions: " + ", ".join(f"{k} {v}" for k, v in versions.items()) + ".", "",
        "Success = found, primal/dual residual and duality gap below the tolerance of the settings "
        "(default 1, high 1e-9, low 1e-3), within the time limit (the control period). Runtime: wall time of "
        f"`qpsolvers.solve_problem` (min of {args.repeats}), shifted geometric mean (shift {SHIFT_US:g} µs, "
        "failures counted at the time limit); ratio = to the best configuration of the table. 'solve-only' is "
        "`Solution.solve_time` as qpsolvers reports it: the wall time minus qpsolvers' build phase (matrix "
        "conversion — dense to CSC for the sparse backends — and the backend's setup/factorization, which "
        "qpsolvers redoes on every call). Residuals and the distance "
        "to the reference are over found solutions. Warm = `initvals` = the previous tick's reference "
        "solution; only backends whose qpsolvers wrapper uses `initvals` are run warm ("
        + ", ".join(f"{s}: {WARM_START[s]}" for s in solvers if WARM_START.get(s)) + "; ignored by "
        + ", ".join(s for s in solvers if not WARM_START.get(s)) + ").", "",
    ]
    lines += ["## All scenarios", ""]
    for setting in settings:
        lines += [f"### settings: {setting}", "", settings_table(rows, setting), ""]
    if any(r["warm"] for r in rows):
        lines += ["### Warm start vs cold start", "", warm_table(rows, settings), ""]
    for sc in scenarios:
        sc_rows = [r for r in rows if r["scenario"] == sc.name]
        if not sc_rows:
            continue
        active = np.mean([r["n_active"] > 0 for r in sc_rows if r["solver"] == sc_rows[0]["solver"]
                          and r["settings"] == sc_rows[0]["settings"] and r["warm"] == sc_rows[0]["warm"]])
        lines += [f"## {sc.name}", "", f"n = {sc.n}, {sc.n_ineq} inequality and {sc.n_eq} equality rows; "
                  f"{100 * active:.0f} % of the sampled ticks have an active bound or inequality at the reference.", ""]
        for setting in settings:
            lines += [f"### {sc.name}, settings: {setting}", "", settings_table(sc_rows, setting), ""]
    lines += ["## Plots", "", "![runtime distributions](runtime_distributions.png)", "",
              "![performance profiles](performance_profiles.png)", ""]
    path = out / "report.md"
    path.write_text("\n".join(lines))
    return path


_DIST = {"proxqp": "proxsuite", "highs": "highspy"}


def plot(rows: list[dict], out: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    settings = list(dict.fromkeys(r["settings"] for r in rows))
    keys = sorted({_config_key(r) for r in rows})
    labels = [f"{s} ({'warm' if w else 'cold'})" for s, w in keys]

    fig, axes = plt.subplots(len(settings), 1, figsize=(10, 3.2 * len(settings)), squeeze=False)
    for ax, setting in zip(axes[:, 0], settings, strict=True):
        data = [[r["runtime"] * 1e6 for r in rows if r["settings"] == setting and _config_key(r) == key]
                for key in keys]
        ax.boxplot(data, whis=(1, 99), showfliers=True, flierprops={"markersize": 2})
        ax.set_xticks(range(1, len(keys) + 1), labels, rotation=30, ha="right", fontsize=8)
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
        problems = sorted({(r["scenario"], r["tick"]) for r in selected})
        position = {p: i for i, p in enumerate(problems)}
        times = np.full((len(keys), len(problems)), np.inf)
        for r in selected:
            if r["success"]:
                times[keys.index(_config_key(r)), position[r["scenario"], r["tick"]]] = r["runtime"]
        best = np.min(times, axis=0)
        ratios = times / np.where(np.isfinite(best), best, np.nan)
        tau = np.logspace(0, 3, 300)
        for i, key in enumerate(keys):
            if not np.any(times[i] < np.inf):
                continue
            fraction = [(np.nan_to_num(ratios[i], nan=np.inf) <= t).mean() for t in tau]
            ax.plot(tau, fraction, label=labels[i], linestyle="--" if key[1] else "-")
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


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.solvers", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--dataset", type=Path, default=OUTPUT / "dataset",
                        help="dataset folder (default: %(default)s)")
    parser.add_argument("--regenerate", action="store_true", help="record the dataset again first")
    parser.add_argument("--out", type=Path, default=OUTPUT / "solvers", help="report folder (default: %(default)s)")
    parser.add_argument("--ticks", type=int, default=400,
                        help="ticks per scenario, evenly spaced; 0 = all (default 400)")
    parser.add_argument("--repeats", type=int, default=3, help="solves per (QP, config); the minimum is kept")
    parser.add_argument("--settings", nargs="+", default=["default", "high", "low"], choices=list(TOLERANCES))
    parser.add_argument("--solvers", nargs="+", help="default: every installed qpsolvers backend")
    parser.add_argument("--scenarios", nargs="+", help="scenario names (default: all in the dataset)")
    parser.add_argument("--no-warm", action="store_true", help="cold starts only")
    parser.add_argument("--time-limit", type=float, help="[s] (default: each scenario's control period dt)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--no-progress", action="store_true")
    args = parser.parse_args(argv)
    args.command_line = "python -m benchmarks.solvers " + " ".join(argv if argv is not None else sys.argv[1:])

    folder = args.dataset / f"v{ds.VERSION}"
    if args.regenerate or not (folder / "index.json").exists():
        print(f"recording the dataset into {folder} ...", file=sys.stderr)
        ds.record_all(args.dataset, show_progress=not args.no_progress)
    index, scenarios = ds.load(args.dataset)
    failed = [e for e in index["scenarios"] if e["status"] != "ok"]
    for entry in failed:
        print(f"warning: dataset scenario {entry['scenario']}: {entry['status']}", file=sys.stderr)
    if args.scenarios:
        scenarios = [sc for sc in scenarios if sc.name in args.scenarios]
    installed = list(qpsolvers.available_solvers)
    solvers = args.solvers or [s for s in SOLVERS if s in installed] + sorted(set(installed) - set(SOLVERS))
    missing = [s for s in solvers if s not in installed]
    if missing:
        parser.error(f"not installed: {', '.join(missing)}")
    configs = make_configs(solvers, args.settings, warm=not args.no_warm)
    args.out.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    rows = benchmark(scenarios, configs, args.ticks, args.repeats, args.time_limit, args.seed, not args.no_progress)
    elapsed = time.perf_counter() - start
    with open(args.out / "results.csv", "w", newline="") as stream:
        writer = csv.DictWriter(stream, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    report = write_report(rows, scenarios, index, args, args.out, elapsed)
    plot(rows, args.out)
    for setting in args.settings:
        print(f"settings: {setting}\n{settings_table(rows, setting)}\n")
    print(f"report written to {report}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
