"""Tasks: weighted least-squares terms of the control QP."""

from .base_velocity_task import BaseVelocityTask
from .com_task import CoMTask
from .frame_task import FrameTask
from .manipulability_task import ManipulabilityTask
from .position_task import PositionTask
from .posture_task import PostureTask
from .relative_frame_task import RelativeFrameTask
from .steering_task import SteeringTask
from .task import Task

__all__ = ["Task", "FrameTask", "PositionTask", "PostureTask", "BaseVelocityTask", "SteeringTask",
           "ManipulabilityTask", "RelativeFrameTask", "CoMTask"]
