"""The QP over the real inputs ``u`` of a nonholonomic base (``Controller(reduced=True)``).

With ``v = S(q) u`` (:meth:`wbc.Robot.input_map`) the QP over ``v`` becomes one over ``u``:
``H_u = S^T H S``, ``c_u = S^T c``, rows ``C S``; bounds on ``v`` coordinates that are one
input each carry over, the coupled base rates ``(xdot, ydot)`` must be unbounded (their limits
are rows, as :class:`wbc.JointVelocityLimits` writes them). The no-slip rows then hold by
construction.
"""

from __future__ import annotations

import numpy as np

from ..core.errors import InvalidInputError
from .problem import QP


class InputReduction:
    """Rewrites one controller's QP over ``v`` into its QP over ``u`` each tick.

    Args:
        S: the input map at any configuration (its sparsity pattern is fixed).
        n_ineq, n_eq: rows of the QP.
    """

    def __init__(self, S: np.ndarray, n_ineq: int, n_eq: int) -> None:
        nv, nu = S.shape
        self.qp = QP(nu, n_ineq, n_eq)  #: the QP the solver sees
        self._HS = np.zeros((nv, nu))
        unit_rows = np.flatnonzero(np.sum(S != 0.0, axis=1) == 1)
        self._bound_v = unit_rows  # v coordinates whose bounds are bounds on one input
        self._bound_u = np.argmax(S[unit_rows] != 0.0, axis=1)
        self._coupled_v = np.setdiff1d(np.arange(nv), unit_rows)  # base x, y: no bounds allowed

    def check_bounds(self, qp_v: QP) -> None:
        """Raise InvalidInputError when a bound sits on a coupled base rate (called at
        construction on the static bounds)."""
        if np.any(np.isfinite(qp_v.lb[self._coupled_v])) or np.any(np.isfinite(qp_v.ub[self._coupled_v])):
            raise InvalidInputError("reduced=True needs the base x, y rates unbounded "
                                    "(express base speed limits as rows, as JointVelocityLimits does)")

    def reduce(self, qp_v: QP, S: np.ndarray) -> bool:
        """Write the QP over ``u`` from ``qp_v`` for this tick's ``S``; False when a bound
        appeared on a coupled base rate (a constraint whose bounds change per tick)."""
        qu = self.qp
        if np.any(np.isfinite(qp_v.lb[self._coupled_v])) or np.any(np.isfinite(qp_v.ub[self._coupled_v])):
            return False
        np.matmul(qp_v.H, S, out=self._HS)
        np.matmul(S.T, self._HS, out=qu.H)
        np.matmul(S.T, qp_v.c, out=qu.c)
        np.matmul(qp_v.C, S, out=qu.C)
        qu.upper[qu.n:] = qp_v.upper[qp_v.n:]
        qu.lower[qu.n:] = qp_v.lower[qp_v.n:]
        qu.lb[self._bound_u] = qp_v.lb[self._bound_v]
        qu.ub[self._bound_u] = qp_v.ub[self._bound_v]
        return True
