"""What every QP backend shares: the interface ``QPSolver.solve(qp) -> QPSolution`` and the
default settings.

Default settings aim at control-grade accuracy (primal/dual residuals ~1e-9) so
that all backends return the same command; override them with ``options``.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from ..qp.problem import QP
from ..runtime.program import TickProgram
from .options import BUDGET_KEYS

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
