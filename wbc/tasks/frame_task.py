"""Full 6-D pose task of one frame."""

from __future__ import annotations

from typing import Any

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike, NDArray

from ..core.settings import Cost, Operand
from ..core.validation import as_gain, as_pose, as_speed_limit, as_vector
from ..model.kinematics import Kinematics, frame_in_joint
from ..model.robot import Robot
from ..runtime import kernels
from ..runtime.native_entry import unchecked_entry
from ..runtime.program import TickProgram
from .error_task import ErrorTask, ErrorTaskData
from .task import _norm

_POSE_OK, _POSE_SHAPE = kernels.POSE_OK, kernels.POSE_SHAPE
_FLOAT64 = np.dtype(np.float64)


def _set_pose(pose: NDArray[np.float64], settings: NDArray[np.float64]) -> int:
    """:func:`wbc.runtime.kernels.set_frame_pose` through its compiled entry, without numba's type
    check (``pose`` is checked to be a 2-D float64 array first; any strides, read-only too): this
    function replaces itself by that entry on its first call (the kernels load lazily)."""
    global _set_pose
    _set_pose = unchecked_entry(kernels.set_frame_pose)
    return _set_pose(pose, settings)


class FrameTask(ErrorTask):
    """Drive a frame to a target pose.

    Error, world-aligned at the frame origin (the axes of :meth:`Robot.frame_jacobian`)::

        e = ( p* - p ,  log3(R* R^T) )      # [m], [rad]

    Both parts are exact: with ``v = J^+ k e`` the position moves straight and the
    orientation rotates along the geodesic to the target. Rows of the objective::

        W ( J v - gain/dt * e - xi* ),   W = diag(sqrt(position_cost) I3, sqrt(orientation_cost) I3)

    ``xi*`` is an optional feed-forward twist of a moving target (world-aligned,
    (linear [m/s]; angular [rad/s])) given to :meth:`set_target`. The feedback part
    ``gain/dt * e`` can be bounded: its linear part to ``max_speed`` [m/s] and its angular
    part to ``max_angular_speed`` [rad/s] (each scaled down in norm, direction kept).

    An :class:`~wbc.tasks.error_task.ErrorTask`: its data says the error and the Jacobian, the
    rows above are the generic ones; its compiled kernel computes the same rows in the native
    tick (the opt-in speed-up of that contract, checked against it by the tests).

    Args:
        frame: frame name in the robot model.
        position_cost: [cost] / [m]^2 weight of the position rows, scalar or per axis.
        orientation_cost: [cost] / [rad]^2 weight of the orientation rows, scalar or per axis.
        gain: fraction of the error removed per tick, in (0, 1].
        max_speed: [m/s] bound on the linear feedback velocity; ``None`` = unbounded.
        max_angular_speed: [rad/s] bound on the angular feedback velocity; ``None`` = unbounded.
    """

    needs_target = True

    #: settings that may be changed between ticks (validated; they live in the compiled operands)
    gain = Operand("_settings", kernels.FRAME_GAIN, as_gain)
    max_speed = Operand("_settings", kernels.FRAME_MAX_SPEED, as_speed_limit)
    max_angular_speed = Operand("_settings", kernels.FRAME_MAX_ANGULAR_SPEED, as_speed_limit)
    position_cost = Cost("_weights", slice(0, 3))
    orientation_cost = Cost("_weights", slice(3, 6))

    speed_limits = ((slice(0, 3), "max_speed"), (slice(3, 6), "max_angular_speed"))

    def __init__(self, frame: str, position_cost: ArrayLike = 1.0, orientation_cost: ArrayLike = 1.0, gain: float = 1.0,
                 max_speed: float | None = None, max_angular_speed: float | None = None,
                 name: str | None = None) -> None:
        self.frame = frame
        # every setting the compiled kernel reads, in one vector (layout: wbc.runtime.kernels.FRAME_*),
        # shared by the controllers using the task
        self._settings = np.zeros(kernels.FRAME_SETTINGS)
        self._target_rotation = self._settings[kernels.FRAME_TARGET_ROTATION].reshape(3, 3)
        self._target_position = self._settings[kernels.FRAME_TARGET_POSITION]
        self._weights = self._settings[kernels.FRAME_WEIGHTS]
        self._feedforward = self._settings[kernels.FRAME_FEEDFORWARD]
        super().__init__(6, gain, name)
        self.position_cost, self.orientation_cost = position_cost, orientation_cost
        self._target_rotation[...] = np.eye(3)
        self.max_speed, self.max_angular_speed = max_speed, max_angular_speed

    @property
    def _has_target(self) -> bool:
        """Whether a target was set: the flag the compiled setters write into the settings
        (``FRAME_HAS_TARGET``), so that ``set_target`` writes no attribute and reads none."""
        return bool(self._settings[kernels.FRAME_HAS_TARGET])

    @_has_target.setter
    def _has_target(self, value: bool) -> None:
        self._settings[kernels.FRAME_HAS_TARGET] = 1.0 if value else 0.0

    def default_name(self) -> str:
        return f"FrameTask({self.frame})"

    def set_target(self, pose: ArrayLike, twist: ArrayLike | None = None) -> None:
        """Set the target of the next ticks.

        Args:
            pose: the 4x4 world pose of the frame (a float64 array takes the control loop's fast
                path: one compiled check and copy; a twist is checked first, written after it).
            twist: optional feed-forward twist of a moving target (6, world-aligned at the frame
                origin, (linear [m/s]; angular [rad/s])); None for a fixed target.

        Raises:
            InvalidInputError: ``pose`` is not a 4x4 homogeneous transform (NaN or inf, last row
                not ``[0, 0, 0, 1]``, a block that is not a rotation), or ``twist`` is not 6
                finite numbers. The previous target is then kept.
        """
        if twist is None:
            given: Any = pose  # (its attributes are read inside the try)
            try:  # the control loop's fast path: a 2-D float64 array, checked and copied in one compiled call
                defect = (_set_pose(given, self._settings) if given.dtype is _FLOAT64 and given.ndim == 2
                          else _POSE_SHAPE)
            except (AttributeError, TypeError):  # not an ndarray (the entry unboxes ndarrays only)
                defect = _POSE_SHAPE
            if defect != _POSE_OK:  # convert (a writable copy: e.g. a read-only array), or say what is wrong
                kernels.set_frame_pose(np.array(as_pose(pose, "target pose")), self._settings)
        else:
            feedforward = as_vector(twist, 6, "target twist")  # checked before the pose is written
            FrameTask.set_target(self, pose)  # the pose's checks and a zero twist (not a subclass's override)
            self._feedforward[...] = feedforward

    def set_target_from_configuration(self, robot: Robot, q: ArrayLike) -> None:
        """Hold the frame at the pose it has in configuration ``q``."""
        self.set_target(robot.frame_pose(q, self.frame))

    @property
    def target(self) -> NDArray[np.float64]:
        pose = np.eye(4)
        pose[:3, :3], pose[:3, 3] = self._target_rotation, self._target_position
        return pose

    def bind(self, robot: Robot) -> FrameTaskData:
        return FrameTaskData(self, robot)

    def __repr__(self) -> str:
        return (f"FrameTask(frame={self.frame!r}, position_cost={self.position_cost.tolist()}, "
                f"orientation_cost={self.orientation_cost.tolist()}, gain={self.gain}, "
                f"max_speed={self.max_speed}, max_angular_speed={self.max_angular_speed})")


class FrameTaskData(ErrorTaskData):
    """A :class:`FrameTask` in one controller: its frame resolved against the robot, and the
    error ``e = (position; orientation)`` of the last tick."""

    task: FrameTask

    def __init__(self, task: FrameTask, robot: Robot) -> None:
        super().__init__(task, robot)
        self._frame_id = robot.frame_id(task.frame)
        self._keys = (f"{self.name}.position", f"{self.name}.orientation")
        self._joint_id, local, self._support = frame_in_joint(robot.model, self._frame_id)
        self._frame = np.zeros(kernels.FRAME_DATA)  # placement in the joint, then kernel scratch
        self._frame[kernels.FRAME_LOCAL] = local
        self._position_error, self._orientation_error = self.error[:3], self.error[3:]
        kernels.prepare("set_frame_pose", "pose_defect")  # set_target's, in the control loop

    def compute_error_and_jacobian(self, kin: Kinematics, error: np.ndarray, jacobian: np.ndarray) -> None:
        """``e = (p* - p, log3(R* R^T))`` and the frame's world-aligned Jacobian (Pinocchio's)."""
        placement, task = kin.frame_placement(self._frame_id), self.task
        np.subtract(task._target_position, placement.translation, out=error[:3])
        error[3:] = pin.log3(task._target_rotation @ placement.rotation.T)
        jacobian[...] = kin.frame_jacobian(self._frame_id)

    def add_ops(self, program: TickProgram, kin: Kinematics, stack_t: np.ndarray, start: int) -> bool:
        joint_jacobians, rotation, translation = kin.joint_views(self._joint_id)
        nv = stack_t.shape[0] - 1
        # J (6 x nv) and R are F-contiguous in Pinocchio: their transposes are C-contiguous views
        program.add(kernels.FRAME_TASK, joint_jacobians_t=joint_jacobians.T, rotation_t=rotation.T,
                    translation=translation, support=self._support, settings=self.task._settings, frame=self._frame,
                    error=self.error, stack=stack_t, start=start, nv=nv, rows=stack_t.shape[1],
                    feedforward=self.feedforward)
        return True

    def report(self, v: np.ndarray, errors: dict[str, float]) -> None:
        errors[self._keys[0]] = _norm(self._position_error)
        errors[self._keys[1]] = _norm(self._orientation_error)
