"""Reference motions: ``reference(t) -> (pose 4x4, twist 6)`` for a FrameTask,
``reference(t) -> (point 3, velocity 3)`` for a PositionTask.

Twists are world-aligned at the frame origin, ordered (linear [m/s]; angular [rad/s]),
matching :meth:`wbc.Robot.frame_jacobian`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from ..core.errors import InvalidInputError
from ..core.validation import as_pose, as_positive, as_vector, direction


class ReferenceMotion(Protocol):
    """What :class:`wbc.app.scenario.Scenario` and :func:`wbc.app.closed_loop.run` call: ``reference(t)``
    at time ``t`` [s] gives the target and its feed-forward rate, the arguments of the task's
    ``set_target`` (every class of this module, and :class:`wbc.trajectory.planner.PlannedReference`)."""

    def __call__(self, t: float, /) -> tuple[NDArray[np.float64], NDArray[np.float64]]: ...


@dataclass
class ConstantPose:
    """A fixed target pose (zero feed-forward twist)."""

    pose: NDArray[np.float64]

    def __post_init__(self) -> None:
        self.pose = as_pose(self.pose, "target pose")
        self._twist = np.zeros(6)

    def __call__(self, t: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        return self.pose, self._twist


@dataclass
class ConstantPoint:
    """A fixed target point [m] for a PositionTask (zero feed-forward velocity)."""

    position: NDArray[np.float64]

    def __post_init__(self) -> None:
        self.position = as_vector(self.position, 3, "target position")
        self._velocity = np.zeros(3)

    def __call__(self, t: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        return self.position, self._velocity


@dataclass
class Circle:
    """Constant-orientation circle through the start pose.

    ``p(t) = centre + radius (cos phi(t) a + sin phi(t) b)`` with ``a`` = ``start_axis``
    (unit vector from the centre to the start point), ``b = normal x a`` and the
    centre placed so that ``p(0)`` is the start position. The phase accelerates
    uniformly during ``ramp_time`` [s] to the rate ``2 pi / period`` so the target
    velocity is continuous (no step at t = 0).
    """

    start: NDArray[np.float64]  #: 4x4 start pose (its rotation is held)
    radius: float  #: [m]
    period: float  #: [s] per revolution after the ramp
    normal: NDArray[np.float64]  #: unit normal of the circle plane (direction of rotation by right hand)
    start_axis: NDArray[np.float64]  #: unit vector from the centre toward the start point
    ramp_time: float = 1.0  #: [s]

    def __post_init__(self) -> None:
        self.start = as_pose(self.start, "circle start pose")
        self.radius = as_positive(self.radius, "radius")
        self.period = as_positive(self.period, "period")
        normal = as_vector(self.normal, 3, "normal")
        axis = as_vector(self.start_axis, 3, "start_axis")
        unit_normal, size = direction(normal)  # (entries near 1e308 keep their direction)
        if unit_normal is None or not size > 1e-12:
            raise InvalidInputError(f"normal must be a nonzero vector (the circle plane's normal), got {normal}")
        unit_axis, length = direction(axis)
        in_plane = None if unit_axis is None else unit_axis - unit_normal * (unit_normal @ unit_axis)
        if in_plane is None or np.linalg.norm(in_plane) < 1e-9 * max(1.0, 1.0 / length):  # (|axis| < 1e-9: zero)
            raise InvalidInputError(f"start_axis {self.start_axis} is parallel to normal {self.normal} (or zero): "
                                    "give a direction in the circle plane, from its centre toward the start point")
        self.normal, self.start_axis = unit_normal, in_plane / np.linalg.norm(in_plane)
        self._b = np.cross(self.normal, self.start_axis)
        self.centre = self.start[:3, 3] - self.radius * self.start_axis
        self._pose = self.start.copy()
        self._twist = np.zeros(6)

    def phase(self, t: float) -> tuple[float, float]:
        """Phase [rad] and its rate [rad/s] at time ``t``."""
        rate = 2.0 * np.pi / self.period
        ramp = max(self.ramp_time, 0.0)
        if t <= 0.0:
            return 0.0, 0.0
        if t < ramp:
            return 0.5 * rate * t * t / ramp, rate * t / ramp
        return rate * (t - 0.5 * ramp), rate

    def __call__(self, t: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        phi, rate = self.phase(t)
        a, b = self.start_axis, self._b
        self._pose[:3, 3] = self.centre + self.radius * (np.cos(phi) * a + np.sin(phi) * b)
        self._twist[:3] = self.radius * rate * (-np.sin(phi) * a + np.cos(phi) * b)
        return self._pose, self._twist


@dataclass
class Line:
    """Straight-line move from ``start`` to ``end`` that arrives at full speed and holds there.

    The path parameter ``s`` in [0, 1] is the travelled fraction of the distance
    ``L = |p_end - p_start|``: ``p(s) = p_start + s (p_end - p_start)`` and the rotation
    follows the geodesic ``R(s) = R_start exp(s log(R_start^T R_end))``. The speed
    ``L ds/dt`` rises uniformly to ``speed`` during ``ramp_time`` [s] (no velocity step
    at t = 0), stays there, and drops to zero on arrival: the target *stops* at
    ``end`` rather than braking into it, the hardest case when ``end`` is singular.
    """

    start: NDArray[np.float64]  #: 4x4 start pose
    end: NDArray[np.float64]  #: 4x4 end pose
    speed: float  #: [m/s] along the line after the ramp
    ramp_time: float = 0.5  #: [s]

    def __post_init__(self) -> None:
        self.start = as_pose(self.start, "line start pose")
        self.end = as_pose(self.end, "line end pose")
        self.speed = as_positive(self.speed, "speed")
        self.length = float(np.linalg.norm(self.end[:3, 3] - self.start[:3, 3]))
        if self.length < 1e-9:
            raise ValueError("a line needs distinct start and end positions")
        self._rotation = pin.log3(self.start[:3, :3].T @ self.end[:3, :3])  # start frame
        self._pose = self.start.copy()
        self._twist = np.zeros(6)

    def distance(self, t: float) -> tuple[float, float]:
        """Travelled distance [m] and speed [m/s] at time ``t``."""
        ramp = max(self.ramp_time, 0.0)
        if t <= 0.0:
            return 0.0, 0.0
        if t < ramp:
            distance, rate = 0.5 * self.speed * t * t / ramp, self.speed * t / ramp
        else:
            distance, rate = self.speed * (t - 0.5 * ramp), self.speed
        if distance >= self.length:
            return self.length, 0.0
        return distance, rate

    def __call__(self, t: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        distance, rate = self.distance(t)
        s, s_rate = distance / self.length, rate / self.length
        start_rotation = self.start[:3, :3]
        self._pose[:3, 3] = self.start[:3, 3] + s * (self.end[:3, 3] - self.start[:3, 3])
        self._pose[:3, :3] = start_rotation @ pin.exp3(s * self._rotation)
        self._twist[:3] = s_rate * (self.end[:3, 3] - self.start[:3, 3])
        self._twist[3:] = s_rate * (start_rotation @ self._rotation)
        return self._pose, self._twist
