"""Mobile-base descriptions: which coordinates form the base and how it moves.

Conventions (used everywhere in wbc):

* The base pose is ``(x, y, yaw)`` in the world frame: ``x, y`` [m] position of the
  base reference point, ``yaw`` [rad] from the world x axis to the base x axis,
  counter-clockwise seen from above (+z).
* A planar base twist ``(v_x, v_y, omega)`` is given in the **base frame**:
  ``v_x`` forward, ``v_y`` to the left [m/s], ``omega`` yaw rate [rad/s].
  With ``R(yaw)`` the 2-D rotation, world rates are ``(xdot, ydot) = R(yaw) (v_x, v_y)``.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

import numpy as np


class BaseKind(enum.Enum):
    """How the base of a robot moves."""

    FIXED = "fixed"  #: bolted to the world
    PLANAR = "planar"  #: holonomic (x, y, yaw) without wheel model
    MECANUM = "mecanum"  #: holonomic, four 45-degree Swedish wheels


@dataclass(frozen=True)
class MecanumWheels:
    """Geometry of four Swedish (mecanum) wheels, all lengths in [m]."""

    radius: float  #: wheel radius r
    half_length: float  #: l, wheel axle to base centre along the base x axis
    half_width: float  #: w, wheel contact to base centre along the base y axis


@dataclass(frozen=True)
class MobileBase:
    """The base of a robot.

    ``indices`` are the positions of ``(x, y, yaw)`` in the velocity vector ``v``
    (and in ``q``; wbc requires the base coordinates to be 1-DOF joints).
    ``max_linear_speed`` [m/s] bounds the base-frame components ``|v_x|, |v_y|``,
    ``max_yaw_rate`` [rad/s] bounds ``|omega|``.
    """

    kind: BaseKind
    indices: tuple[int, int, int] = (0, 1, 2)
    max_linear_speed: float = np.inf
    max_yaw_rate: float = np.inf
    wheels: MecanumWheels | None = None

    @property
    def is_mobile(self) -> bool:
        return self.kind is not BaseKind.FIXED


FIXED_BASE = MobileBase(BaseKind.FIXED, indices=(-1, -1, -1))
