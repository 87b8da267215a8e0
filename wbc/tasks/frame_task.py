"""Full 6-D pose task of one frame."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from ..kinematics import Kinematics
from ..robot import Robot
from ..errors import InvalidInputError
from ..validation import as_gain, as_pose, as_positive, as_vector, as_weights
from .task import Task, _norm, _saturate


class FrameTask(Task):
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

    Args:
        frame: frame name in the robot model.
        position_cost: [cost] / [m]^2 weight of the position rows, scalar or per axis.
        orientation_cost: [cost] / [rad]^2 weight of the orientation rows, scalar or per axis.
        gain: fraction of the error removed per tick, in (0, 1].
        max_speed: [m/s] bound on the linear feedback velocity; ``None`` = unbounded.
        max_angular_speed: [rad/s] bound on the angular feedback velocity; ``None`` = unbounded.
    """

    dim = 6

    def __init__(self, frame: str, position_cost=1.0, orientation_cost=1.0, gain: float = 1.0,
                 max_speed: float | None = None, max_angular_speed: float | None = None,
                 name: str | None = None) -> None:
        self.frame = frame
        super().__init__(name)
        self.position_cost = as_weights(position_cost, 3, "position_cost")
        self.orientation_cost = as_weights(orientation_cost, 3, "orientation_cost")
        self.gain = as_gain(gain)
        self.max_speed = np.inf if max_speed is None else as_positive(max_speed, "max_speed")
        self.max_angular_speed = (np.inf if max_angular_speed is None
                                  else as_positive(max_angular_speed, "max_angular_speed"))
        self._weights = np.sqrt(np.concatenate([self.position_cost, self.orientation_cost]))
        self._target_rotation = np.eye(3)
        self._target_position = np.zeros(3)
        self._feedforward = np.zeros(6)
        self._has_target = False
        self._rotation_error = np.zeros((3, 3))
        self.error = np.zeros(6)  #: last error e = (position; orientation), world-aligned
        self._frame_id = -1

    def default_name(self) -> str:
        return f"FrameTask({self.frame})"

    def set_target(self, pose, twist=None) -> None:
        """Set the target world pose (4x4) and optionally its twist (6, world-aligned, linear; angular)."""
        pose = as_pose(pose, "target pose")
        self._target_rotation[...] = pose[:3, :3]
        self._target_position[...] = pose[:3, 3]
        if twist is None:
            self._feedforward.fill(0.0)
        else:
            self._feedforward[...] = as_vector(twist, 6, "target twist")
        self._has_target = True

    def set_target_from_configuration(self, robot: Robot, q) -> None:
        """Hold the frame at the pose it has in configuration ``q``."""
        self.set_target(robot.frame_pose(q, self.frame))

    @property
    def target(self) -> np.ndarray:
        pose = np.eye(4)
        pose[:3, :3], pose[:3, 3] = self._target_rotation, self._target_position
        return pose

    def bind(self, robot: Robot) -> None:
        self._frame_id = robot.frame_id(self.frame)
        self._keys = (f"{self.name}.position", f"{self.name}.orientation")

    def compute(self, kin: Kinematics, dt: float, jacobian: np.ndarray, target: np.ndarray) -> None:
        if not self._has_target:
            raise InvalidInputError(f"{self.name}: no target set; call set_target() before stepping")
        placement = kin.frame_placement(self._frame_id)
        error = self.error
        np.subtract(self._target_position, placement.translation, out=error[:3])
        np.matmul(self._target_rotation, placement.rotation.T, out=self._rotation_error)
        error[3:] = pin.log3(self._rotation_error)
        np.multiply(self._weights[:, None], kin.frame_jacobian(self._frame_id), out=jacobian)
        np.multiply(error, self.gain / dt, out=target)
        _saturate(target[:3], self.max_speed)
        _saturate(target[3:], self.max_angular_speed)
        target += self._feedforward
        target *= self._weights

    def report(self, v: np.ndarray, errors: dict[str, float]) -> None:
        errors[self._keys[0]] = _norm(self.error[:3])
        errors[self._keys[1]] = _norm(self.error[3:])

    def __repr__(self) -> str:
        return (f"FrameTask(frame={self.frame!r}, position_cost={self.position_cost.tolist()}, "
                f"orientation_cost={self.orientation_cost.tolist()}, gain={self.gain}, "
                f"max_speed={self.max_speed}, max_angular_speed={self.max_angular_speed})")
