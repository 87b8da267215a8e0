"""Wheel speed limits of a wheeled base."""

from __future__ import annotations

import numpy as np

from ..core.errors import InvalidInputError
from ..core.validation import as_positive
from ..model.bases.interface import BaseKind, TwistRows
from ..model.kinematics import Kinematics
from ..model.robot import Robot
from ..runtime.program import TickProgram
from .constraint import Constraint, ConstraintData, ConstraintRows
from .heading_rows import HeadingRows


class WheelSpeedLimits(Constraint):
    """``|u_i| <= u_max`` for the wheel speeds ``u = H0 B(heading) v`` of the base.

    ``B`` rotates the world base rates into the base-frame twist ``(v_x, v_y, omega)``
    (see :mod:`wbc.model.mobile_base`) and ``H0`` is the wheel model's inverse kinematics
    (:meth:`MecanumWheels.inverse_matrix`, :meth:`DifferentialWheels.inverse_matrix`).
    Each wheel gives two rows, ``+-H0_i B v <= u_max``.

    Args:
        max_speed: wheel speed limit [rad/s]; default: the model's ``[base.wheels] max_speed``.
    """

    required_kind: BaseKind | None = None

    def __init__(self, max_speed: float | None = None, name: str | None = None) -> None:
        super().__init__(name)
        self._max_speed = None if max_speed is None else as_positive(max_speed, "max_speed")

    def bind(self, robot: Robot) -> WheelSpeedLimitsData:
        base = robot.base
        if base.wheels is None or (self.required_kind is not None and base.kind is not self.required_kind):
            wanted = self.required_kind.value if self.required_kind else "wheeled"
            raise InvalidInputError(f"{self.name} needs a {wanted} base with wheel geometry; "
                                    f"robot '{robot.name}' has a {base.name} base")
        return WheelSpeedLimitsData(self, robot)

    def __repr__(self) -> str:
        return f"{type(self).__name__}(max_speed={self._max_speed})"


class WheelSpeedLimitsData(ConstraintData):
    """:class:`WheelSpeedLimits` in one controller: the robot's wheel model and limit."""

    python_kernels = ("heading_rows",)  # HeadingRows.write's

    def __init__(self, limits: WheelSpeedLimits, robot: Robot) -> None:
        super().__init__(limits)
        base, wheels = robot.base, robot.base.wheels
        assert wheels is not None  # bind() refuses a base without wheel geometry
        self._H0 = wheels.inverse_matrix()
        self.max_speed = limits._max_speed if limits._max_speed is not None else wheels.max_speed
        if not np.isfinite(self.max_speed):
            raise InvalidInputError(f"{self.name}: no wheel speed limit given or declared by the model")
        self.n_wheels = self._H0.shape[0]
        self.n_inequalities = 2 * self.n_wheels
        # the rows +-H0 t on the base-frame twist t = B(heading) v: forward, then backward
        self._heading_rows = HeadingRows.of_twist(TwistRows(np.vstack([self._H0, -self._H0]), self.max_speed,
                                                            tuple(self.row_labels())), base.indices)

    def write_static(self, rows: ConstraintRows) -> None:
        rows.h.fill(self.max_speed)
        self._heading_rows.write_heading_column(rows.G)

    def add_ops(self, program: TickProgram, kin: Kinematics, rows: ConstraintRows) -> bool:
        self._heading_rows.add_op(program, kin, rows.G)
        return True

    def compute(self, kin: Kinematics, dt: float, rows: ConstraintRows) -> None:
        self._heading_rows.write(kin.q, rows.G)

    def row_labels(self) -> list[str]:
        return [f"wheel {i} {side}" for side in ("forward", "backward") for i in range(self.n_wheels)]


class MecanumWheelLimits(WheelSpeedLimits):
    """:class:`WheelSpeedLimits` for the four Swedish wheels of a mecanum base (the youBot)."""

    required_kind = BaseKind.MECANUM
