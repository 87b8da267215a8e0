"""No-lateral-slip rows of a nonholonomic base."""

from __future__ import annotations

import numpy as np

from ..core.errors import InvalidInputError
from ..model.kinematics import Kinematics
from ..model.robot import Robot
from ..runtime.program import TickProgram
from .constraint import Constraint, ConstraintData, ConstraintRows
from .heading_rows import HeadingRows


class NonholonomicBase(Constraint):
    """The wheels of a unicycle / differential-drive / synchro-drive base do not slip sideways::

        -sin(heading) xdot + cos(heading) ydot = 0          (one equality row)

    Equivalent to ``v = S(q) u`` with :meth:`Robot.input_map`; a controller built with
    ``reduced=True`` solves over ``u`` directly and skips this constraint (it holds by
    construction there).
    """

    satisfied_by_input_map = True

    def bind(self, robot: Robot) -> NonholonomicBaseData:
        if not robot.base.is_nonholonomic:
            raise InvalidInputError(f"{self.name}: robot '{robot.name}' has a {robot.base.kind.value} base, "
                                    "not a nonholonomic one")
        return NonholonomicBaseData(self, robot)


class NonholonomicBaseData(ConstraintData):
    """:class:`NonholonomicBase` in one controller: the robot's base coordinates."""

    n_equalities = 1

    def __init__(self, constraint: NonholonomicBase, robot: Robot) -> None:
        super().__init__(constraint)
        x, y, heading = robot.base.indices
        # the row (-sin, cos) on (xdot, ydot): cos (0, 1) + sin (-1, 0)
        self._heading_rows = HeadingRows(np.array([[0.0, 1.0]]), np.array([[-1.0, 0.0]]), heading, x, y)

    def add_ops(self, program: TickProgram, kin: Kinematics, rows: ConstraintRows) -> bool:
        self._heading_rows.add_op(program, kin, rows.A)
        return True

    def compute(self, kin: Kinematics, dt: float, rows: ConstraintRows) -> None:
        self._heading_rows.write(kin.q, rows.A)

    def row_labels(self) -> list[str]:
        return ["no lateral slip"]
