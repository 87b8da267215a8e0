"""Constraint rows on the planar base rates that turn with the base heading."""

from __future__ import annotations

import numpy as np

from ..model.bases.interface import TwistRows
from ..model.kinematics import Kinematics
from ..runtime import kernels
from ..runtime.program import TickProgram

#: ``[[0, 1], [-1, 0]]``: the ``sin`` part of ``M_xy R(heading)^T``
_QUARTER_TURN = np.array([[0.0, 1.0], [-1.0, 0.0]])


class HeadingRows:
    """Columns ``(x, y)`` of some rows ``G`` of the form ``cos(heading) A + sin(heading) B``.

    Base-frame limits (speed, wheel speeds) act on ``R(heading)^T (xdot, ydot)``, so their
    rows are linear in ``(cos, sin)`` (:func:`wbc.runtime.kernels.heading_rows`).

    Args:
        cos_part: ``A``, (rows, 2): the rows' ``(x, y)`` columns at heading 0.
        sin_part: ``B``, (rows, 2): the rows' ``(x, y)`` columns at heading pi/2.
        heading: index of the heading in ``q``; ``x``, ``y``: velocity indices of the base rates.
        heading_column: the rows' column of the heading rate, constant (written by
            :meth:`write_heading_column`); None: left as it is.
    """

    def __init__(self, cos_part: np.ndarray, sin_part: np.ndarray, heading: int, x: int, y: int,
                 heading_column: np.ndarray | None = None) -> None:
        self._cos_part = np.ascontiguousarray(cos_part, dtype=np.float64)
        self._sin_part = np.ascontiguousarray(sin_part, dtype=np.float64)
        self._heading, self._x, self._y = heading, x, y
        self._heading_column = None if heading_column is None else np.array(heading_column, dtype=np.float64)

    @classmethod
    def of_twist(cls, rows: TwistRows, indices: tuple[int, int, int]) -> HeadingRows:
        """Rows ``M t`` on the base-frame twist ``t = (v_x, v_y, omega)`` (a base's
        :class:`~wbc.model.bases.interface.TwistRows`) as rows on ``v``: with
        ``(v_x, v_y) = R(heading)^T (xdot, ydot)`` their ``(x, y)`` columns are
        ``M_xy R^T = cos M_xy + sin M_xy [[0, 1], [-1, 0]]``, their heading column ``M_omega``."""
        x, y, heading = indices
        planar = rows.matrix[:, :2]
        return cls(planar, planar @ _QUARTER_TURN, heading, x, y, heading_column=rows.matrix[:, 2])

    def write_heading_column(self, G: np.ndarray) -> None:
        """Write the constant heading-rate column of ``G`` (once: the program leaves it alone)."""
        if self._heading_column is not None:
            G[:, self._heading] = self._heading_column

    def write(self, q: np.ndarray, G: np.ndarray) -> None:
        """Write the ``(x, y)`` columns of ``G`` for the heading in ``q``."""
        kernels.heading_rows(self._cos_part, self._sin_part, q, self._heading, G, self._x, self._y)

    def add_op(self, program: TickProgram, kin: Kinematics, G: np.ndarray) -> None:
        """The same as a compiled op (``G``: C-contiguous rows of the QP)."""
        program.add(kernels.HEADING_ROWS, cos_part=self._cos_part, sin_part=self._sin_part, q=kin.q,
                    heading=self._heading, G=G, rows=G.shape[0], nq=len(kin.q), nv=G.shape[1], x=self._x, y=self._y)
