"""A base moving in the plane on ``(x, y, heading)`` joints: the holonomic planar base, and the
math every planar kind shares (its rows come from two tuples a kind declares).

With ``R(heading)`` the 2-D rotation, the base-frame twist is ``t = B(heading) v`` with
``(v_x, v_y) = R^T (xdot, ydot)``, ``omega = heading rate``. A kind declares

* ``no_slip``: rows ``N`` (k x 3) with ``N t = 0`` (none: holonomic), and
* ``input_twists``: the ``3 - k`` twists its inputs drive, a basis of ``null(N)``, so that
  ``v = S(q) u`` with the base block of ``S`` equal to ``blockdiag(R(heading), 1) [input_twists]^T``
  and the other coordinates their own inputs, after the base's (``u = (base inputs, joints)``).

A holonomic base's inputs are ``v`` itself (``S = I``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numpy.typing import NDArray

from .interface import NO_ROWS, BaseKind, MobileBase, TwistRows

#: the four base-frame speed rows ``+-v_x, +-v_y <= max_linear_speed``
_SPEED_ROWS = ((1.0, 0.0, 0.0), (-1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, -1.0, 0.0))
_SPEED_LABELS = ("base v_x upper", "base v_x lower", "base v_y upper", "base v_y lower")

Twist = tuple[float, float, float]


@dataclass(frozen=True)
class PlanarBase(MobileBase):
    """A holonomic base on ``(x, y, heading)`` without a wheel model."""

    kind: BaseKind = BaseKind.PLANAR

    #: no-slip rows ``N`` on the twist (k rows; none: holonomic)
    no_slip: ClassVar[tuple[Twist, ...]] = ()
    no_slip_labels: ClassVar[tuple[str, ...]] = ()
    #: the twists the base's inputs drive (3 - k of them; used when ``no_slip`` is not empty)
    input_twists: ClassVar[tuple[Twist, ...]] = ()

    @property
    def is_nonholonomic(self) -> bool:
        return bool(self.no_slip)

    def limit_coordinates(self, lower: NDArray[np.float64], upper: NDArray[np.float64],
                          velocity_limit: NDArray[np.float64]) -> None:
        """Positions unbounded; ``|xdot|, |ydot| <= max_linear_speed`` (the base-frame limits as
        bounds; :class:`wbc.JointVelocityLimits` writes them as rows), ``|omega| <= max_yaw_rate``."""
        x, y, heading = self.indices
        lower[[x, y, heading]] = -np.inf
        upper[[x, y, heading]] = np.inf
        velocity_limit[[x, y]] = self.max_linear_speed
        velocity_limit[heading] = self.max_yaw_rate

    def twist(self, q: NDArray[np.float64], v: NDArray[np.float64]) -> NDArray[np.float64]:
        x, y, heading = self.indices
        cos, sin = np.cos(q[..., heading]), np.sin(q[..., heading])
        return np.stack([cos * v[..., x] + sin * v[..., y], -sin * v[..., x] + cos * v[..., y], v[..., heading]],
                        axis=-1)

    def speed_rows(self) -> TwistRows:
        """``+-v_x <= max_linear_speed``, ``+-v_y <= max_linear_speed`` (none when unbounded)."""
        if not np.isfinite(self.max_linear_speed):
            return NO_ROWS
        return TwistRows(_SPEED_ROWS, self.max_linear_speed, _SPEED_LABELS)

    def no_slip_rows(self) -> TwistRows:
        return TwistRows(self.no_slip, 0.0, self.no_slip_labels) if self.no_slip else NO_ROWS

    def allocate_input_map(self, nv: int) -> NDArray[np.float64]:
        if not self.no_slip:
            return np.eye(nv)
        n_base = len(self.input_twists)
        others = [i for i in range(nv) if i not in self.indices]
        S = np.zeros((nv, n_base + len(others)))
        S[others, np.arange(n_base, S.shape[1])] = 1.0
        heading = self.indices[2]
        for column, (_, _, omega) in enumerate(self.input_twists):
            S[heading, column] = omega
        self.write_input_map(np.zeros(heading + 1), S)
        return S

    def write_input_map(self, q: NDArray[np.float64] | Sequence[float], S: NDArray[np.float64]) -> None:
        """The base block's ``(x, y)`` rows: ``R(heading) (t_x, t_y)`` for each input twist ``t``."""
        if not self.no_slip:
            return
        x, y, heading = self.indices
        angle = q[heading]
        cos, sin = math.cos(angle), math.sin(angle)
        for column, (t_x, t_y, _) in enumerate(self.input_twists):
            S[x, column], S[y, column] = cos * t_x - sin * t_y, sin * t_x + cos * t_y


__all__ = ["PlanarBase"]
