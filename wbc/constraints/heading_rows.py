"""Constraint rows on the planar base rates that turn with the base heading."""

from __future__ import annotations

import numpy as np

from ..model.kinematics import Kinematics
from ..runtime import kernels
from ..runtime.program import TickProgram


class HeadingRows:
    """Columns ``(x, y)`` of some rows ``G`` of the form ``cos(heading) A + sin(heading) B``.

    Base-frame limits (speed, wheel speeds) act on ``R(heading)^T (xdot, ydot)``, so their
    rows are linear in ``(cos, sin)`` (:func:`wbc.runtime.kernels.heading_rows`).

    Args:
        cos_part: ``A``, (rows, 2): the rows' ``(x, y)`` columns at heading 0.
        sin_part: ``B``, (rows, 2): the rows' ``(x, y)`` columns at heading pi/2.
        heading: index of the heading in ``q``; ``x``, ``y``: velocity indices of the base rates.
    """

    def __init__(self, cos_part: np.ndarray, sin_part: np.ndarray, heading: int, x: int, y: int) -> None:
        self._cos_part = np.ascontiguousarray(cos_part, dtype=np.float64)
        self._sin_part = np.ascontiguousarray(sin_part, dtype=np.float64)
        self._heading, self._x, self._y = heading, x, y

    def write(self, q: np.ndarray, G: np.ndarray) -> None:
        """Write the ``(x, y)`` columns of ``G`` for the heading in ``q``."""
        kernels.heading_rows(self._cos_part, self._sin_part, q, self._heading, G, self._x, self._y)

    def add_op(self, program: TickProgram, kin: Kinematics, G: np.ndarray) -> None:
        """The same as a compiled op (``G``: C-contiguous rows of the QP)."""
        program.add(kernels.HEADING_ROWS, cos_part=self._cos_part, sin_part=self._sin_part, q=kin.q,
                    heading=self._heading, G=G, rows=G.shape[0], nq=len(kin.q), nv=G.shape[1], x=self._x, y=self._y)
