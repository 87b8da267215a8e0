"""Tasks: weighted least-squares terms of the control QP."""

from .axis_align_task import AxisAlignTask
from .base_velocity_task import BaseVelocityTask
from .com_task import CoMTask
from .damping_task import DampingTask
from .frame_task import FrameTask
from .kinetic_energy import KineticEnergyRegularization
from .linear_cost import LinearCost
from .linear_task import LinearTask
from .look_at_task import LookAtTask
from .manipulability_gradient import ManipulabilityGradient
from .manipulability_task import ManipulabilityTask
from .position_task import PositionTask
from .posture_task import PostureTask
from .relative_frame_task import RelativeFrameTask
from .steering_task import SteeringTask
from .task import Task

__all__ = ["Task", "FrameTask", "PositionTask", "PostureTask", "BaseVelocityTask", "SteeringTask",
           "ManipulabilityTask", "RelativeFrameTask", "CoMTask", "DampingTask", "KineticEnergyRegularization",
           "LookAtTask", "AxisAlignTask", "LinearTask",
           "LinearCost", "ManipulabilityGradient"]
