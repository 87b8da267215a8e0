"""3-D position task of one frame."""

from __future__ import annotations

import numpy as np

from ..errors import InvalidInputError
from ..kinematics import Kinematics
from ..robot import Robot
from ..validation import as_gain, as_positive, as_vector, as_weights
from .task import Task, _norm, _saturate


class PositionTask(Task):
    """Drive the origin of a frame to a target point (orientation free).

    Error ``e = p* - p`` [m] (world); rows ``W (J_lin v - r)`` with the linear rows of
    :meth:`Robot.frame_jacobian` and the desired velocity ``r = sat(gain/dt * e) + pdot*``,
    ``pdot*`` an optional feed-forward velocity [m/s] and ``sat`` scaling the feedback
    part down to at most ``max_speed`` in norm (far targets are approached at a
    bounded speed instead of demanding metres per second that only saturate the joints).

    Args:
        frame: frame name.
        cost: [cost] / [m]^2, scalar or per axis.
        gain: fraction of the error removed per tick, in (0, 1].
        max_speed: [m/s] bound on the feedback velocity; ``None`` = unbounded.
    """

    dim = 3

    def __init__(self, frame: str, cost=1.0, gain: float = 1.0, max_speed: float | None = None,
                 name: str | None = None) -> None:
        self.frame = frame
        super().__init__(name)
        self.cost = as_weights(cost, 3, "cost")
        self.gain = as_gain(gain)
        self.max_speed = np.inf if max_speed is None else as_positive(max_speed, "max_speed")
        self._weights = np.sqrt(self.cost)
        self._target = np.zeros(3)
        self._feedforward = np.zeros(3)
        self._has_target = False
        self.error = np.zeros(3)  #: last error p* - p [m], world

    def default_name(self) -> str:
        return f"PositionTask({self.frame})"

    def set_target(self, position, velocity=None) -> None:
        """Target point [m] (world) and optional feed-forward velocity [m/s]."""
        self._target[...] = as_vector(position, 3, "target position")
        self._feedforward[...] = 0.0 if velocity is None else as_vector(velocity, 3, "target velocity")
        self._has_target = True

    @property
    def target(self) -> np.ndarray:
        return self._target.copy()

    def bind(self, robot: Robot) -> None:
        self._frame_id = robot.frame_id(self.frame)
        self._key = self.name

    def compute(self, kin: Kinematics, dt: float, jacobian: np.ndarray, target: np.ndarray) -> None:
        if not self._has_target:
            raise InvalidInputError(f"{self.name}: no target set; call set_target() before stepping")
        np.subtract(self._target, kin.frame_placement(self._frame_id).translation, out=self.error)
        np.multiply(self._weights[:, None], kin.frame_jacobian(self._frame_id)[:3], out=jacobian)
        np.multiply(self.error, self.gain / dt, out=target)
        _saturate(target, self.max_speed)
        target += self._feedforward
        target *= self._weights

    def report(self, v: np.ndarray, errors: dict[str, float]) -> None:
        errors[self._key] = _norm(self.error)

    def __repr__(self) -> str:
        return (f"PositionTask(frame={self.frame!r}, cost={self.cost.tolist()}, gain={self.gain}, "
                f"max_speed={self.max_speed})")
