"""Every solver that qpsolvers finds installed, by name: :class:`QpsolversBackend`."""

from __future__ import annotations

import functools
import math
import time
import warnings
from types import ModuleType
from typing import TYPE_CHECKING, Any

import numpy as np

from ..core.quiet import silenced
from ..core.validation import all_finite
from ..qp.problem import QP
from .options import validate_options
from .solver import DEFAULT_SETTINGS, WARM_START_SOLVERS, QPSolution, QPSolver

if TYPE_CHECKING:  # pragma: no cover
    import qpsolvers


#: backends that ran once in this process (:meth:`QpsolversBackend._first_use`)
_FIRST_USE_DONE: set[str] = set()


class QpsolversBackend(QPSolver):
    """Any qpsolvers backend, called through ``qpsolvers.solve_problem``.

    With ``warm_start`` (option, default True) the previous solution is passed as the
    primal initial guess to the backends in :data:`WARM_START_SOLVERS`.
    """

    def __init__(self, name: str, options: dict[str, Any] | None = None) -> None:
        self.name = name
        settings = {**DEFAULT_SETTINGS.get(name, {}), **validate_options(name, options)}
        self.warm_start = bool(settings.pop("warm_start", True)) and name in WARM_START_SOLVERS
        self.settings = settings
        self._sparse = name in getattr(_qpsolvers(), "sparse_solvers", ())
        self._previous: np.ndarray | None = None
        if name not in _FIRST_USE_DONE:
            self._first_use()

    def _first_use(self) -> None:
        """Solve a small QP with fds 1 and 2 silenced (:func:`wbc.core.quiet.silenced`): whatever the
        backend prints the first time it runs in a process (highspy >= 1.16: a banner on
        stdout) is swallowed here, when the controller is built, never inside a tick."""
        qp = QP(2, 1, 1)
        qp.H[:] = np.eye(2)
        qp.c[:] = (1.0, -1.0)
        qp.G[:], qp.h[:] = ((1.0, 1.0),), 1.0
        qp.A[:], qp.b[:] = ((1.0, -1.0),), 0.0
        qp.lb[:], qp.ub[:] = -1.0, 1.0
        with silenced():
            self.solve(qp)  # its outcome does not matter; a backend that fails fails its real solves too
        _FIRST_USE_DONE.add(self.name)
        self._previous = None

    def __setstate__(self, state: dict[str, Any]) -> None:
        """A copy or an unpickled backend keeps the warm start; in a new process its first use
        (:meth:`_first_use`) runs now, as when built."""
        self.__dict__.update(state)
        if self.name not in _FIRST_USE_DONE:
            previous = self._previous
            self._first_use()
            self._previous = previous

    def reset(self) -> None:
        self._previous = None

    def solve(self, qp: QP) -> QPSolution:
        matrix = _scipy_sparse().csc_matrix if self._sparse else (lambda m: m)
        problem = _qpsolvers().Problem(
            matrix(qp.H),
            qp.c,
            matrix(qp.G) if qp.n_ineq else None,
            qp.h if qp.n_ineq else None,
            matrix(qp.A) if qp.n_eq else None,
            qp.b if qp.n_eq else None,
            qp.lb if qp.has_bounds else None,
            qp.ub if qp.has_bounds else None,
        )
        initvals = self._previous if self.warm_start and self._previous is not None else None
        if initvals is not None and initvals.shape != qp.c.shape:
            initvals = None
        start = time.perf_counter()
        try:
            with warnings.catch_warnings():  # failures are reported in the diagnostics instead
                warnings.simplefilter("ignore")
                solution = _qpsolvers().solve_problem(problem, solver=self.name, initvals=initvals, **self.settings)
        except Exception as exc:  # backends raise many types; report, never propagate
            self._previous = None
            return QPSolution(None, False, f"{type(exc).__name__}: {exc}", time.perf_counter() - start)
        elapsed = time.perf_counter() - start
        x = solution.x
        if not solution.found or x is None or not all_finite(np.asarray(x, dtype=np.float64)):
            self._previous = None
            return QPSolution(None, False, "not found", elapsed)
        x = np.array(x, dtype=np.float64)  # an owned, writable copy (PIQP's is read-only)
        defect = _optimality_defect(solution, qp)
        if defect > OPTIMALITY_TOLERANCE:
            self._previous = None
            return QPSolution(None, False, f"not optimal (dual residual / duality gap {defect:.1e}, relative)",
                              elapsed)
        self._previous = x
        return QPSolution(x, True, "optimal", elapsed)


#: largest relative dual residual or duality gap accepted from a qpsolvers backend's answer
#: (:func:`_optimality_defect`); HiGHS 1.15 was seen to report "optimal" with a dual
#: residual of 2 on an unconstrained 6-variable QP
OPTIMALITY_TOLERANCE = 1e-6


def _optimality_defect(solution: qpsolvers.Solution, qp: QP) -> float:
    """Dual residual ``|H x + c + G^T z + A^T y + z_box|_inf`` and duality gap of ``solution``
    (qpsolvers' own residuals) relative to the size of their terms (``s = 1 + |c|_inf +
    |H x|_inf``; the gap, a cost, over ``s (1 + |x|_inf)``): the check of optimality that the
    controller's feasibility check cannot make. 0 where the backend returned no multipliers
    (qpsolvers then reports inf: nothing to check)."""
    x = solution.x
    assert x is not None  # the caller checked that the backend found one
    with np.errstate(over="ignore", invalid="ignore"):  # (huge answers: inf, read as nothing to check)
        scale = 1.0 + float(np.max(np.abs(qp.c))) + float(np.max(np.abs(qp.H @ x)))
        dual, gap = solution.dual_residual(), solution.duality_gap()
    dual = dual / scale if math.isfinite(dual) else 0.0
    gap = gap / (scale * (1.0 + float(np.max(np.abs(x))))) if math.isfinite(gap) else 0.0
    return max(dual, gap)


@functools.cache
def _qpsolvers() -> ModuleType:
    """qpsolvers, imported when a backend is first built (~0.06 s that ``import wbc`` does not pay)."""
    import qpsolvers

    return qpsolvers


@functools.cache
def _scipy_sparse() -> ModuleType:
    """``scipy.sparse`` (imported with qpsolvers; named here for the sparse backends' matrices)."""
    import scipy.sparse

    return scipy.sparse
