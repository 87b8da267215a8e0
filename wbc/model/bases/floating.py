"""A floating base: a free-flyer root joint (humanoids, legged robots, flying bases).

The root joint is Pinocchio's ``JointModelFreeFlyer``: its 7 configuration coordinates are the
base's world position ``p`` [m] and orientation as a unit quaternion ``(x, y, z, w)``, its 6
velocity coordinates the base twist ``(v, omega)`` expressed in the **base frame** (linear
[m/s], then angular [rad/s]). A velocity held for ``dt`` moves the base along the SE(3)
exponential::

    M(t + dt) = M(t) exp(dt (v, omega))          (M: the base's world pose)

(``pinocchio.integrate``). The base has no wheels and no rows: its speed bounds are the box
``|v_i| <= max_linear_speed``, ``|omega_i| <= max_yaw_rate`` on the base-frame components, which
are the velocity coordinates themselves.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from .interface import BaseKind, MobileBase

#: size of the free-flyer's configuration (position, quaternion) and velocity (twist)
FREE_FLYER_NQ, FREE_FLYER_NV = 7, 6


@dataclass(frozen=True)
class FloatingBase(MobileBase):
    """A free-flyer root joint whose coordinates start at ``q[configuration_start]`` and
    ``v[velocity_start]`` (0 for a root joint). ``indices`` (a ground base's ``(x, y, heading)``)
    are ``(-1, -1, -1)``: the base does not drive on the ground plane, so the planar-base items
    (:class:`wbc.BaseVelocityTask`, wheel limits, footprint) refuse it; every other item treats
    its six velocity coordinates like joint rates. ``max_yaw_rate`` bounds each angular
    component ``|omega_x|, |omega_y|, |omega_z|`` [rad/s], ``max_linear_speed`` each linear one.
    """

    kind: BaseKind = BaseKind.FLOATING
    indices: tuple[int, int, int] = (-1, -1, -1)
    configuration_start: int = 0
    velocity_start: int = 0

    is_mobile: ClassVar[bool] = False  # no (x, y, heading) ground coordinates

    @property
    def is_nonholonomic(self) -> bool:
        return False

    @property
    def velocity_coordinates(self) -> tuple[int, ...]:
        """The twist's six coordinates in ``v``: ``(v_x, v_y, v_z, omega_x, omega_y, omega_z)``."""
        return tuple(range(self.velocity_start, self.velocity_start + FREE_FLYER_NV))

    def limit_coordinates(self, lower: NDArray[np.float64], upper: NDArray[np.float64],
                          velocity_limit: NDArray[np.float64]) -> None:
        """Position unbounded, quaternion components in ``[-1, 1]``; the twist's components
        bounded by ``max_linear_speed`` and ``max_yaw_rate`` (inf: unbounded)."""
        position = slice(self.configuration_start, self.configuration_start + 3)
        quaternion = slice(self.configuration_start + 3, self.configuration_start + FREE_FLYER_NQ)
        lower[position], upper[position] = -np.inf, np.inf
        lower[quaternion], upper[quaternion] = -1.0, 1.0
        linear = slice(self.velocity_start, self.velocity_start + 3)
        angular = slice(self.velocity_start + 3, self.velocity_start + FREE_FLYER_NV)
        velocity_limit[linear] = self.max_linear_speed
        velocity_limit[angular] = self.max_yaw_rate

    def twist(self, q: NDArray[np.float64], v: NDArray[np.float64]) -> NDArray[np.float64]:
        """Base-frame twist ``(v_x, v_y, v_z, omega_x, omega_y, omega_z)``: the free-flyer's
        velocity coordinates (6 entries, or ``(T, 6)`` for rows of ``v``)."""
        return np.array(v[..., self.velocity_start:self.velocity_start + FREE_FLYER_NV], dtype=np.float64)

    def integrate(self, model: pin.Model, q: NDArray[np.float64], v: NDArray[np.float64],
                  dt: float) -> NDArray[np.float64]:
        """``q`` after ``dt`` [s] at ``v``: the base pose ``M exp(dt (v, omega))`` on SE(3), the
        other joints each on their own coordinates (``pinocchio.integrate``)."""
        return pin.integrate(model, q, v * dt)


def free_flyer_root(model: pin.Model) -> int | None:
    """Index of a free-flyer joint at the root of ``model`` (a URDF ``floating`` root joint, or
    the root joint given to Pinocchio's parser), None when there is none."""
    for joint_id in range(1, model.njoints):
        if model.parents[joint_id] == 0 and model.joints[joint_id].shortname() == "JointModelFreeFlyer":
            return joint_id
    return None


__all__ = ["FloatingBase", "free_flyer_root", "FREE_FLYER_NQ", "FREE_FLYER_NV"]
