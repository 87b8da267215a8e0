"""Point an axis of a frame at a world point (a camera at a target)."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.settings import Cost
from ..core.validation import as_vector, direction
from ..model.kinematics import Kinematics
from ..model.robot import Robot
from .axis_error import as_unit_axis, axis_error, skew
from .error_task import ErrorTask, ErrorTaskData

#: [m] a target closer than this to the frame origin gives no direction: the task's rows are zero
MIN_TARGET_DISTANCE = 1e-3


class LookAtTask(ErrorTask):
    """Turn ``axis`` (a direction fixed in ``frame``, e.g. a camera's optical z axis) toward a
    world point ``p*``. The point is given as ``target`` or by :meth:`set_target`.

    With the frame's world placement ``(R, p)``, ``a = R axis`` (unit) and the line of sight
    ``d = (p* - p) / rho``, ``rho = |p* - p|``, the error is the rotation turning ``a`` onto
    ``d`` (:mod:`wbc.tasks.axis_error`)::

        e = theta n,   theta = angle(a, d) [rad],   n = (a x d) / |a x d|     (3 rows, world axes)

    ``e`` is always perpendicular to ``d``: the turn about the line of sight is free (the rows
    have no error along it). The Jacobian is exact and includes the frame's translation
    (the line of sight turns when the frame moves): with the frame Jacobian's linear and
    angular rows ``J_p``, ``J_w`` (world-aligned, :meth:`Robot.frame_jacobian`) and
    ``da = -[a]x J_w v``, ``dd = -(I - d d^T) / rho J_p v``::

        J = E_a [a]x J_w + E_d (I - d d^T) / rho J_p          (de/dt = -J v)

    Rows ``W (J v - gain/dt e)``, ``W = sqrt(cost) I3``
    (:class:`~wbc.tasks.error_task.ErrorTask`). **Degenerate target**: while the target is
    closer than :data:`MIN_TARGET_DISTANCE` (1 mm) to the frame origin there is no direction to
    look along; the error and the rows are then zero (the task asks nothing) until it moves
    away. With the axis pointing exactly away from the target the error is a half turn about
    a fixed axis perpendicular to ``a`` (:mod:`wbc.tasks.axis_error`).

    Args:
        frame: the frame carrying the axis (name in the robot model).
        axis: 3 numbers, the direction in the frame's axes (scaled to unit length; not zero).
        cost: [cost] / [rad]^2 weight of the rows, scalar or per world axis.
        gain: fraction of the error removed per tick, in (0, 1].
        target: the world point [m] to look at (or later, :meth:`set_target`).
    """

    needs_target = True

    cost = Cost("_weights", slice(0, 3))

    def __init__(self, frame: str, axis: ArrayLike = (0.0, 0.0, 1.0), cost: ArrayLike = 1.0, gain: float = 1.0,
                 target: ArrayLike | None = None, name: str | None = None) -> None:
        self.frame = frame
        self.axis = as_unit_axis(axis, "axis")
        super().__init__(3, gain, name)
        self.cost = cost
        self._target = np.zeros(3)
        self._has_target = False
        if target is not None:
            self.set_target(target)

    def default_name(self) -> str:
        return f"LookAtTask({self.frame})"

    def set_target(self, point: ArrayLike) -> None:
        """Look at the world point ``point`` [m] from the next tick on.

        Raises:
            InvalidInputError: ``point`` is not 3 finite numbers (the previous target is kept).
        """
        self._target[:] = as_vector(point, 3, "target point")
        if not self._has_target:
            self._has_target = True

    @property
    def target(self) -> NDArray[np.float64]:
        """The world point looked at [m] (a copy)."""
        return self._target.copy()

    def bind(self, robot: Robot) -> LookAtTaskData:
        return LookAtTaskData(self, robot)

    def __repr__(self) -> str:
        return (f"LookAtTask(frame={self.frame!r}, axis={self.axis.tolist()}, cost={self.cost.tolist()}, "
                f"gain={self.gain})")


class LookAtTaskData(ErrorTaskData):
    """A :class:`LookAtTask` in one controller: its frame resolved against the robot."""

    task: LookAtTask

    def __init__(self, task: LookAtTask, robot: Robot) -> None:
        super().__init__(task, robot)
        self._frame_id = robot.frame_id(task.frame)

    def compute_error_and_jacobian(self, kin: Kinematics, error: np.ndarray, jacobian: np.ndarray) -> None:
        placement = kin.frame_placement(self._frame_id)
        a = placement.rotation @ self.task.axis
        d, rho = direction(self.task._target - placement.translation)  # (a target near 1e308 keeps its direction)
        if d is None or not rho >= MIN_TARGET_DISTANCE:  # no direction to look along: ask nothing
            error[:] = 0.0
            jacobian[...] = 0.0
            return
        e_a, e_d = axis_error(a, d, error)
        frame_jacobian = kin.frame_jacobian(self._frame_id)
        sight_rate = (np.eye(3) - np.outer(d, d)) / rho  # -dd/dp
        np.matmul(e_a @ skew(a), frame_jacobian[3:], out=jacobian)
        jacobian += (e_d @ sight_rate) @ frame_jacobian[:3]
