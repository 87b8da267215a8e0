"""wbc's control QPs as a qpbenchmark test set (https://github.com/qpsolvers/qpbenchmark).

    qpbenchmark benchmarks/wbc_qpbenchmark.py --results-path results.csv run   # qpbenchmark's own CLI
    python benchmarks/wbc_qpbenchmark.py run    # the same, results in benchmarks/output/qpbenchmark/
    wbc bench solvers                           # this test set through qpbenchmark, plus wbc's tables

The problems are the QPs wbc's controller solved at real ticks of every shipped scenario
(``tasks/*.toml``), recorded by :mod:`benchmarks.dataset` into ``benchmarks/output/dataset/``
(git-ignored; recorded on first use, ~30 s): ``TICKS`` ticks per scenario, half of them with an
active bound or inequality at the reference solution and half without where the scenario has
both. The runtime tolerance (qpbenchmark's time limit) is the control period: a control QP
solved slower than one tick is of no use to the controller.
"""

from __future__ import annotations

import copy
import os
import sys
from collections.abc import Iterator, Sequence
from pathlib import Path

import numpy as np
import qpbenchmark

if __package__ in (None, ""):  # loaded by path (qpbenchmark's CLI or `python benchmarks/wbc_qpbenchmark.py`)
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from benchmarks import dataset as ds  # noqa: E402
from benchmarks import starts as st  # noqa: E402
from benchmarks import sweep  # noqa: E402
from benchmarks.common import OUTPUT  # noqa: E402

#: ticks per scenario (0: every recorded tick)
TICKS = 200
#: qpbenchmark's solver settings; "wbc" (``wbc.solvers.DEFAULT_SETTINGS``, checked at 1e-9) on request
SETTINGS = ("default", "high_accuracy", "low_accuracy", "mid_accuracy")
WBC_TOLERANCE = 1e-9


def select_ticks(active: np.ndarray, count: int) -> np.ndarray:
    """``count`` tick indices, evenly spaced in time within two groups: ticks with an active
    constraint (``active[k]``) and ticks without, ``count // 2`` from each where both have
    enough, the other group filling what one lacks. All ticks when ``count`` is 0 or too large."""
    if count <= 0 or count >= active.size:
        return np.arange(active.size)
    with_active, without = np.flatnonzero(active), np.flatnonzero(~active)
    n_active = min(with_active.size, max(count // 2, count - without.size))

    def spaced(indices: np.ndarray, k: int) -> np.ndarray:
        return indices[np.linspace(0, indices.size - 1, k).round().astype(int)] if k else indices[:0]

    return np.sort(np.concatenate([spaced(with_active, n_active), spaced(without, count - n_active)]))


class WbcProblem(qpbenchmark.Problem):
    """A qpbenchmark problem that knows where it comes from and its reference solution."""

    scenario: str
    start: int  #: 0: the scenario's initial configuration; s >= 1: its perturbed start s (benchmarks.starts)
    tick: int
    active: bool  #: a bound or inequality is active at the reference solution
    x_ref: np.ndarray  #: reference solution (DAQP at 1e-12, checked by its KKT residuals)
    x_previous: np.ndarray  #: the previous tick's reference solution: a controller's warm start


class WbcQpbenchmark(qpbenchmark.TestSet):
    """The QPs of real control ticks of wbc's scenarios (whole-body velocity control)."""

    def __init__(self, dataset: Path | str | None = None, ticks: int = TICKS, scenarios: Sequence[str] | None = None,
                 settings: Sequence[str] = SETTINGS, solvers: Sequence[str] | None = None,
                 time_limit: float | None = None, starts: int = 1, start_seed: int = 0,
                 record: sweep.Mapper | None = None, show_progress: bool = True) -> None:
        """Load (or record) the dataset and select ``ticks`` per scenario and start (0: all).

        ``dataset``: default ``$WBC_QPBENCHMARK_DATASET``, else ``benchmarks/output/dataset``
        (qpbenchmark's CLI builds the test set without arguments). ``scenarios``, ``solvers``:
        subsets (default: every recorded scenario, every installed solver qpbenchmark knows).
        ``time_limit`` [s]: default the shortest control period of the scenarios. ``starts``: the
        nominal start and ``starts - 1`` perturbed ones per scenario (:mod:`benchmarks.starts`, seed
        ``start_seed``), recorded first where missing, through ``record`` (default: here, one by one).
        ``show_progress``: progress bars while a missing dataset is recorded.
        """
        folder = Path(dataset or os.environ.get("WBC_QPBENCHMARK_DATASET") or OUTPUT / "dataset")
        if not (folder / f"v{ds.VERSION}" / "index.json").exists() and not (folder / "index.json").exists():
            print(f"wbc_qpbenchmark: recording the dataset into {folder} ...", file=sys.stderr)
            ds.record_all(folder, show_progress=show_progress)
        self.index, recorded = ds.load(folder)
        if scenarios is not None:
            unknown = set(scenarios) - {sc.name for sc in recorded}
            if unknown:
                raise ValueError(f"not in the dataset: {', '.join(sorted(unknown))}")
            recorded = [sc for sc in recorded if sc.name in scenarios]
        if starts < 1:
            raise ValueError(f"starts = {starts}: give 1 (the scenarios' own initial configuration) or more")
        if starts > 1:
            version = ds.version_folder(folder)
            st.ensure_starts(version, self.index, recorded, starts, start_seed, record or sweep.Here(False))
            recorded = st.load_starts(version, recorded, starts)
        self.scenarios = recorded
        self.starts, self.start_seed = starts, start_seed
        self.selection: list[tuple[ds.ScenarioQPs, int]] = [
            (sc, int(k)) for sc in recorded for k in select_ticks(self.tick_has_active_constraint(sc), ticks)]
        self.problems: list[WbcProblem] = [problem for sc, k in self.selection for problem in self.tick_problems(sc, k)]
        self.time_limit = time_limit if time_limit is not None else min(sc.meta["dt"] for sc in recorded)
        self.requested_settings = tuple(settings)
        unknown = set(settings) - set(SETTINGS) - {"wbc"}
        if unknown:
            raise ValueError(f"unknown settings: {', '.join(sorted(unknown))}")
        super().__init__()
        if solvers is not None:
            missing = set(solvers) - self.solvers
            if missing:
                raise ValueError(f"not available to qpbenchmark here: {', '.join(sorted(missing))}")
            self.solvers = set(solvers)

    @property
    def title(self) -> str:
        return "wbc test set: whole-body velocity control QPs"

    def composition(self) -> list[dict]:
        """Per scenario and start: name (with the start), selected and recorded ticks, selected ticks with
        an active constraint, sizes."""
        return [{"scenario": sc.label, "selected": len(ticks), "recorded": sc.ticks,
                 "active": int(self.tick_has_active_constraint(sc)[ticks].sum()), "n": sc.n,
                 "n_ineq": sc.n_ineq, "n_eq": sc.n_eq}
                for sc in self.scenarios for ticks in [[k for s, k in self.selection if s is sc]]]

    @property
    def description(self) -> str:
        parts = self.composition()
        counts = ", ".join(f"{c['scenario']} {c['selected']} (n = {c['n']}, {c['n_ineq']} inequality and "
                           f"{c['n_eq']} equality rows)" for c in parts)
        active = sum(c["active"] for c in parts)
        return (
            "QPs solved by wbc's whole-body velocity controller at real ticks of its shipped scenarios "
            "(mobile manipulators, arms, a car-like base), recorded in closed loop by benchmarks/dataset.py "
            "of the wbc repository. Each QP is min 1/2 x'Hx + c'x s.t. G x <= h, A x = b, lb <= x <= ub over "
            "the joint and base velocities: dense, 6-8 variables, H positive definite and scaled to a "
            "largest diagonal entry of 1. Ticks per scenario: "
            f"{counts}; {active} of the {len(self.selection)} QPs have an active bound or inequality at the "
            f"reference solution (DAQP at 1e-12, KKT residuals < {ds.REF_TOL:g}). The time limit is the "
            f"control period, {self.time_limit:g} s."
            + (f" Each scenario also from {self.starts - 1} perturbed initial configurations (<scenario>_s<start>, "
               f"seed {self.start_seed}; benchmarks/starts.py)." if self.starts > 1 else "")
        )

    @property
    def sparse_only(self) -> bool:
        return False

    def define_tolerances(self, runtime: float | None = None) -> None:
        """qpbenchmark's tolerances with the control period as the time limit (+ "wbc" if requested)."""
        runtime = self.time_limit if runtime is None else runtime
        super().define_tolerances(runtime=runtime)
        self.tolerances["wbc"] = qpbenchmark.Tolerance(WBC_TOLERANCE, WBC_TOLERANCE, WBC_TOLERANCE, runtime)

    def define_solver_settings(self) -> None:
        """qpbenchmark's solver settings (+ "wbc": ``wbc.solvers.DEFAULT_SETTINGS``, if requested)."""
        super().define_solver_settings()
        if "wbc" in self.requested_settings:
            from qpbenchmark.solver_settings import SolverSettings

            from wbc.solvers import DEFAULT_SETTINGS

            own = SolverSettings()
            for solver, options in DEFAULT_SETTINGS.items():
                for key, value in options.items():
                    own.set_param(solver, key, value)
            self.solver_settings["wbc"] = own
        self.solver_settings = {name: self.solver_settings[name] for name in self.requested_settings}
        self.tolerances = {name: self.tolerances[name] for name in self.requested_settings}

    @staticmethod
    def tick_has_active_constraint(sc: ds.ScenarioQPs) -> np.ndarray:
        """Per tick: a bound or inequality is active at the reference solution."""
        return sc.active[:, :sc.n + sc.n_ineq].any(axis=1)

    def tick_problems(self, sc: ds.ScenarioQPs, k: int) -> list[WbcProblem]:
        """The QPs the controller solved at tick ``k`` of ``sc``: one, named ``<scenario>_<tick>``
        (``<scenario>_s<start>_<tick>`` for a perturbed start).

        Hook for strict priorities: a hierarchical controller solves one QP per priority level
        per tick. Record them in the dataset with a level axis and return one problem per
        level here, named ``<scenario>_<tick>_L<level>``, level 0 first.
        """
        qp = sc.problem(k)
        problem = WbcProblem(qp.P, qp.q, qp.G, qp.h, qp.A, qp.b, qp.lb, qp.ub, name=f"{sc.label}_{k:05d}")
        problem.scenario, problem.start, problem.tick = sc.name, sc.start, k
        problem.active, problem.x_ref = bool(self.tick_has_active_constraint(sc)[k]), sc.x_ref[k]
        problem.x_previous = sc.x_ref[k - 1] if k > 0 else np.zeros(sc.n)
        return [problem]

    def __iter__(self) -> Iterator[WbcProblem]:
        yield from self.problems

    def subset(self, problems: list[WbcProblem]) -> WbcQpbenchmark:
        """A test set of ``problems`` only (same settings, solvers, limits), without the recorded
        scenarios: what a work unit ships to a worker (the problems' arrays, nothing else)."""
        part = copy.copy(self)
        part.problems, part.scenarios, part.selection = problems, [], []
        return part

    def parts(self, size: int) -> Iterator[WbcQpbenchmark]:
        """This test set in consecutive parts of ``size`` problems."""
        for start in range(0, len(self.problems), size):
            yield self.subset(self.problems[start:start + size])


if __name__ == "__main__":
    from qpbenchmark.benchmark import main

    (OUTPUT / "qpbenchmark").mkdir(parents=True, exist_ok=True)
    main(test_set_path=str(Path(__file__).resolve()), results_path=str(OUTPUT / "qpbenchmark" / "results.csv"))
