"""QP backends behind one interface: ``QPSolver.solve(qp) -> QPSolution``.

Every solver that qpsolvers finds installed works by name through
:class:`QpsolversBackend`. ``"daqp"`` additionally has a direct backend that hands
the preallocated buffers of :class:`~wbc.qp.problem.QP` to DAQP without any copy.

Default settings aim at control-grade accuracy (primal/dual residuals ~1e-9) so
that all backends return the same command; override them with ``options``.
"""

from __future__ import annotations

import math
import time
import warnings
from abc import ABC, abstractmethod
from typing import Any, NamedTuple

import numpy as np
import qpsolvers
import scipy.sparse as sp
from numpy.typing import NDArray

from . import daqp_abi
from .core.errors import UnknownSolverError
from .core.quiet import silenced
from .core.validation import all_finite
from .daqp_native import NativeWorkspace
from .qp.problem import QP
from .runtime import kernels
from .runtime.program import TickProgram
from .solver_options import BUDGET_KEYS, validate_options

#: per-backend settings passed to qpsolvers unless the user overrides them
DEFAULT_SETTINGS: dict[str, dict[str, Any]] = {
    # time_limit [s]: a safety cap per solve (a hung backend would hang the control loop);
    # tighten it to your period with solver_options
    # polishing off: OSQP >= 1.0 prints "Polishing not needed - no active set detected" to
    # fd 1 (C printf, whatever `verbose`) on every solve without active constraints; at
    # eps 1e-9 the unpolished answer still meets the 1e-6 agreement on recorded ticks
    "osqp": {"eps_abs": 1e-9, "eps_rel": 1e-9, "polishing": False, "max_iter": 200_000, "verbose": False,
             "raise_error": False, "time_limit": 0.1},
    # no time budget in ProxQP: an iteration cap instead (without one a fuzz campaign hung in it)
    "proxqp": {"eps_abs": 1e-10, "eps_rel": 0.0, "max_iter": 10_000},
    "clarabel": {"tol_gap_abs": 1e-12, "tol_gap_rel": 1e-12, "tol_feas": 1e-12, "tol_ktratio": 1e-10,
                 "time_limit": 0.1},
    # without the duality-gap check PIQP stops on small residuals alone (seen 1e-4 off)
    "piqp": {"eps_abs": 1e-12, "eps_rel": 1e-12, "check_duality_gap": True,
             "eps_duality_gap_abs": 1e-12, "eps_duality_gap_rel": 1e-12},
    # HiGHS regularises QPs by default, which moved solutions by up to 7e-6 on recorded ticks;
    # its QP solver can cycle forever on degenerate ticks (tests/test_reliability.py): cap it.
    # An abort (malloc(): invalid size) was reported with regularisation 0.0; not reproduced
    # with highspy 1.15.1 on ~40 000 ill-conditioned / degenerate QPs and random ticks
    # (H up to 1e11 : 1e-3, zero diagonals, duplicated rows through one vertex, cost
    # ratios 1e12..1e-12); a set of those runs in a child process in tests/test_solvers.py.
    # Whatever the costs, the controller hands every backend H scaled to max diag 1 with the
    # damping floored at 1e-10 of it (wbc.runtime.kernels.normalise_cost): positive definite and well
    # scaled, which is what HiGHS's own regularisation would otherwise provide
    "highs": {"primal_feasibility_tolerance": 1e-10, "dual_feasibility_tolerance": 1e-10,
              "qp_regularization_value": 0.0, "qp_iteration_limit": 10_000, "time_limit": 0.1},
    "scs": {"eps_abs": 1e-9, "eps_rel": 1e-9},
    # DAQP's default primal_tol (1e-6, in its scaled rows) let it stop on an active set 1e-7
    # suboptimal in relative cost (5.6e-4 rad/s off in one joint; random fuzz: a PUMA joint
    # exactly on its limit); 1e-9 solves that case and costs no measurable tick time. The levels
    # of a strict hierarchy keep 1e-6 (DaqpBackend.for_levels): their band rows need the slack.
    "daqp": {"primal_tol": 1e-9},
    "ecos": {"abstol": 1e-10, "reltol": 1e-10, "feastol": 1e-10},
}

_SPARSE_SOLVERS = set(getattr(qpsolvers, "sparse_solvers", ()))

#: backends that ran once in this process (:meth:`QpsolversBackend._first_use`)
_FIRST_USE_DONE: set[str] = set()

#: qpsolvers backends that use a primal warm start (``initvals``); DAQP warm-starts its
#: active set through :class:`DaqpBackend`; the others ignore it
WARM_START_SOLVERS = frozenset({"daqp", "osqp", "proxqp"})


class QPSolution(NamedTuple):
    """Outcome of one solve: ``x`` is None unless ``success``."""

    x: NDArray[np.float64] | None
    success: bool
    status: str
    solve_time: float  #: wall time inside the backend [s]
    #: relative violation of the QP's bounds and rows by x (:func:`wbc.runtime.kernels.qp_defect`)
    #: when the backend checked it itself (the native DAQP path); None: not checked yet
    defect: float | None = None


class QPSolver(ABC):
    """A QP backend."""

    name: str
    settings: dict[str, Any]

    @abstractmethod
    def solve(self, qp: QP) -> QPSolution:
        """Solve ``qp`` now.

        Returns:
            The answer (``x`` None unless ``success``), the backend's status and time. A backend
            never raises for a failed solve: the failure is in the solution.
        """

    def reset(self) -> None:  # noqa: B027 -- optional hook: a backend without warm-start state keeps this no-op
        """Forget any warm start (the next solve starts cold)."""

    def bind_program(self, program: TickProgram, qp: QP) -> bool:
        """Append the solve of ``qp`` to a controller's tick program, when this backend can run
        inside it (then the controller reads each tick's answer with :meth:`collect` instead
        of calling :meth:`solve`); False, and nothing appended, otherwise."""
        return False

    def collect(self) -> QPSolution:
        """The answer of the solve that the bound tick program ran (see :meth:`bind_program`)."""
        raise NotImplementedError(f"{self.name} does not run inside a tick program")

    def collect_optimal(self, tolerance: float) -> tuple[NDArray[np.float64], float] | None:
        """The control loop's fast path of :meth:`collect`: ``(x, solve time [s])`` when the
        bound solve succeeded and its answer's defect is at most ``tolerance``; None
        otherwise (then :meth:`collect` says what happened)."""
        return None

    @property
    def fallback_budget(self) -> dict[str, Any]:
        """DAQP settings (``time_limit`` [s], ``iter_limit``) for the elastic fallback solve:
        this backend's time budget whatever the backend; its iteration budget only when it
        is DAQP (iterations of other algorithms do not count the same work). Nothing for a
        backend without ``settings``."""
        own, settings = BUDGET_KEYS.get(self.name, {}), getattr(self, "settings", {})
        budget = {"time_limit": settings.get(own.get("time_limit", ""))}
        if self.name == "daqp":
            budget["iter_limit"] = settings.get("iter_limit")
        return {key: value for key, value in budget.items() if value is not None}

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.name!r})"


def available_solvers() -> list[str]:
    """Names of the QP solvers qpsolvers finds installed."""
    return list(qpsolvers.available_solvers)


def make_solver(name: str, options: dict[str, Any] | None = None) -> QPSolver:
    """Backend for ``name``: the direct DAQP backend for ``"daqp"``, qpsolvers otherwise.

    ``options`` are checked by the backend's constructor
    (:func:`wbc.solver_options.validate_options`).

    Raises:
        UnknownSolverError: ``name`` is not a solver qpsolvers finds installed.
        InvalidSolverOptionError: an unknown key or a bad value in ``options``.
    """
    if not isinstance(name, str) or name not in qpsolvers.available_solvers:
        raise UnknownSolverError(
            f"unknown or uninstalled QP solver {name!r}; installed: {', '.join(available_solvers())}"
        )
    if name == "daqp":
        return DaqpBackend(options)
    return QpsolversBackend(name, options)


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
        self._sparse = name in _SPARSE_SOLVERS
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

    def reset(self) -> None:
        self._previous = None

    def solve(self, qp: QP) -> QPSolution:
        matrix = sp.csc_matrix if self._sparse else (lambda m: m)
        problem = qpsolvers.Problem(
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
                solution = qpsolvers.solve_problem(problem, solver=self.name, initvals=initvals, **self.settings)
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


#: DAQP's primal tolerance in the levels of a strict hierarchy (DAQP's default)
LEVEL_PRIMAL_TOL = 1e-6


class DaqpBackend(QPSolver):
    """DAQP on a persistent workspace that points into the QP's own buffers (no copy).

    **Native path** (DAQP releases whose C layout :mod:`wbc.daqp_abi` knows and has checked):
    :class:`wbc.daqp_native.NativeWorkspace` calls DAQP's C API from compiled code. A
    controller appends the solve to its tick program (:meth:`bind_program`), so the whole
    tick is one native call and :meth:`collect` reads its outcome; :meth:`solve` solves a
    QP on its own (one native call). **Binding path** (any other DAQP): a ``daqp.Model``,
    set up once, refreshed by ``update(H)`` each tick.

    Either way each tick re-forms DAQP's factorisation from H, which re-derives every other
    part of the workspace (``A R^-1``, ``R^-T f``, the scaled bounds) from the buffers, so
    the fresh ``c``, rows and bounds are picked up too. With ``warm_start=True`` (default)
    the solve starts from the previous tick's active set, which in a control loop usually
    means zero or one active-set change; a failed solve is never warm-started from.
    ``options`` are DAQP settings (``iter_limit``, ``time_limit`` [s], ``primal_tol``,
    ...) plus ``warm_start``.
    """

    name = "daqp"

    def __init__(self, options: dict[str, Any] | None = None) -> None:
        chosen = validate_options(self.name, options)
        self.options = dict(options or {})  #: as given (for :meth:`for_levels`)
        settings = {**DEFAULT_SETTINGS[self.name], **chosen}
        self.warm_start = bool(settings.pop("warm_start", True))
        self.settings = settings
        self._library = daqp_abi.native()
        self._workspace: NativeWorkspace | None = None  # native path
        self._bound: NativeWorkspace | None = None  # the one a tick program runs
        self._model: Any = None  # binding path: a daqp.Model (untyped extension)
        self._data: np.ndarray | None = None  # buffer of the QP the binding's workspace points into
        self._shape: tuple[int, int, int] | None = None
        self._sense = np.zeros(0, dtype=np.int32)

    @property
    def native(self) -> bool:
        """Whether DAQP is called through its C API (else through its Python binding;
        :func:`wbc.daqp_abi.unavailable_reason` says why)."""
        return self._library is not None

    def for_levels(self) -> DaqpBackend:
        """A backend for the levels of a strict hierarchy: these options, but DAQP's own
        ``primal_tol`` (:data:`LEVEL_PRIMAL_TOL`) unless the options set one. Band rows pin a
        level below to the optimal task values of the levels above, a thin feasible set that
        DAQP called infeasible on 1.5 % of a fast reach's ticks with ``primal_tol`` 1e-9."""
        return DaqpBackend({"primal_tol": LEVEL_PRIMAL_TOL, **self.options})

    def reset(self) -> None:
        """Forget the warm start (the next solve starts cold)."""
        self._model = None
        for workspace in {id(w): w for w in (self._workspace, self._bound) if w is not None}.values():
            workspace.reset()

    def bind_program(self, program: TickProgram, qp: QP) -> bool:
        """Append the solve of ``qp`` to ``program`` (native path only; False otherwise)."""
        if self._library is None:
            return False
        self._bound = NativeWorkspace(self._library, qp, self.settings, self.warm_start)
        self._bound.add_op(program)
        return True

    @property
    def bound(self) -> NativeWorkspace | None:
        """The workspace whose solve the program of :meth:`bind_program` runs (None before)."""
        return self._bound

    def workspace(self, qp: QP) -> NativeWorkspace | None:
        """A native workspace of its own on ``qp`` (this backend's settings and warm start), for a
        caller that solves several QPs every tick (the levels of :mod:`wbc.hierarchy`); None on
        the binding path."""
        return None if self._library is None else NativeWorkspace(self._library, qp, self.settings, self.warm_start)

    def collect(self) -> QPSolution:
        """The outcome of the solve that the bound program ran (:meth:`bind_program`)."""
        bound = self._bound
        assert bound is not None, "collect() before bind_program()"
        return self._native_solution(bound, *bound.outcome())

    def collect_optimal(self, tolerance: float) -> tuple[NDArray[np.float64], float] | None:
        bound = self._bound
        assert bound is not None, "collect_optimal() before bind_program()"
        exitflag, defect, elapsed = bound.control[kernels.DAQP_CONTROL_OUTCOME].tolist()
        if exitflag >= 1.0 and defect <= tolerance:
            return bound.x.copy(), elapsed
        return None

    def solve(self, qp: QP) -> QPSolution:
        if self._library is None:
            return self._binding_solve(qp)
        workspace: NativeWorkspace | None
        if self._bound is not None and self._bound.qp is qp:
            workspace = self._bound
        else:  # any other QP: copied into a workspace of its shape, which keeps its warm start
            workspace = self._workspace
            if workspace is None or (workspace.qp.n, workspace.qp.n_ineq, workspace.qp.n_eq) != (qp.n, qp.n_ineq,
                                                                                             qp.n_eq):
                workspace = NativeWorkspace(self._library, QP(qp.n, qp.n_ineq, qp.n_eq), self.settings,
                                            self.warm_start)
                self._workspace = workspace
            workspace.qp.data[...] = qp.data
        return self._native_solution(workspace, *workspace.solve())

    def _native_solution(self, workspace: NativeWorkspace, exitflag: int, defect: float,
                         elapsed: float) -> QPSolution:
        if exitflag >= 1 and math.isfinite(defect):
            return QPSolution(workspace.x.copy(), True, "optimal", elapsed, defect)
        workspace.reset()  # never warm start from a failed solve
        status = "answer not finite" if exitflag >= 1 else daqp_abi.EXIT_FLAGS.get(exitflag, f"exitflag {exitflag}")
        return QPSolution(None, False, status, elapsed)

    # ------------------------------------------------- DAQP's Python binding
    def _setup(self, qp: QP) -> int:
        import daqp

        self._shape = (qp.n, qp.n_ineq, qp.n_eq)
        self._sense = np.zeros(qp.n + qp.n_ineq + qp.n_eq, dtype=np.int32)
        self._sense[qp.n + qp.n_ineq :] = daqp_abi.SENSE_EQUALITY
        self._model = daqp.Model()
        if self.settings:
            self._model.settings = self.settings
        exitflag, _ = self._model.setup(qp.H, qp.c, qp.C, qp.upper, qp.lower, self._sense)
        self._data = qp.data
        return exitflag

    def _binding_solve(self, qp: QP) -> QPSolution:
        start = time.perf_counter()
        try:
            sense = None if self.warm_start else self._sense  # passing sense forgets the active set
            if self._model is None or self._shape != (qp.n, qp.n_ineq, qp.n_eq):
                exitflag = self._setup(qp)
            elif self._data is not qp.data:  # another QP of the same shape: point the workspace at it
                # (A=None without rows: daqp 0.11's update indexes an empty A out of bounds)
                exitflag = self._model.update(H=qp.H, f=qp.c, A=qp.C if len(qp.C) else None, bupper=qp.upper,
                                              blower=qp.lower, sense=sense)
                self._data = qp.data
            else:
                exitflag = self._model.update(qp.H, sense=sense)
            if exitflag >= 0:
                x, _, exitflag, _ = self._model.solve()
        except Exception as exc:
            self._model = None
            return QPSolution(None, False, f"{type(exc).__name__}: {exc}", time.perf_counter() - start)
        elapsed = time.perf_counter() - start
        if exitflag >= 1 and all_finite(x):  # NaN or inf: never returned
            return QPSolution(x, True, "optimal", elapsed)
        self._model = None  # never warm start from a failed solve
        return QPSolution(None, False, daqp_abi.EXIT_FLAGS.get(exitflag, f"exitflag {exitflag}"), elapsed)
