"""DAQP as a backend: :class:`DaqpBackend`, native (compiled calls of DAQP's C API, inside the
tick program) when the installed build passes :mod:`wbc.solvers.daqp.probe`, through DAQP's
Python binding otherwise."""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ...core.validation import all_finite
from ...qp.problem import QP
from ...runtime import kernels
from ...runtime.program import TickProgram
from ..options import validate_options
from ..solver import DEFAULT_SETTINGS, QPSolution, QPSolver
from . import abi as daqp_abi
from . import probe as daqp_probe
from .native import NativeWorkspace

_EXITFLAG, _DEFECT, _TIME = kernels.DAQP_CONTROL_EXITFLAG, kernels.DAQP_CONTROL_DEFECT, kernels.DAQP_CONTROL_TIME

#: DAQP's primal tolerance in the levels of a strict hierarchy (DAQP's default)
LEVEL_PRIMAL_TOL = 1e-6


class DaqpBackend(QPSolver):
    """DAQP on a persistent workspace that points into the QP's own buffers (no copy).

    **Native path** (DAQP releases whose C layout :mod:`wbc.solvers.daqp.abi` knows and has checked):
    :class:`wbc.solvers.daqp.native.NativeWorkspace` calls DAQP's C API from compiled code. A
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
        self._library = daqp_probe.native()
        self._workspace: NativeWorkspace | None = None  # native path
        self._bound: NativeWorkspace | None = None  # the one a tick program runs
        self._model: Any = None  # binding path: a daqp.Model (untyped extension)
        self._data: np.ndarray | None = None  # buffer of the QP the binding's workspace points into
        self._shape: tuple[int, int, int] | None = None
        self._sense = np.zeros(0, dtype=np.int32)

    def __reduce__(self) -> tuple[type[DaqpBackend], tuple[dict[str, Any]]]:
        """Copies and pickles are new backends with these options, starting cold: DAQP's
        workspaces (C memory, pointers into one controller's QP) stay with their controller."""
        return type(self), (self.options,)

    @property
    def native(self) -> bool:
        """Whether DAQP is called through its C API (else through its Python binding;
        :func:`wbc.solvers.daqp.probe.unavailable_reason` says why)."""
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

    def workspace(self, qp: QP, working_set_first: bool = False) -> NativeWorkspace | None:
        """A native workspace of its own on ``qp`` (this backend's settings and warm start), for a
        caller that solves several QPs every tick (the levels of :mod:`wbc.control.hierarchy`); None on
        the binding path. ``working_set_first``: see :class:`~wbc.solvers.daqp.native.NativeWorkspace`."""
        if self._library is None:
            return None
        return NativeWorkspace(self._library, qp, self.settings, self.warm_start, working_set_first)

    def collect(self) -> QPSolution:
        """The outcome of the solve that the bound program ran (:meth:`bind_program`)."""
        bound = self._bound
        assert bound is not None, "collect() before bind_program()"
        return self._native_solution(bound, *bound.outcome())

    def collect_optimal(self, tolerance: float) -> tuple[NDArray[np.float64], float] | None:
        bound = self._bound
        assert bound is not None, "collect_optimal() before bind_program()"
        control = bound.control_view  # (a memoryview's items are Python floats: ~0.1 us less than a slice)
        if control[_EXITFLAG] >= 1.0 and control[_DEFECT] <= tolerance:
            return bound.x.copy(), control[_TIME]
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
            else:  # A too: DAQP then restores the state of a row that was zero (abi.WARM_UPDATE)
                exitflag = self._model.update(qp.H, A=qp.C if len(qp.C) else None, sense=sense)
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
