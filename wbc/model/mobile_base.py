"""Mobile-base descriptions: which coordinates form the base and how it moves.

Conventions (used everywhere in wbc):

* The base pose is ``(x, y, heading)`` in the world frame: ``x, y`` [m] position of the
  base reference point, ``heading`` [rad] from the world x axis to the base x axis,
  counter-clockwise seen from above (+z). For a synchro drive the heading is the
  common steering angle of the wheels (the chassis itself does not turn).
* A planar base twist ``(v_x, v_y, omega)`` is given in the **base frame**:
  ``v_x`` forward, ``v_y`` to the left [m/s], ``omega`` heading rate [rad/s].
  With ``R(heading)`` the 2-D rotation, world rates are ``(xdot, ydot) = R (v_x, v_y)``.
* Nonholonomic bases (unicycle / differential drive, synchro drive) cannot slip
  sideways: ``v_y = -sin(heading) xdot + cos(heading) ydot = 0``. Their real inputs are
  ``(v, omega)`` = (forward speed [m/s], heading rate [rad/s]).
* Wheel speeds are wheel angular rates [rad/s], positive when the wheel rolls the base
  forward (+x of the base frame).
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray


class BaseKind(enum.Enum):
    """How the base of a robot moves."""

    FIXED = "fixed"  #: bolted to the world
    PLANAR = "planar"  #: holonomic (x, y, heading) without a wheel model
    MECANUM = "mecanum"  #: holonomic, four 45-degree Swedish wheels
    UNICYCLE = "unicycle"  #: differential drive: no lateral slip, the chassis turns with the heading
    SYNCHRO = "synchro"  #: synchro drive: no lateral slip, wheels steer together, chassis does not turn

    @property
    def is_mobile(self) -> bool:
        return self is not BaseKind.FIXED

    @property
    def is_nonholonomic(self) -> bool:
        return self in (BaseKind.UNICYCLE, BaseKind.SYNCHRO)


@dataclass(frozen=True)
class MecanumWheels:
    """Four Swedish wheels with 45-degree rollers, all lengths in [m].

    Wheel order (front-left, front-right, rear-left, rear-right). With ``k = l + w`` the
    inverse kinematics from the base-frame twist is ``u = H0 (v_x, v_y, omega)``::

        H0 = 1/r [[1, -1, -k],
                  [1,  1,  k],
                  [1,  1, -k],
                  [1, -1,  k]]
    """

    radius: float  #: wheel radius r
    half_length: float  #: l, wheel axle to base centre along the base x axis
    half_width: float  #: w, wheel contact to base centre along the base y axis
    max_speed: float = np.inf  #: ``|u_i|`` limit [rad/s]

    def inverse_matrix(self) -> NDArray[np.float64]:
        """``H0`` (4x3): base-frame twist -> wheel speeds."""
        k = self.half_length + self.half_width
        return np.array([[1.0, -1.0, -k], [1.0, 1.0, k], [1.0, 1.0, -k], [1.0, -1.0, k]]) / self.radius

    def forward_matrix(self) -> NDArray[np.float64]:
        """``F`` (3x4) with ``F H0 = I``: wheel speeds -> base-frame twist (least squares)."""
        k = self.half_length + self.half_width
        return self.radius / 4.0 * np.array([[1.0, 1.0, 1.0, 1.0], [-1.0, 1.0, 1.0, -1.0],
                                              [-1 / k, 1 / k, -1 / k, 1 / k]])


@dataclass(frozen=True)
class DifferentialWheels:
    """Two driven wheels of a differential-drive base, lengths in [m]; order (left, right).

    ``u = 1/r [[1, -b], [1, b]] (v, omega)``.
    """

    radius: float  #: wheel radius r
    half_track: float  #: b, half the distance between the wheels
    max_speed: float = np.inf  #: ``|u_i|`` limit [rad/s]

    def inverse_matrix(self) -> NDArray[np.float64]:
        """(2x3) base-frame twist (v_x, v_y, omega) -> wheel speeds (v_y must be 0)."""
        b = self.half_track
        return np.array([[1.0, 0.0, -b], [1.0, 0.0, b]]) / self.radius


@dataclass(frozen=True)
class MobileBase:
    """The base of a robot.

    ``indices`` are the positions of ``(x, y, heading)`` in the velocity vector ``v``
    (and in ``q``; wbc requires the base coordinates to be 1-DOF joints).
    ``max_linear_speed`` [m/s] bounds the base-frame components ``|v_x|, |v_y|``,
    ``max_yaw_rate`` [rad/s] bounds ``|omega|``.
    """

    kind: BaseKind
    indices: tuple[int, int, int] = (0, 1, 2)
    max_linear_speed: float = np.inf
    max_yaw_rate: float = np.inf
    wheels: MecanumWheels | DifferentialWheels | None = None

    @property
    def is_mobile(self) -> bool:
        return self.kind.is_mobile

    @property
    def is_nonholonomic(self) -> bool:
        return self.kind.is_nonholonomic

    def twist(self, q: NDArray[np.float64], v: NDArray[np.float64]) -> NDArray[np.float64]:
        """Base-frame twist ``(v_x, v_y, omega)`` of ``v`` at ``q``; rows of ``(T, n)`` arrays
        give a ``(T, 3)`` array. Inputs are not validated (see :meth:`Robot.base_twist`)."""
        x, y, heading = self.indices
        cos, sin = np.cos(q[..., heading]), np.sin(q[..., heading])
        return np.stack([cos * v[..., x] + sin * v[..., y], -sin * v[..., x] + cos * v[..., y], v[..., heading]],
                        axis=-1)


FIXED_BASE = MobileBase(BaseKind.FIXED, indices=(-1, -1, -1))
