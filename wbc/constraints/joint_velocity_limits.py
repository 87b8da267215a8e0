"""Joint (and base) speed limits."""

from __future__ import annotations

import numpy as np

from ..model.kinematics import Kinematics
from ..model.robot import Robot
from ..runtime.program import TickProgram
from .constraint import Constraint, ConstraintData, ConstraintRows
from .heading_rows import HeadingRows


class JointVelocityLimits(Constraint):
    """``|v_i| <= velocity_limit_i`` for every coordinate with a finite limit.

    For a mobile base the linear limit holds in the **base frame** (the platform's
    own speed limits do not rotate with the world): four rows
    ``|c xdot + s ydot| <= v_max`` and ``|-s xdot + c ydot| <= v_max`` with
    ``(c, s) = (cos yaw, sin yaw)``; the yaw rate is a plain bound.
    """

    def bind(self, robot: Robot) -> JointVelocityLimitsData:
        return JointVelocityLimitsData(self, robot)


class JointVelocityLimitsData(ConstraintData):
    """:class:`JointVelocityLimits` in one controller: the robot's limits and base rows."""

    has_bounds = True

    def __init__(self, limits: JointVelocityLimits, robot: Robot) -> None:
        super().__init__(limits)
        limit = robot.velocity_limit.copy()
        base = robot.base
        self._base_rows = base.is_mobile and np.isfinite(base.max_linear_speed)
        if base.is_mobile:
            self._x, self._y, self._yaw = base.indices
            limit[[self._x, self._y]] = np.inf  # handled by the base-frame rows
            self._linear_limit = base.max_linear_speed
        self.n_inequalities = 4 if self._base_rows else 0
        self._limit = limit
        if self._base_rows:
            # rows +-(c xdot + s ydot), +-(-s xdot + c ydot): the (cos; sin) parts of (x, y)
            cos_part = np.array([[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0], [0.0, -1.0]])
            sin_part = np.array([[0.0, 1.0], [0.0, -1.0], [-1.0, 0.0], [1.0, 0.0]])
            self._heading_rows = HeadingRows(cos_part, sin_part, self._yaw, self._x, self._y)

    def write_static(self, rows: ConstraintRows) -> None:
        np.negative(self._limit, out=rows.lower)
        rows.upper[...] = self._limit
        rows.h.fill(self._linear_limit if self._base_rows else 0.0)

    def add_ops(self, program: TickProgram, kin: Kinematics, rows: ConstraintRows) -> bool:
        if self._base_rows:
            self._heading_rows.add_op(program, kin, rows.G)
        return True

    def compute(self, kin: Kinematics, dt: float, rows: ConstraintRows) -> None:
        if self._base_rows:
            self._heading_rows.write(kin.q, rows.G)

    def row_labels(self) -> list[str]:
        return ["base v_x upper", "base v_x lower", "base v_y upper", "base v_y lower"][: self.n_inequalities]
