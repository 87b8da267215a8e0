"""The QP of one control tick, in preallocated buffers.

    minimize    1/2 v^T H v + c^T v
    subject to  G v <= h,   A v = b,   lb <= v <= ub

Inequality and equality rows share one matrix ``C = [G; A]`` and the bounds share
``upper = [ub; h; b]``, ``lower = [lb; -inf; b]`` -- the layout DAQP consumes
directly -- so ``G, h, A, b, lb, ub`` are views and no backend has to copy.

An inequality row may have a lower side too, ``l_i <= G_i v <= h_i`` (``lower[n + i]`` finite):
only in a QP solved by DAQP, which takes rows with two sides -- the band rows of strict
priorities (:mod:`wbc.control.hierarchy`). A reader of such a QP in the ``G v <= h`` form adds
``-G_i v <= -l_i`` (``benchmarks/dataset.py``'s ``make_problem`` does).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from ..runtime import kernels


@dataclass
class QP:
    """Buffers of a QP with ``n`` variables, ``n_ineq`` inequality and ``n_eq`` equality rows."""

    n: int
    n_ineq: int = 0
    n_eq: int = 0
    H: NDArray[np.float64] = field(init=False)
    c: NDArray[np.float64] = field(init=False)
    C: NDArray[np.float64] = field(init=False)
    upper: NDArray[np.float64] = field(init=False)
    lower: NDArray[np.float64] = field(init=False)

    def __post_init__(self) -> None:
        n, p, e = self.n, self.n_ineq, self.n_eq
        m = n + p + e
        # one flat buffer behind every array, so a single call can screen it for NaN
        self.data = np.zeros(n * n + n + (p + e) * n + 2 * m)
        sizes = np.cumsum([0, n * n, n, (p + e) * n, m, m])
        self.Hc = self.data[sizes[0]:sizes[2]].reshape(n + 1, n)  #: H with c as an extra row
        self.H = self.Hc[:n]
        self.c = self.Hc[n]
        self.C = self.data[sizes[2]:sizes[3]].reshape(p + e, n)
        self.upper = self.data[sizes[3]:sizes[4]]
        self.lower = self.data[sizes[4]:sizes[5]]
        self.upper.fill(np.inf)
        self.lower.fill(-np.inf)
        self.upper[n + p :] = self.lower[n + p :] = 0.0  # equality rows: b = 0 until written
        self.lb, self.ub = self.lower[:n], self.upper[:n]
        #: (ub; lb) as one (2, n) view: C-contiguous when there are no rows
        self.bounds = self.data[sizes[3]:sizes[5]].reshape(2, m)[:, :n]
        self.G, self.h = self.C[:p], self.upper[n : n + p]
        self.A, self.b = self.C[p:], self.upper[n + p :]

    def has_nan(self) -> bool:
        """True when any matrix, vector or bound holds a NaN (a bug upstream, never solved)."""
        return kernels.has_nan(self.data)

    @property
    def has_bounds(self) -> bool:
        return bool(np.any(np.isfinite(self.lb)) or np.any(np.isfinite(self.ub)))

    def sync_equalities(self) -> None:
        """Mirror ``b`` into the lower bound of the equality rows (call after writing ``b``)."""
        self.lower[self.n + self.n_ineq :] = self.b

    def copy(self) -> QP:
        """A deep copy (used to record QPs for tests and benchmarks)."""
        other = QP(self.n, self.n_ineq, self.n_eq)
        other.data[...] = self.data
        return other
