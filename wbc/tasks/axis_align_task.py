"""Align an axis of a frame with a world direction (a gripper kept vertical)."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.settings import UniformCost
from ..model.kinematics import Kinematics
from ..model.robot import Robot
from .axis_error import as_unit_axis, axis_error, perpendicular, skew
from .error_task import ErrorTask, ErrorTaskData


class AxisAlignTask(ErrorTask):
    """Turn ``axis`` (a direction fixed in ``frame``) onto the world direction ``target_axis``;
    the rotation about the target axis stays free (e.g. a gripper's z axis kept pointing down
    while it moves and turns about the vertical).

    With ``a = R axis`` (``R`` the frame's world rotation) and unit ``t``, the rotation turning
    ``a`` onto ``t`` (:mod:`wbc.tasks.axis_error`) is ``theta n`` with ``n`` perpendicular to
    ``t``; its two coordinates in a fixed orthonormal basis ``B = (b1, b2)`` of the plane
    perpendicular to ``t`` are the error (2 rows, nothing lost: ``B B^T theta n = theta n``)::

        e = B^T theta n   [rad],     J = B^T E_a [a]x J_w      (de/dt = -J v, da = -[a]x J_w v)

    ``J_w`` the angular rows of the world-aligned frame Jacobian. Rows ``W (J v - gain/dt e)``,
    ``W = sqrt(cost) I2`` (:class:`~wbc.tasks.error_task.ErrorTask`). With ``a`` exactly
    opposite ``t`` the error is a half turn about a fixed axis perpendicular to ``a``.

    Args:
        frame: the frame carrying the axis (name in the robot model).
        axis: 3 numbers, the direction in the frame's axes (scaled to unit length; not zero).
        target_axis: 3 numbers, the world direction (scaled to unit length; not zero);
            :meth:`set_target` changes it.
        cost: [cost] / [rad]^2 weight of both rows (a scalar: the basis is arbitrary).
        gain: fraction of the error removed per tick, in (0, 1].
    """

    cost = UniformCost("_weights")

    def __init__(self, frame: str, axis: ArrayLike = (0.0, 0.0, 1.0), target_axis: ArrayLike = (0.0, 0.0, -1.0),
                 cost: float = 1.0, gain: float = 1.0, name: str | None = None) -> None:
        self.frame = frame
        self.axis = as_unit_axis(axis, "axis")
        super().__init__(2, gain, name)
        self.cost = cost
        self._target_axis = np.zeros(3)
        self._basis = np.zeros((2, 3))  # B^T: rows b1, b2
        self.set_target(target_axis)

    def default_name(self) -> str:
        return f"AxisAlignTask({self.frame})"

    def set_target(self, target_axis: ArrayLike) -> None:
        """Align the axis with the world direction ``target_axis`` (3 numbers, not zero) from the
        next tick on.

        Raises:
            InvalidInputError: not 3 finite numbers, or zero (the previous target is kept).
        """
        t = as_unit_axis(target_axis, "target_axis")
        b1 = perpendicular(t)
        self._target_axis[:], self._basis[0], self._basis[1] = t, b1, np.cross(t, b1)

    @property
    def target_axis(self) -> NDArray[np.float64]:
        """The world direction the axis is aligned with (unit, a copy)."""
        return self._target_axis.copy()

    def bind(self, robot: Robot) -> AxisAlignTaskData:
        return AxisAlignTaskData(self, robot)

    def __repr__(self) -> str:
        return (f"AxisAlignTask(frame={self.frame!r}, axis={self.axis.tolist()}, "
                f"target_axis={self._target_axis.tolist()}, cost={self.cost}, gain={self.gain})")


class AxisAlignTaskData(ErrorTaskData):
    """An :class:`AxisAlignTask` in one controller: its frame resolved against the robot."""

    task: AxisAlignTask

    def __init__(self, task: AxisAlignTask, robot: Robot) -> None:
        super().__init__(task, robot)
        self._frame_id = robot.frame_id(task.frame)
        self._rotation_error = np.zeros(3)  # theta n, world axes

    def compute_error_and_jacobian(self, kin: Kinematics, error: np.ndarray, jacobian: np.ndarray) -> None:
        task = self.task
        a = kin.frame_placement(self._frame_id).rotation @ task.axis
        e_a, _ = axis_error(a, task._target_axis, self._rotation_error)
        np.matmul(task._basis, self._rotation_error, out=error)
        np.matmul(task._basis @ e_a @ skew(a), kin.frame_jacobian(self._frame_id)[3:], out=jacobian)
