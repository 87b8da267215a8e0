"""Steer a nonholonomic base toward where a holonomic base would go."""

from __future__ import annotations

import math

import numpy as np

from ..errors import InvalidInputError
from ..kinematics import Kinematics
from ..robot import Robot
from ..validation import as_gain, as_positive
from .task import Task


class SteeringTask(Task):
    """Turn the heading of a nonholonomic base toward the holonomic preview.

    Why: the heading rate ``omega`` of a unicycle or synchro drive has no first-order
    effect on where the base goes (for the synchro drive it has no effect on the arm
    either: the zero column of De Luca's ``J(q)``). A one-tick velocity QP therefore sees
    no reason to steer, and a target that lies sideways is never reached. The base is
    still controllable -- steering and driving generate the sideways motion at second
    order -- so the missing information is *which way the base ought to go*.

    The controller provides it: before the main QP it solves the **holonomic
    relaxation** of the same task stack (all other tasks, no constraints, no
    no-slip rows), ``v_h = argmin sum ||W (J v - r)||^2 + damping ||v||^2``. Its base
    velocity ``(xdot_h, ydot_h)`` is the motion a holonomic base would make now. This
    task asks the heading to align with that direction, forward or backward
    (whichever needs less turning)::

        delta = wrap_(-pi/2, pi/2](atan2(ydot_h, xdot_h) - heading)
        row:  sqrt(cost) (omega - gain/dt * delta)

    When the relaxation needs no base motion (``|(xdot_h, ydot_h)| < min_speed``, e.g. the
    arm alone reaches the target) the row asks ``omega = 0``. It works for any
    nonholonomic base kind and costs one small linear solve per tick.

    Args:
        cost: [cost] / [rad/s]^2.
        gain: fraction of the heading error removed per tick, (0, 1].
        min_speed: [m/s] relaxation base speed below which the heading is held.
    """

    dim = 1
    uses_preview = True

    def __init__(self, cost: float = 1.0, gain: float = 0.1, min_speed: float = 1e-3,
                 name: str | None = None) -> None:
        super().__init__(name)
        self.cost = as_positive(cost, "cost")
        self.gain = as_gain(gain)
        self.min_speed = as_positive(min_speed, "min_speed")
        self._weight = math.sqrt(self.cost)
        self.error = np.zeros(1)  #: heading error delta [rad]

    def bind(self, robot: Robot) -> None:
        if not robot.base.is_nonholonomic:
            raise InvalidInputError(f"{self.name}: robot '{robot.name}' has a {robot.base.kind.value} base; "
                                    "steering is only needed by nonholonomic bases")
        self._x, self._y, self._heading = robot.base.indices

    def compute(self, kin: Kinematics, dt: float, jacobian: np.ndarray, target: np.ndarray) -> None:
        raise RuntimeError("SteeringTask is computed by the controller with a preview (compute_preview)")

    def compute_preview(self, kin: Kinematics, dt: float, jacobian: np.ndarray, target: np.ndarray,
                        preview: np.ndarray) -> None:
        """Write the row given the holonomic relaxation's velocity ``preview`` (nv)."""
        xdot, ydot = preview[self._x], preview[self._y]
        delta = 0.0
        if math.hypot(xdot, ydot) >= self.min_speed:
            delta = math.atan2(ydot, xdot) - kin.q[self._heading]
            delta = (delta + math.pi / 2) % math.pi - math.pi / 2  # drive forward or backward
        self.error[0] = delta
        jacobian.fill(0.0)
        jacobian[0, self._heading] = self._weight
        target[0] = self._weight * self.gain * delta / dt

    def report(self, v: np.ndarray, errors: dict[str, float]) -> None:
        errors[self.name] = abs(float(self.error[0]))

    def __repr__(self) -> str:
        return f"SteeringTask(cost={self.cost}, gain={self.gain}, min_speed={self.min_speed})"
