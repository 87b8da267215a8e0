"""QP dataset recorded from real control ticks.

    python -m benchmarks.dataset [--out benchmarks/output/dataset] [--tasks tasks/] [--duration S]

Runs every scenario ``tasks/*.toml`` in closed loop with its own solver and records the
QP the solver saw at every tick (``Controller.qp``: the input-space QP for ``reduced``
scenarios). Every scenario file is picked up; one that fails to load or run is listed
in the index with its error and makes the command exit with status 1 — never skipped
silently.

Layout (format version :data:`VERSION`) in ``<out>/v<VERSION>/``::

    index.json       dataset metadata + one entry per scenario (robot, sizes, ticks, status)
    index.csv        one row per tick: scenario, tick, robot, n vars/rows, active constraints, ...
    <scenario>.npz   per scenario, stacked over ticks T:
                     H (T,n,n), c (T,n), C (T,m,n) = [G; A], upper/lower (T,n+m) = [ub; h; b] /
                     [lb; -inf; b], n_ineq, n_eq, x_ref (T,n) high-accuracy reference solution,
                     x_controller (T,n) what the controller's solver returned, active (T,n+m) bool
                     (bounds, then rows, active at x_ref), ref_residuals (T,3) primal/dual/gap of
                     x_ref, q (T,nq), time (T,)

The QP is ``min 1/2 x'Hx + c'x  s.t.  G x <= h, A x = b, lb <= x <= ub`` (``wbc.qp.problem.QP``).
:func:`load` reads it back; :meth:`ScenarioQPs.problem` gives a ``qpsolvers.Problem``.
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
import traceback
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import qpsolvers

from .common import OUTPUT, TASKS, git_commit, machine_note, package_versions, progress, scenario_files

VERSION = 1
#: tolerance [QP units] under which an inequality or bound counts as active at x_ref
ACTIVE_TOL = 1e-9
#: reference solution: DAQP (active set, exact on its working set) with tight tolerances,
#: then ProxQP / Clarabel at high accuracy if DAQP's KKT residuals are not below REF_TOL
REF_TOL = 1e-9
_REFERENCE_SOLVERS = (
    ("daqp", {"primal_tol": 1e-12, "dual_tol": 1e-12}),
    ("proxqp", {"eps_abs": 1e-12, "eps_rel": 0.0}),
    ("clarabel", {"tol_gap_abs": 1e-12, "tol_gap_rel": 0.0, "tol_feas": 1e-12}),
)


# --------------------------------------------------------------------------- data
def make_problem(H: np.ndarray, c: np.ndarray, C: np.ndarray, upper: np.ndarray, lower: np.ndarray,
                 n_ineq: int, n_eq: int) -> qpsolvers.Problem:
    """A ``qpsolvers.Problem`` from wbc's QP layout (``C = [G; A]``, ``upper = [ub; h; b]``,
    ``lower = [lb; l; b]``): bounds apart, inequalities ``G x <= h`` -- and ``-G_i x <= -l_i`` for
    each inequality row with a finite lower side ``l_i`` (the band rows of strict priorities under
    DAQP, rows with two sides), after them -- and equalities ``A x = b``.

    Raises ValueError when ``lower``/``upper`` are not of that layout (shapes, an equality row
    whose two bounds differ): those would be dropped silently.
    """
    n, p, e = H.shape[0], n_ineq, n_eq
    if C.shape != (p + e, n) or upper.shape != (n + p + e,) or lower.shape != (n + p + e,):
        raise ValueError(f"QP of {n} variables, {p} + {e} rows: C {C.shape}, upper {upper.shape}, lower {lower.shape}")
    if not np.array_equal(lower[n + p:], upper[n + p:]):
        raise ValueError("an equality row has lower != upper (wbc's layout: lower = upper = b on A x = b)")
    lb, ub = lower[:n], upper[:n]
    has_bounds = bool(np.any(np.isfinite(lb)) or np.any(np.isfinite(ub)))
    sided = np.flatnonzero(np.isfinite(lower[n:n + p]))  # inequality rows with a lower side too
    G = np.vstack([C[:p], -C[sided]]) if sided.size else C[:p]
    h = np.concatenate([upper[n:n + p], -lower[n + sided]]) if sided.size else upper[n:n + p]
    return qpsolvers.Problem(
        H, c,
        G if p else None, h if p else None,
        C[p:p + e] if e else None, upper[n + p:n + p + e] if e else None,
        lb if has_bounds else None, ub if has_bounds else None,
    )


@dataclass
class ScenarioQPs:
    """The recorded QPs of one scenario (arrays stacked over ticks)."""

    name: str
    H: np.ndarray
    c: np.ndarray
    C: np.ndarray
    upper: np.ndarray
    lower: np.ndarray
    n_ineq: int
    n_eq: int
    x_ref: np.ndarray
    x_controller: np.ndarray
    active: np.ndarray
    ref_residuals: np.ndarray
    q: np.ndarray
    time: np.ndarray
    meta: dict = field(default_factory=dict)
    #: 0: recorded from the scenario's initial configuration; s >= 1: from its perturbed start s
    #: (:mod:`benchmarks.starts`)
    start: int = 0

    @property
    def label(self) -> str:
        """``<scenario>`` for the nominal start, ``<scenario>_s<start>`` for a perturbed one."""
        return self.name if self.start == 0 else f"{self.name}_s{self.start}"

    @property
    def ticks(self) -> int:
        return self.H.shape[0]

    @property
    def n(self) -> int:
        return self.H.shape[1]

    def problem(self, k: int) -> qpsolvers.Problem:
        """Tick ``k`` as a dense ``qpsolvers.Problem`` (None for absent parts)."""
        return make_problem(self.H[k], self.c[k], self.C[k], self.upper[k], self.lower[k], self.n_ineq, self.n_eq)

    def objective(self, k: int, x: np.ndarray) -> float:
        return float(0.5 * x @ self.H[k] @ x + self.c[k] @ x)


def version_folder(folder: Path | str) -> Path:
    """The folder holding ``index.json``: ``folder`` itself or ``folder/v<VERSION>``."""
    folder = Path(folder)
    return folder if (folder / "index.json").exists() else folder / f"v{VERSION}"


def load(folder: Path | str = OUTPUT / "dataset") -> tuple[dict, list[ScenarioQPs]]:
    """Read a dataset written by :func:`record_all` (``folder`` or ``folder/v<VERSION>``)."""
    folder = version_folder(folder)
    index = json.loads((folder / "index.json").read_text())
    if index.get("version") != VERSION:
        raise RuntimeError(f"{folder}: dataset version {index.get('version')}, this code reads {VERSION}; "
                           "regenerate with python -m benchmarks.dataset")
    out = []
    for entry in index["scenarios"]:
        if entry["status"] != "ok":
            continue
        with np.load(folder / entry["file"]) as data:
            arrays = {key: data[key] for key in data.files}
        out.append(scenario_qps(entry, arrays))
    return index, out


def scenario_qps(entry: dict, arrays: dict[str, np.ndarray], start: int = 0) -> ScenarioQPs:
    """A :class:`ScenarioQPs` from its index entry and the arrays of its ``.npz`` file."""
    return ScenarioQPs(
        name=entry["scenario"], H=arrays["H"], c=arrays["c"], C=arrays["C"], upper=arrays["upper"],
        lower=arrays["lower"], n_ineq=int(arrays["n_ineq"]), n_eq=int(arrays["n_eq"]),
        x_ref=arrays["x_ref"], x_controller=arrays["x_controller"], active=arrays["active"],
        ref_residuals=arrays["ref_residuals"], q=arrays["q"], time=arrays["time"], meta=entry, start=start)


# ---------------------------------------------------------------------- reference
def kkt_residuals(problem: qpsolvers.Problem, solution: qpsolvers.Solution) -> tuple[float, float, float]:
    """(primal residual, dual residual, duality gap) as qpsolvers/qpbenchmark define them."""
    return solution.primal_residual(), solution.dual_residual(), solution.duality_gap()


def reference_solution(problem: qpsolvers.Problem) -> tuple[np.ndarray, tuple[float, float, float], str]:
    """High-accuracy solution: the first reference solver whose residuals are all below REF_TOL
    (else the one with the smallest worst residual). Returns (x, residuals, solver name)."""
    best = None
    for name, settings in _REFERENCE_SOLVERS:
        if name not in qpsolvers.available_solvers:
            continue
        solution = qpsolvers.solve_problem(problem, solver=name, **settings)
        if not solution.found or solution.x is None:
            continue
        residuals = kkt_residuals(problem, solution)
        if max(residuals) < REF_TOL:
            return solution.x.copy(), residuals, name
        if best is None or max(residuals) < max(best[1]):
            best = (solution.x.copy(), residuals, name)
    if best is None:
        raise RuntimeError("no reference solver found a solution")
    return best


def active_set(C: np.ndarray, upper: np.ndarray, lower: np.ndarray, x: np.ndarray,
               tol: float = ACTIVE_TOL) -> np.ndarray:
    """Boolean mask over ``[bounds; rows]``: bound or inequality tight at ``x`` (equalities: always)."""
    values = np.concatenate([x, C @ x])
    with np.errstate(invalid="ignore"):
        scale = 1.0 + np.abs(values)
        tight_upper = np.isfinite(upper) & (upper - values <= tol * scale)
        tight_lower = np.isfinite(lower) & (values - lower <= tol * scale)
    return tight_upper | tight_lower


# ---------------------------------------------------------------------- recording
def record_scenario(path: Path, duration: float | None = None, show_progress: bool = True,
                    q0: np.ndarray | None = None) -> dict:
    """Run one scenario in closed loop; return its arrays and per-tick metadata.

    ``q0``: start the loop there instead of the scenario's initial configuration (its tasks and
    reference, built from the initial configuration, are unchanged: a perturbed start).
    """
    from wbc.app.scenario import load_scenario
    from wbc.core.errors import SolverError

    scenario = load_scenario(path)
    controller = scenario.make_controller()
    robot, dt = scenario.robot, scenario.dt
    ticks = scenario.ticks if duration is None else int(round(duration / dt))
    qp = controller.qp
    n, p, e = qp.n, qp.n_ineq, qp.n_eq
    m = p + e
    arrays = {
        "H": np.zeros((ticks, n, n)), "c": np.zeros((ticks, n)), "C": np.zeros((ticks, m, n)),
        "upper": np.zeros((ticks, n + m)), "lower": np.zeros((ticks, n + m)),
        "x_ref": np.zeros((ticks, n)), "x_controller": np.zeros((ticks, n)),
        "active": np.zeros((ticks, n + m), dtype=bool), "ref_residuals": np.zeros((ticks, 3)),
        "q": np.zeros((ticks, robot.nq)), "time": np.arange(ticks) * dt,
    }
    rows: list[dict] = []
    q = (scenario.q0 if q0 is None else robot.check_configuration(q0)).copy()
    status = "ok"
    iterator = range(ticks)
    if show_progress:
        iterator = progress(iterator, desc=f"record {scenario.name}", unit="tick", leave=False)
    for k in iterator:
        if scenario.reference is not None:
            scenario.reference_task.set_target(*scenario.reference(k * dt))
        arrays["q"][k] = q
        try:
            v = controller.step(q)
            solver_status = controller.last.status
        except SolverError as exc:  # keep the QP that failed, then stop this scenario
            v, solver_status, status = None, f"failed: {exc}", f"controller failed at tick {k}"
        for name in ("H", "c", "C", "upper", "lower"):
            arrays[name][k] = getattr(qp, name)
        problem = make_problem(*(arrays[name][k] for name in ("H", "c", "C", "upper", "lower")), p, e)
        x_ref, residuals, ref_solver = reference_solution(problem)
        arrays["x_ref"][k], arrays["ref_residuals"][k] = x_ref, residuals
        if v is not None:
            arrays["x_controller"][k] = controller.last.u if controller.reduced else v
        active = active_set(qp.C, qp.upper, qp.lower, x_ref)
        arrays["active"][k] = active
        labels = controller.last.active_constraints if v is not None else []
        rows.append({
            "scenario": scenario.name, "tick": k, "time": round(k * dt, 9), "robot": robot.name,
            "n": n, "n_ineq": p, "n_eq": e,
            "n_active_bounds": int(active[:n].sum()), "n_active_ineq": int(active[n:n + p].sum()),
            "active_labels": "; ".join(labels), "controller_status": solver_status,
            "reference_solver": ref_solver, "ref_primal_residual": residuals[0],
            "ref_dual_residual": residuals[1], "ref_duality_gap": residuals[2],
            "controller_vs_ref": float(np.max(np.abs(arrays["x_controller"][k] - x_ref))) if v is not None
            else float("nan"),
        })
        if v is None:
            for name in arrays:
                arrays[name] = arrays[name][:k + 1]
            break
        q = robot.integrate(q, v, dt)
    entry = {
        "scenario": scenario.name, "source": str(path.name), "robot": robot.name, "base": robot.base.kind.value,
        "solver": controller.solver.name, "reduced": controller.reduced, "dt": dt,
        "ticks": len(rows), "n": n, "n_ineq": p, "n_eq": e,
        "tasks": [repr(t) for t in scenario.tasks], "constraints": [repr(c) for c in scenario.constraints],
        "status": status, "ticks_with_active_constraints": sum(
            1 for row in rows if row["n_active_bounds"] + row["n_active_ineq"] > 0),
        "max_ref_residual": float(arrays["ref_residuals"].max()) if rows else None,
        "max_controller_vs_ref": float(np.nanmax([row["controller_vs_ref"] for row in rows])) if rows else None,
    }
    arrays["n_ineq"], arrays["n_eq"] = np.array(p), np.array(e)
    return {"entry": entry, "arrays": arrays, "rows": rows}


def record_all(out: Path = OUTPUT / "dataset", tasks: Path = TASKS, duration: float | None = None,
               show_progress: bool = True, only: list[str] | None = None) -> tuple[Path, dict]:
    """Record every scenario of ``tasks`` into ``out/v<VERSION>``; returns (folder, index)."""
    folder = Path(out) / f"v{VERSION}"
    folder.mkdir(parents=True, exist_ok=True)
    files = scenario_files(tasks)
    if only:
        files = [f for f in files if f.stem in only]
    if not files:
        raise SystemExit(f"no scenario files in {tasks}")
    index = {
        "version": VERSION, "created": machine_note(), "git_commit": git_commit(),
        "generator": "python -m benchmarks.dataset" + (f" --duration {duration}" if duration else ""),
        "packages": package_versions(["wbc", "pin", "qpsolvers", "daqp", "proxsuite", "clarabel", "numpy"]),
        "active_tolerance": ACTIVE_TOL, "reference": [name for name, _ in _REFERENCE_SOLVERS],
        "qp_form": "min 1/2 x'Hx + c'x s.t. lower <= [I; C] x <= upper, C = [G; A] (equality rows: lower = upper)",
        "scenarios": [],
    }
    all_rows: list[dict] = []
    for path in files:
        try:
            result = record_scenario(path, duration, show_progress)
        except Exception as exc:  # noqa: BLE001 - every failure is reported, none is skipped silently
            print(f"dataset: {path.name} FAILED: {type(exc).__name__}: {exc}", file=sys.stderr)
            traceback.print_exc(file=sys.stderr)
            index["scenarios"].append({"scenario": path.stem, "source": path.name, "status":
                                       f"error: {type(exc).__name__}: {exc}"})
            continue
        entry = result["entry"]
        entry["file"] = f"{entry['scenario']}.npz"
        np.savez_compressed(folder / entry["file"], **result["arrays"])
        index["scenarios"].append(entry)
        all_rows += result["rows"]
        if entry["status"] != "ok":
            print(f"dataset: {path.name}: {entry['status']} (recorded up to there)", file=sys.stderr)
    (folder / "index.json").write_text(json.dumps(index, indent=2))
    if all_rows:
        with open(folder / "index.csv", "w", newline="") as stream:
            writer = csv.DictWriter(stream, fieldnames=list(all_rows[0]))
            writer.writeheader()
            writer.writerows(all_rows)
    return folder, index


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.dataset", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", type=Path, default=OUTPUT / "dataset", help="output folder (default: %(default)s)")
    parser.add_argument("--tasks", type=Path, default=TASKS, help="folder of scenario files (default: %(default)s)")
    parser.add_argument("--duration", type=float, help="override every scenario's duration [s]")
    parser.add_argument("--only", nargs="*", help="scenario names (file stems) to record")
    parser.add_argument("--no-progress", action="store_true")
    args = parser.parse_args(argv)
    folder, index = record_all(args.out, args.tasks, args.duration, not args.no_progress, args.only)
    failed = 0
    for entry in index["scenarios"]:
        if entry["status"] == "ok" or "ticks" in entry:
            print(f"{entry['scenario']:24s} {entry['ticks']:6d} ticks  n={entry['n']:3d} ineq={entry['n_ineq']:3d} "
                  f"eq={entry['n_eq']:2d}  ticks with active constraints {entry['ticks_with_active_constraints']:5d}"
                  f"  max ref residual {entry['max_ref_residual']:.1e}  controller vs ref "
                  f"{entry['max_controller_vs_ref']:.1e}  [{entry['status']}]")
        failed += entry["status"] != "ok"
        if "ticks" not in entry:
            print(f"{entry['scenario']:24s} {entry['status']}")
    print(f"dataset v{VERSION} written to {folder}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
