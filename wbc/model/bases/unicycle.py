"""A differential-drive (unicycle) base: it drives along its x axis and turns, never slips sideways."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numpy.typing import NDArray

from ...core.errors import ModelError
from .interface import LAYOUT_TOLERANCE, BaseKind, WheelMount
from .planar import PlanarBase, Twist


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
class UnicycleBase(PlanarBase):
    """No lateral slip, ``v_y = -sin(heading) xdot + cos(heading) ydot = 0``; the inputs are
    ``(v, omega)`` = (forward speed [m/s], heading rate [rad/s]), so
    ``(xdot, ydot) = v (cos, sin)(heading)``. ``wheels``: :class:`DifferentialWheels` (or none)."""

    kind: BaseKind = BaseKind.UNICYCLE
    wheels: DifferentialWheels | None = None

    no_slip: ClassVar[tuple[Twist, ...]] = ((0.0, 1.0, 0.0),)
    no_slip_labels: ClassVar[tuple[str, ...]] = ("no lateral slip",)
    input_twists: ClassVar[tuple[Twist, ...]] = ((1.0, 0.0, 0.0), (0.0, 0.0, 1.0))
    wheel_count: ClassVar[int] = 2

    @classmethod
    def wheels_from_mounts(cls, mounts: list[WheelMount], radius: float, max_speed: float,
                           where: str) -> DifferentialWheels:
        """Left (+y) and right wheels on an axle through the base origin, symmetric."""
        left, right = sorted(mounts, key=lambda wheel: -wheel.position[1])
        layout = ", ".join(f"{w.name} at {np.round(w.position[:2], 6).tolist()}" for w in (left, right))
        if max(abs(left.position[0]), abs(right.position[0])) > LAYOUT_TOLERANCE \
                or abs(left.position[1] + right.position[1]) > LAYOUT_TOLERANCE or left.position[1] <= 0.0:
            raise ModelError(f"{where}: differential wheels {layout} (x, y in the base frame [m]); wbc's "
                             "differential drive needs the axle on the base frame's y axis, the wheels at +-b: put "
                             "the base frame (the model's root link) on the axle midpoint")
        return DifferentialWheels(radius=radius, half_track=float(left.position[1]), max_speed=max_speed)


__all__ = ["UnicycleBase", "DifferentialWheels"]
