"""A holonomic base on four mecanum (Swedish, 45-degree roller) wheels: the youBot's."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numpy.typing import NDArray

from ...core.errors import ModelError
from .interface import LAYOUT_TOLERANCE, BaseKind, WheelMount
from .planar import PlanarBase


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
class MecanumBase(PlanarBase):
    """A planar (holonomic) base whose ``wheels`` are :class:`MecanumWheels` (or not modelled)."""

    kind: BaseKind = BaseKind.MECANUM
    wheels: MecanumWheels | None = None

    wheel_count: ClassVar[int] = 4

    @classmethod
    def wheels_from_mounts(cls, mounts: list[WheelMount], radius: float, max_speed: float,
                           where: str) -> MecanumWheels:
        """Four wheels at (+-l, +-w), rollers at 45 degrees (the X layout of the youBot)."""
        half_length, half_width = (float(np.mean([abs(w.position[k]) for w in mounts])) for k in (0, 1))
        corners = sorted((np.sign(w.position[0]), np.sign(w.position[1])) for w in mounts)
        if corners != [(-1, -1), (-1, 1), (1, -1), (1, 1)] or any(
                abs(abs(w.position[0]) - half_length) > LAYOUT_TOLERANCE
                or abs(abs(w.position[1]) - half_width) > LAYOUT_TOLERANCE for w in mounts):
            layout = ", ".join(f"{w.name} at {np.round(w.position[:2], 6).tolist()}" for w in mounts)
            raise ModelError(f"{where}: mecanum wheels {layout} (x, y in the base frame [m]); wbc's mecanum model "
                             "needs one wheel at each corner (+-l, +-w) of a rectangle centred on the base frame")
        return MecanumWheels(radius=radius, half_length=half_length, half_width=half_width, max_speed=max_speed)


__all__ = ["MecanumBase", "MecanumWheels"]
