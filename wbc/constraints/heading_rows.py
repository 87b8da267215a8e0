"""Constraint rows on the planar base rates that turn with the base heading."""

from __future__ import annotations

import math

import numpy as np


class HeadingRows:
    """Columns ``(x, y)`` of some rows of ``G`` of the form ``cos(heading) A + sin(heading) B``.

    Base-frame limits (speed, wheel speeds) act on ``R(heading)^T (xdot, ydot)``, so their
    rows are linear in ``(cos, sin)``. Writing them is one matrix-vector product on
    ``[A | B]`` flattened, then one copy into the rows -- instead of a rotation matrix
    built entry by entry and several strided products.

    Args:
        cos_part: ``A``, (rows, 2): the rows' ``(x, y)`` columns at heading 0.
        sin_part: ``B``, (rows, 2): the rows' ``(x, y)`` columns at heading pi/2.
        G: the constraint's rows (rows, nv); ``x``, ``y``: velocity indices of the base rates.
    """

    def __init__(self, cos_part: np.ndarray, sin_part: np.ndarray, G: np.ndarray, x: int, y: int) -> None:
        rows = len(G)
        self._basis = np.ascontiguousarray(np.stack([np.ravel(cos_part), np.ravel(sin_part)], axis=1))
        self._cos_sin = np.zeros(2)
        self._values = np.zeros(2 * rows)
        self._block = self._values.reshape(rows, 2)
        self._target = G[:, x:x + 2] if y == x + 1 else None
        self._G, self._columns = G, [x, y]

    def write(self, heading: float) -> None:
        """Write the ``(x, y)`` columns for this ``heading`` [rad]."""
        cos_sin = self._cos_sin
        cos_sin[0], cos_sin[1] = math.cos(heading), math.sin(heading)
        np.dot(self._basis, cos_sin, out=self._values)
        if self._target is not None:
            self._target[...] = self._block
        else:
            self._G[:, self._columns] = self._block
