"""Tasks: weighted least-squares terms of the control QP."""

from .base_velocity_task import BaseVelocityTask
from .frame_task import FrameTask
from .posture_task import PostureTask
from .task import Task

__all__ = ["Task", "FrameTask", "PostureTask", "BaseVelocityTask"]
