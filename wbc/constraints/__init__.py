"""Constraints: hard limits of the control QP."""

from .constraint import Constraint, ConstraintRows
from .joint_position_limits import JointPositionLimits
from .joint_velocity_limits import JointVelocityLimits
from .nonholonomic_base import NonholonomicBase
from .wheel_speed_limits import MecanumWheelLimits, WheelSpeedLimits

__all__ = ["Constraint", "ConstraintRows", "JointPositionLimits", "JointVelocityLimits",
           "MecanumWheelLimits", "NonholonomicBase", "WheelSpeedLimits"]
