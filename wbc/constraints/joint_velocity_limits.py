"""Joint (and base) speed limits."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ..model.bases import TwistRows
from ..model.kinematics import Kinematics
from ..model.robot import Robot
from ..runtime.program import TickProgram
from .constraint import Constraint, ConstraintData, ConstraintRows
from .heading_rows import HeadingRows


class JointVelocityLimits(Constraint):
    """``|v_i| <= velocity_limit_i`` for every coordinate with a finite limit.

    For a mobile base the linear limit holds in the **base frame** (the platform's
    own speed limits do not rotate with the world): the base's speed rows
    (:meth:`MobileBase.speed_rows`; for the shipped kinds four rows
    ``|c xdot + s ydot| <= v_max`` and ``|-s xdot + c ydot| <= v_max`` with
    ``(c, s) = (cos yaw, sin yaw)``); the yaw rate is a plain bound.
    """

    def bind(self, robot: Robot) -> JointVelocityLimitsData:
        return JointVelocityLimitsData(self, robot)


class JointVelocityLimitsData(ConstraintData):
    """:class:`JointVelocityLimits` in one controller: the robot's limits and its base's speed
    rows (:meth:`MobileBase.speed_rows`)."""

    python_kernels = ("heading_rows",)  # HeadingRows.write's

    has_bounds = True

    def __init__(self, limits: JointVelocityLimits, robot: Robot) -> None:
        super().__init__(limits)
        limit = robot.velocity_limit.copy()
        base = robot.base
        self._base: tuple[int, int] | None = None  #: the base's xdot, ydot columns
        if base.is_mobile:
            x, y, _ = base.indices
            limit[[x, y]] = np.inf  # the coupled base rates: bounded by the base-frame rows
            self._base = (x, y)
        self._limit = limit
        self._speed_rows = base.speed_rows()
        self.n_inequalities = self._speed_rows.count
        self._heading_rows = HeadingRows.of_twist(self._speed_rows, base.indices) if self.n_inequalities else None

    def write_static(self, rows: ConstraintRows) -> None:
        np.negative(self._limit, out=rows.lower)
        rows.upper[...] = self._limit
        rows.h[...] = self._speed_rows.bound
        if self._heading_rows is not None:
            self._heading_rows.write_heading_column(rows.G)

    def bound_speed(self, speed: NDArray[np.float64]) -> None:
        """The limits, and for a base whose speed rows bound ``|v_x| <= a`` and ``|v_y| <= b`` in
        its frame, ``|xdot|, |ydot| <= |(xdot, ydot)| = |(v_x, v_y)| <= sqrt(a^2 + b^2)``."""
        np.minimum(speed, self._limit, out=speed)
        if self._base is None:
            return
        rows = self._speed_rows
        a = max(_bound_along(rows, (1.0, 0.0, 0.0)), _bound_along(rows, (-1.0, 0.0, 0.0)))
        b = max(_bound_along(rows, (0.0, 1.0, 0.0)), _bound_along(rows, (0.0, -1.0, 0.0)))
        planar = float(np.hypot(a, b))  # (inf when a side is unbounded)
        for k in self._base:
            speed[k] = min(speed[k], planar)

    def add_ops(self, program: TickProgram, kin: Kinematics, rows: ConstraintRows) -> bool:
        if self._heading_rows is not None:
            self._heading_rows.add_op(program, kin, rows.G)
        return True

    def compute(self, kin: Kinematics, dt: float, rows: ConstraintRows) -> None:
        if self._heading_rows is not None:
            self._heading_rows.write(kin.q, rows.G)

    def row_labels(self) -> list[str]:
        return list(self._speed_rows.labels)


def _bound_along(rows: TwistRows, direction: tuple[float, float, float]) -> float:
    """The tightest ``b`` of the rows ``direction . t <= b`` among ``rows`` (inf: none)."""
    return min((float(b) for row, b in zip(rows.matrix, rows.bound, strict=True)
                if np.array_equal(row, direction)), default=np.inf)
