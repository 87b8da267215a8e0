"""How the bounds of several constraints become the QP's ``lb <= v <= ub``.

Every bounded constraint writes its own ``(upper; lower)`` pair (``+-inf`` where it has no
opinion). *Hard* bounds (speed limits) are intersected; *soft* bounds (position dampers) are
intersected among themselves -- where they exclude each other, both are set to the midpoint
of the conflict -- and then clipped into the hard ones, so conflicting limits never make the
QP infeasible: a joint outside its range returns at top speed.
"""

from __future__ import annotations

import numpy as np

from . import kernels
from .program import TickProgram
from .qp import QP


class BoundPolicy:
    """The bound buffers of one controller and the merge into its QP.

    Args:
        hard_dynamic: whether some hard constraint rewrites its bounds every tick (else the
            hard bounds are intersected once, after ``write_static``).
        n_hard, n_soft: numbers of bounded hard / soft constraints.
        nv: number of velocity coordinates.
    """

    def __init__(self, n_hard: int, n_soft: int, nv: int, hard_dynamic: bool) -> None:
        self.n_hard, self.hard_dynamic = n_hard, hard_dynamic
        # each bounded constraint k writes (upper; lower) = self.bounds[k]: hard ones first;
        # with no bounded constraint at all, one all-inf pair
        self.bounds = np.empty((max(n_hard + n_soft, 1), 2, nv))
        self.bounds[:, 0], self.bounds[:, 1] = np.inf, -np.inf
        self.upper, self.lower = self.bounds[:, 0], self.bounds[:, 1]
        n_soft = len(self.bounds) - n_hard
        self._hard = self.bounds[0] if n_hard == 1 else np.array([[np.inf] * nv, [-np.inf] * nv])
        self._soft = self.bounds[n_hard] if n_soft == 1 else np.zeros((2, nv))  # scratch if several
        self._hard_rows, self._soft_rows = tuple(self._hard), tuple(self._soft)
        #: the usual case -- fixed hard bounds, one soft pair -- is one compiled clip
        self.compiled = n_hard >= 1 and n_soft == 1 and not hard_dynamic

    def slot(self, k: int) -> tuple[np.ndarray, np.ndarray]:
        """(lower, upper) of bounded constraint ``k`` (hard ones numbered first)."""
        return self.bounds[k, 1], self.bounds[k, 0]

    def intersect_hard(self) -> None:
        """Intersect the hard bounds (once after ``write_static`` when they are static)."""
        if self.n_hard > 1:
            _intersect(self.bounds[: self.n_hard], self._hard)

    def add_op(self, program: TickProgram, qp: QP) -> None:
        """The clip of the soft bounds into the hard ones as a compiled op (when :attr:`compiled`)."""
        (soft_upper, soft_lower), (hard_upper, hard_lower) = self._soft_rows, self._hard_rows
        program.add(kernels.OP_CLIP_BOUNDS, soft_upper=soft_upper, soft_lower=soft_lower, hard_upper=hard_upper,
                    hard_lower=hard_lower, upper=qp.ub, lower=qp.lb, n=qp.n)

    def merge(self, qp: QP) -> None:
        """``lb, ub`` of ``qp``: hard bounds intersected, then the soft ones clipped into them."""
        k, total = self.n_hard, len(self.bounds)
        if self.hard_dynamic:
            self.intersect_hard()
        if k == total:
            qp.bounds[...] = self._hard
            return
        if total - k > 1:
            _intersect(self.bounds[k:], self._soft)
            _meet_halfway(self._soft)
        if k == 0:
            qp.bounds[...] = self._soft
            _meet_halfway(qp.bounds)
            return
        soft_upper, soft_lower = self._soft_rows
        hard_upper, hard_lower = self._hard_rows
        kernels.clip_bounds(soft_upper, soft_lower, hard_upper, hard_lower, qp.ub, qp.lb)


def _intersect(bounds: np.ndarray, out: np.ndarray) -> None:
    """``out = (min_k upper_k; max_k lower_k)`` of ``bounds`` (k, 2, nv) rows (upper; lower)."""
    np.minimum(bounds[0, 0], bounds[1, 0], out=out[0])
    np.maximum(bounds[0, 1], bounds[1, 1], out=out[1])
    for upper, lower in bounds[2:]:
        np.minimum(out[0], upper, out=out[0])
        np.maximum(out[1], lower, out=out[1])


def _meet_halfway(bounds: np.ndarray) -> None:
    """Where soft bounds (upper; lower) exclude each other (lower > upper), set both to their midpoint."""
    upper, lower = bounds
    conflict = lower > upper
    if conflict.any():
        lower[conflict] = upper[conflict] = 0.5 * (lower[conflict] + upper[conflict])
