"""No-lateral-slip rows of a nonholonomic base."""

from __future__ import annotations

import numpy as np

from ..errors import InvalidInputError
from ..kinematics import Kinematics
from ..robot import Robot
from .constraint import Constraint, ConstraintRows


class NonholonomicBase(Constraint):
    """The wheels of a unicycle / differential-drive / synchro-drive base do not slip sideways::

        -sin(heading) xdot + cos(heading) ydot = 0          (one equality row)

    Equivalent to ``v = S(q) u`` with :meth:`Robot.input_map`; a controller built with
    ``reduced=True`` solves over ``u`` directly and skips this constraint (it holds by
    construction there).
    """

    n_equalities = 1
    satisfied_by_input_map = True

    def bind(self, robot: Robot) -> None:
        if not robot.base.is_nonholonomic:
            raise InvalidInputError(f"{self.name}: robot '{robot.name}' has a {robot.base.kind.value} base, "
                                    "not a nonholonomic one")
        self._x, self._y, self._heading = robot.base.indices

    def compute(self, kin: Kinematics, dt: float, rows: ConstraintRows) -> None:
        angle = kin.q[self._heading]
        rows.A[0, self._x] = -np.sin(angle)
        rows.A[0, self._y] = np.cos(angle)

    def row_labels(self) -> list[str]:
        return ["no lateral slip"]
