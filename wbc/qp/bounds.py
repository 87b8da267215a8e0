"""How the bounds of several constraints become the QP's ``lb <= v <= ub``.

Every bounded constraint writes its own ``(upper; lower)`` pair (``+-inf`` where it has no
opinion). *Hard* bounds (speed limits) are intersected; *soft* bounds (position dampers) are
intersected among themselves -- where they exclude each other, both are set to the midpoint
of the conflict -- and then clipped into the hard ones, so conflicting limits never make the
QP infeasible: a joint outside its range returns at top speed. The merge is one compiled op
of the tick program (:func:`wbc.runtime.kernels.merge_bounds`).
"""

from __future__ import annotations

import numpy as np

from ..runtime import kernels
from ..runtime.program import TickProgram
from .problem import QP


class BoundPolicy:
    """The bound buffers of one controller and their merge into its QP.

    Args:
        n_hard, n_soft: numbers of bounded hard / soft constraints.
        nv: number of velocity coordinates.
    """

    def __init__(self, n_hard: int, n_soft: int, nv: int) -> None:
        self.n_hard = n_hard
        # constraint k writes (upper; lower) = self.bounds[k] (rows 2k, 2k + 1 of the op's
        # matrix), hard ones first; with no bounded constraint at all, one all-inf pair
        self.bounds = np.empty((max(n_hard + n_soft, 1), 2, nv))
        self.bounds[:, 0], self.bounds[:, 1] = np.inf, -np.inf
        self.upper, self.lower = self.bounds[:, 0], self.bounds[:, 1]

    def slot(self, k: int) -> tuple[np.ndarray, np.ndarray]:
        """(lower, upper) of bounded constraint ``k`` (hard ones numbered first)."""
        return self.bounds[k, 1], self.bounds[k, 0]

    def add_op(self, program: TickProgram, qp: QP) -> None:
        """The merge into ``qp.lb, qp.ub`` as an op of ``program``."""
        count, _, nv = self.bounds.shape
        program.add(kernels.MERGE_BOUNDS, bounds=self.bounds.reshape(2 * count, nv), count=count,
                    n_hard=self.n_hard, nv=nv, upper=qp.ub, lower=qp.lb)
