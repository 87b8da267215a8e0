"""Constraints: hard limits of the control QP."""

from .acceleration_limits import AccelerationLimits
from .constraint import Constraint, ConstraintRows
from .dof_freezing import DofFreezing
from .joint_position_limits import JointPositionLimits
from .joint_velocity_limits import JointVelocityLimits
from .linear_constraint import LinearConstraint
from .manipulability_barrier import ManipulabilityBarrier
from .mimic_joints import MimicJoints
from .nonholonomic_base import NonholonomicBase
from .support_polygon import SupportPolygon
from .wheel_speed_limits import MecanumWheelLimits, WheelSpeedLimits

__all__ = ["AccelerationLimits", "Constraint", "ConstraintRows", "JointPositionLimits", "JointVelocityLimits",
           "ManipulabilityBarrier", "MecanumWheelLimits", "NonholonomicBase", "WheelSpeedLimits", "SupportPolygon",
           "DofFreezing", "MimicJoints", "LinearConstraint"]
