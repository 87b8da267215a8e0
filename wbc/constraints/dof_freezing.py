"""Freeze some joints: their velocities are held at zero."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from ..model.declared_base import joint_columns
from ..model.kinematics import Kinematics
from ..model.manipulability import check_joint_names
from ..model.robot import Robot
from ..runtime.program import TickProgram
from .constraint import Constraint, ConstraintData, ConstraintRows


class DofFreezing(Constraint):
    """``v_j = 0`` for every velocity coordinate of the named joints (hard bounds): the controller
    moves the other joints only, as if the frozen ones were welded where they are — a broken
    joint, an arm held while the base drives, a subset of a humanoid's joints.

    The bounds hold with every solver and form; a frozen joint outside its position limits stays
    there (the position limits' bounds are soft and yield to these). Freezing a nonholonomic
    base's heading or position holds those rates at zero too (the no-slip row then allows no
    other motion of the base than what is left).

    Args:
        joints: names of the joints to freeze (at least one; all of a multi-DOF joint's coordinates).
    """

    def __init__(self, joints: Sequence[str], name: str | None = None) -> None:
        super().__init__(name)
        self.joints = tuple(check_joint_names(joints))

    def bind(self, robot: Robot) -> DofFreezingData:
        return DofFreezingData(self, robot)

    def __repr__(self) -> str:
        return f"DofFreezing(joints={list(self.joints)!r})"


class DofFreezingData(ConstraintData):
    """:class:`DofFreezing` in one controller: the frozen velocity coordinates of the robot."""

    has_bounds = True

    def __init__(self, freezing: DofFreezing, robot: Robot) -> None:
        super().__init__(freezing)
        self.columns = joint_columns(robot.model, freezing.joints, freezing.name)  #: the frozen coordinates of v

    def write_static(self, rows: ConstraintRows) -> None:
        rows.lower[self.columns] = 0.0
        rows.upper[self.columns] = 0.0

    def bound_speed(self, speed: NDArray[np.float64]) -> None:
        speed[self.columns] = 0.0

    def add_ops(self, program: TickProgram, kin: Kinematics, rows: ConstraintRows) -> bool:
        return True  # static bounds: nothing to do per tick

    def compute(self, kin: Kinematics, dt: float, rows: ConstraintRows) -> None:
        """The bounds are static (:meth:`write_static`)."""
