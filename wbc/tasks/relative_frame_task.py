"""6-D pose task of one frame relative to another (moving) frame."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike, NDArray

from ..core.errors import InvalidInputError
from ..core.settings import Cost
from ..core.validation import as_pose, as_vector
from ..model.kinematics import Kinematics
from ..model.robot import Robot
from .error_task import ErrorTask, ErrorTaskData
from .task import _norm


class RelativeFrameTask(ErrorTask):
    """Drive the pose of ``frame`` expressed in ``root`` to a target pose given in ``root``
    (a gripper relative to the platform, or to another moving frame).

    With world placements ``(R_f, p_f)`` of the frame and ``(R_r, p_r)`` of the root, the
    relative pose is ``R = R_r^T R_f``, ``p = R_r^T (p_f - p_r)``; the error, root-aligned at
    the frame origin (FrameTask's error with the root for the world)::

        e = ( p* - p ,  log3(R* R^T) )      # [m], [rad]

    Its Jacobian ``J_rel`` (``de/dt = -J_rel v`` for a fixed target) follows from the
    world-aligned frame Jacobians ``J_f``, ``J_r`` (rows (linear; angular), at each frame's
    origin, :meth:`Robot.frame_jacobian`) and ``d = p_f - p_r``::

        dp/dt = R_r^T (v_f - v_r - w_r x d),    w_rel = R_r^T (w_f - w_r)   (dR/dt = [w_rel]x R)

        J_rel = diag(R_r^T, R_r^T) (J_f - [[I, -[d]x], [0, I]] J_r)

    i.e. the root's twist moved to the frame origin, subtracted, and rotated into the root's
    axes. Rows ``W (J_rel v - gain/dt e - xi*)`` (:class:`~wbc.tasks.error_task.ErrorTask`),
    ``W = diag(sqrt(position_cost) I3, sqrt(orientation_cost) I3)``, ``xi*`` an optional
    feed-forward twist of the target (root-aligned, (linear [m/s]; angular [rad/s])).

    Args:
        frame: the frame to drive (name in the robot model).
        root: the frame whose placement the target is given in (name; may move).
        position_cost: [cost] / [m]^2 weight of the position rows, scalar or per axis.
        orientation_cost: [cost] / [rad]^2 weight of the orientation rows, scalar or per axis.
        gain: fraction of the error removed per tick, in (0, 1].
    """

    needs_target = True

    position_cost = Cost("_weights", slice(0, 3))
    orientation_cost = Cost("_weights", slice(3, 6))

    def __init__(self, frame: str, root: str, position_cost: ArrayLike = 1.0, orientation_cost: ArrayLike = 1.0,
                 gain: float = 1.0, name: str | None = None) -> None:
        if frame == root:
            raise InvalidInputError(f"RelativeFrameTask: frame and root are both {frame!r}; the pose of a frame "
                                    "in itself cannot move (use FrameTask for a world pose)")
        self.frame, self.root = frame, root
        super().__init__(6, gain, name)
        self.position_cost, self.orientation_cost = position_cost, orientation_cost
        self._target = np.eye(4)  # T* in the root
        self._has_target = False

    def default_name(self) -> str:
        return f"RelativeFrameTask({self.frame} in {self.root})"

    def set_target(self, pose: ArrayLike, twist: ArrayLike | None = None) -> None:
        """Set the target pose of the frame in the root (4x4) and optionally its feed-forward
        twist (6, root-aligned at the frame origin, (linear [m/s]; angular [rad/s])).

        Raises:
            InvalidInputError: ``pose`` is not a 4x4 homogeneous transform, or ``twist`` is not
                6 finite numbers; the previous target is then kept.
        """
        pose = as_pose(pose, "target pose")
        twist = np.zeros(6) if twist is None else as_vector(twist, 6, "target twist")
        self._target[...], self._feedforward[...] = pose, twist
        if not self._has_target:
            self._has_target = True

    def set_target_from_configuration(self, robot: Robot, q: ArrayLike) -> None:
        """Hold the frame at the pose in the root it has in configuration ``q``."""
        root = robot.frame_pose(q, self.root)
        self.set_target(np.linalg.solve(root, robot.frame_pose(q, self.frame)))

    @property
    def target(self) -> NDArray[np.float64]:
        return self._target.copy()

    def bind(self, robot: Robot) -> RelativeFrameTaskData:
        return RelativeFrameTaskData(self, robot)

    def __repr__(self) -> str:
        return (f"RelativeFrameTask(frame={self.frame!r}, root={self.root!r}, "
                f"position_cost={self.position_cost.tolist()}, orientation_cost={self.orientation_cost.tolist()}, "
                f"gain={self.gain})")


class RelativeFrameTaskData(ErrorTaskData):
    """A :class:`RelativeFrameTask` in one controller: both frames resolved against the robot."""

    task: RelativeFrameTask

    def __init__(self, task: RelativeFrameTask, robot: Robot) -> None:
        super().__init__(task, robot)
        self._frame_id, self._root_id = robot.frame_id(task.frame), robot.frame_id(task.root)
        self._keys = (f"{self.name}.position", f"{self.name}.orientation")

    def compute_error_and_jacobian(self, kin: Kinematics, error: np.ndarray, jacobian: np.ndarray) -> None:
        frame, root = kin.frame_placement(self._frame_id), kin.frame_placement(self._root_id)
        root_rotation_t = root.rotation.T
        offset = frame.translation - root.translation  # d = p_f - p_r
        rotation = root_rotation_t @ frame.rotation
        target = self.task._target
        error[:3] = target[:3, 3] - root_rotation_t @ offset
        error[3:] = pin.log3(target[:3, :3] @ rotation.T)
        frame_jacobian, root_jacobian = kin.frame_jacobian(self._frame_id), kin.frame_jacobian(self._root_id)
        difference = frame_jacobian - root_jacobian
        difference[:3] += np.cross(offset, root_jacobian[3:], axis=0)  # + [d]x J_r,ang: v_r moved to p_f
        np.matmul(root_rotation_t, difference[:3], out=jacobian[:3])
        np.matmul(root_rotation_t, difference[3:], out=jacobian[3:])

    def report(self, v: np.ndarray, errors: dict[str, float]) -> None:
        errors[self._keys[0]] = _norm(self.error[:3])
        errors[self._keys[1]] = _norm(self.error[3:])
