"""The fallback chain of a tick whose QP the backend could not solve (see :class:`wbc.Controller`).

1. The same QP is solved again by DAQP with the rows of soft constraints *elastic*
   (violations penalised, DAQP's soft constraints); hard limits hold and are checked. If
   DAQP fails on it, once more with ``H + ELASTIC_REGULARISATION max(diag H) I``: at the
   damping floor (1e-10 of the largest curvature, a pose weighted 1e12 beside a position
   weighted 1) DAQP called a feasible QP infeasible (hard wheel rows on coordinates that only
   the floor held), which twice the floor already cured.
2. If that fails too, or the QP data holds NaN, the command is ``v = 0``, which satisfies
   every shipped hard limit (speed, wheel and no-slip limits).

With ``strict=True`` a failure raises :class:`~wbc.core.errors.SolverError` instead.
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np

from ..core.errors import SolverError
from ..core.outcome import Outcome
from ..qp.problem import QP
from ..runtime import kernels
from ..solvers import QPSolution

#: largest relative violation of its own constraints accepted in an answer
#: (:func:`wbc.runtime.kernels.constraint_defect`); the backends' default tolerances are ~1e-9
ANSWER_TOLERANCE = 1e-6

#: the regularisation of the elastic solve's second try (relative to the largest diagonal of H)
ELASTIC_REGULARISATION = 1e-8

_SOFT, _EQUALITY = 8, 5  # DAQP's sense flags


class Fallback:
    """The fallback chain of one controller.

    Args:
        soft_rows: indices, among the inequality rows, of the soft constraints' rows.
        budget: DAQP settings of the elastic solve (``time_limit``, ``iter_limit``: the
            main backend's budget, :attr:`wbc.solvers.QPSolver.fallback_budget`).
        strict: raise :class:`SolverError` instead of answering.
    """

    def __init__(self, soft_rows: np.ndarray, budget: dict[str, Any], strict: bool) -> None:
        self.soft_rows, self.budget, self.strict = soft_rows, budget, strict
        kernels.prepare("constraint_defect")  # answer() calls it in ticks: compiled now

    def answer(self, qp: QP, failed: QPSolution, solver: str, tick: int,
               has_nan: bool) -> tuple[QPSolution, Outcome, str]:
        """The command after ``solver`` failed on ``qp`` with ``failed``: (solution, outcome, status)."""
        if self.strict:
            raise SolverError(f"{solver} failed at tick {tick}: {failed.status}")
        reason = f"{solver}: {failed.status}"
        elapsed = failed.solve_time
        if not has_nan:
            elastic = self.elastic_solve(qp)
            elapsed += elastic.solve_time
            if elastic.success:
                return (QPSolution(elastic.x, False, "", elapsed), Outcome.ELASTIC,
                        f"fallback: elastic soft rows after {reason}")
            reason += f"; elastic: {elastic.status}"
        return self.last_resort(qp, reason, elapsed, has_nan)

    def last_resort(self, qp: QP, reason: str, elapsed: float, has_nan: bool) -> tuple[QPSolution, Outcome, str]:
        """The command when nothing else answered: ``v = 0``."""
        return (QPSolution(np.zeros(qp.n), False, "", elapsed), Outcome.ZERO,
                f"fallback: zero command after {reason}")

    def elastic_solve(self, qp: QP) -> QPSolution:
        """DAQP, cold, on ``qp`` with the soft inequality rows elastic; hard limits checked."""
        import daqp

        start = time.perf_counter()
        sense = np.zeros(qp.n + qp.n_ineq + qp.n_eq, dtype=np.int32)
        sense[qp.n + self.soft_rows] = _SOFT
        sense[qp.n + qp.n_ineq:] = _EQUALITY
        H = qp.H
        for attempt in range(2):
            try:
                x, _, exitflag, _ = daqp.solve(H, qp.c, qp.C, qp.upper, qp.lower, sense, **self.budget)
            except Exception as exc:  # noqa: BLE001 -- any backend error means: no elastic solution
                return QPSolution(None, False, f"{type(exc).__name__}: {exc}", time.perf_counter() - start)
            if exitflag >= 1 and np.all(np.isfinite(x)):
                break
            curvature = float(np.max(np.diag(qp.H)))
            if attempt or not math.isfinite(curvature):  # (an overflowed H: nothing to regularise)
                break
            H = qp.H + ELASTIC_REGULARISATION * max(curvature, 1e-300) * np.eye(qp.n)  # once more (docstring)
        elapsed = time.perf_counter() - start
        if exitflag < 1 or not np.all(np.isfinite(x)):
            return QPSolution(None, False, f"exitflag {exitflag}", elapsed)
        # the bounds are hard here, but DAQP's soft mode was seen to leave them ~1e-6 off on
        # ill-conditioned ticks: project onto them (exact), then check every hard row
        np.clip(x, qp.lb, qp.ub, out=x)
        hard_upper = qp.upper.copy()
        hard_upper[qp.n + self.soft_rows] = np.inf
        defect = kernels.constraint_defect(qp.C, hard_upper, qp.lower, x)
        if defect > ANSWER_TOLERANCE:
            return QPSolution(None, False, f"hard limits violated by {defect:.1e} (relative)", elapsed)
        return QPSolution(x, True, "optimal", elapsed)
