"""No-lateral-slip rows of a nonholonomic base."""

from __future__ import annotations

from ..core.errors import InvalidInputError
from ..model.kinematics import Kinematics
from ..model.robot import Robot
from ..runtime.program import TickProgram
from .constraint import Constraint, ConstraintData, ConstraintRows
from .heading_rows import HeadingRows


class NonholonomicBase(Constraint):
    """The wheels of a unicycle / differential-drive / synchro-drive base do not slip sideways::

        -sin(heading) xdot + cos(heading) ydot = 0          (one equality row)

    In general the base's no-slip rows ``N B(heading) v = 0`` (:meth:`MobileBase.no_slip_rows`).
    Equivalent to ``v = S(q) u`` with :meth:`Robot.input_map`; a controller built with
    ``reduced=True`` solves over ``u`` directly and skips this constraint (it holds by
    construction there).
    """

    satisfied_by_input_map = True

    def bind(self, robot: Robot) -> NonholonomicBaseData:
        if not robot.base.is_nonholonomic:
            raise InvalidInputError(f"{self.name}: robot '{robot.name}' has a {robot.base.name} base, "
                                    "not a nonholonomic one")
        return NonholonomicBaseData(self, robot)


class NonholonomicBaseData(ConstraintData):
    """:class:`NonholonomicBase` in one controller: the base's no-slip rows."""

    python_kernels = ("heading_rows",)  # HeadingRows.write's

    def __init__(self, constraint: NonholonomicBase, robot: Robot) -> None:
        super().__init__(constraint)
        self._no_slip = robot.base.no_slip_rows()
        self.n_equalities = self._no_slip.count
        self._heading_rows = HeadingRows.of_twist(self._no_slip, robot.base.indices)

    def write_static(self, rows: ConstraintRows) -> None:
        self._heading_rows.write_heading_column(rows.A)

    def add_ops(self, program: TickProgram, kin: Kinematics, rows: ConstraintRows) -> bool:
        self._heading_rows.add_op(program, kin, rows.A)
        return True

    def compute(self, kin: Kinematics, dt: float, rows: ConstraintRows) -> None:
        self._heading_rows.write(kin.q, rows.A)

    def row_labels(self) -> list[str]:
        return list(self._no_slip.labels)
