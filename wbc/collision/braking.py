"""The braking (viability) bound of velocity-damper rows under hard acceleration bounds."""

from __future__ import annotations

import math
import warnings

import numpy as np
from numpy.typing import NDArray

from ..constraints.acceleration_limits import braking_speed
from ..core.errors import ConfigurationWarning
from ..model.robot import Robot
from ..model.tick_context import TickContext

#: the share of the rate at which the acceleration bounds can change a row's ``g . v`` that its
#: braking bound counts on: the rest absorbs the change of the row while braking and the speed limits
BRAKING_SHARE = 0.5
#: the rate given to a row that no bound moves (a zero row: inert, or a vanishing gradient): its
#: braking bound is then above its damper, which it keeps
UNBOUNDED = 1e300


class RowBraking:
    """Caps damper rows ``-g . v <= h``, ``h = gain (d - d_min) / dt``, by the speed from which the
    acceleration bounds of the stack can still stop the approach before ``d_min``::

        d_dot >= -min(gain (d - d_min) / dt,  v_brake(d - d_min, a_d))

    ``v_brake`` is :func:`~wbc.constraints.acceleration_limits.braking_speed`: the exact discrete-time
    inverse of the distance covered while braking at ``a_d`` per tick (Del Prete et al. 2018, as for
    the joints' position limits), invariant: braking at ``a_d`` from the bound meets it at the next
    tick. ``a_d`` = :data:`BRAKING_SHARE` times ``braking.decelerations`` (what the bounds can do
    along g). The damper alone asks, one tick before the margin, for a stop from any approach speed,
    which the hard bounds forbid; capped, the soft rows stay feasible with them. Rows inside the
    margin (``h <= 0``: a push-out) keep the damper. Buffers for up to ``rows`` rows; the bounds
    are the controller's (``context.braking``, :meth:`use_context`): without them nothing changes.
    """

    def __init__(self, rows: int) -> None:
        self._deceleration, self._margin, self._speed = np.zeros(rows), np.zeros(rows), np.zeros(rows)
        self._still = np.zeros(rows, dtype=bool)
        self._context: TickContext | None = None

    def use_context(self, context: TickContext) -> None:
        """Read the acceleration bounds of ``context``'s controller (its damper rows' data calls this)."""
        self._context = context

    @property
    def active(self) -> bool:
        """Whether the controller has acceleration bounds (known once its items are bound)."""
        return self._context is not None and self._context.braking is not None

    def apply(self, q: NDArray[np.float64], G: NDArray[np.float64], h: NDArray[np.float64], gain: float,
              dt: float, count: int | None = None) -> None:
        """Cap ``h`` (rows ``G``, ``G = -g``; at most ``rows``; only the first ``count`` when given)
        in place, when the controller has acceleration bounds."""
        braking = None if self._context is None else self._context.braking
        if braking is None:
            return
        if count is not None:
            G, h = G[:count], h[:count]
        n = h.shape[0]
        deceleration, margin, speed, still = self._deceleration[:n], self._margin[:n], self._speed[:n], self._still[:n]
        braking.decelerations(G, q, deceleration)
        np.multiply(deceleration, BRAKING_SHARE, out=deceleration)
        np.less_equal(deceleration, 0.0, out=still)
        np.copyto(deceleration, UNBOUNDED, where=still)
        np.multiply(h, dt / gain, out=margin)  # d - d_min of each row
        braking_speed(margin, deceleration, dt, speed)
        np.maximum(speed, np.minimum(h, 0.0, out=margin), out=speed)  # inside the margin: the push-out
        np.minimum(h, speed, out=h)

    def check_detection(self, robot: Robot, name: str, detection: float, min_distance: float) -> None:
        """Warn (:class:`~wbc.ConfigurationWarning`) when the controller has acceleration bounds
        and ``detection - min_distance`` is shorter than the distance the platform needs to stop
        from its top speed along one of its axes (``robot.base.max_linear_speed``, at ``a_d``
        as in :meth:`apply`): ``s^2 / (2 a_d)``. A pair found that late cannot be braked for: the
        soft rows give way and the margin goes (docs/acceleration.md). Only the platform's
        approach is checked (an arm's speed along a row depends on its configuration)."""
        braking = None if self._context is None else self._context.braking
        base = robot.base
        speed = base.max_linear_speed
        if braking is None or not base.is_mobile or not 0.0 < speed < math.inf:
            return
        axes = np.zeros((2, robot.nv))  # the base's x and y axes (its heading at the neutral configuration)
        axes[0, base.indices[0]] = axes[1, base.indices[1]] = 1.0
        rates = np.zeros(2)
        braking.decelerations(axes, robot.neutral(), rates)
        rate = BRAKING_SHARE * float(rates.min())
        if rate <= 0.0:
            return
        stop = speed * speed / (2.0 * rate)
        if detection - min_distance < stop:
            warnings.warn(f"{name}: detection_distance {detection:g} m leaves {detection - min_distance:g} m "
                          f"before min_distance, but the acceleration bounds need {stop:.3g} m to stop the "
                          f"platform from its {speed:g} m/s (at {rate:.3g} m/s^2, half of what they allow along "
                          "its axis): an approach at that speed found that late cannot be braked for, and the margin "
                          f"goes; set detection_distance >= {stop + min_distance:.3g} m, or lower the base's speed "
                          "limit (docs/acceleration.md)", ConfigurationWarning, stacklevel=2)
