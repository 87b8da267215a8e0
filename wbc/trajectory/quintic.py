"""Quintic polynomial segments (Lu et al., eqs. 7-9).

A segment of duration T joins the state (position, velocity, acceleration)
``(p0, v0, a0)`` at t = 0 to ``(p1, v1, a1)`` at t = T with

    F(t)   = A t^5 + B t^4 + C t^3 + D t^2 + E t + F0                      (eq. 7)
    F'(t)  = 5 A t^4 + 4 B t^3 + 3 C t^2 + 2 D t + E
    F''(t) = 20 A t^3 + 12 B t^2 + 6 C t + 2 D

(eq. 7 of the paper prints 16 B t^2 in F''; the derivative of B t^4 is 12 B t^2). The six
boundary conditions (eq. 8) give, with h = p1 - p0 (eq. 9):

    F0 = p0,   E = v0,   D = a0 / 2,
    C = [ 20 h - (8 v1 + 12 v0) T - (3 a0 -   a1) T^2 ] / (2 T^3)
    B = [-30 h + (14 v1 + 16 v0) T + (3 a0 - 2 a1) T^2 ] / (2 T^4)
    A = [ 12 h -  6 (v1 +    v0) T - (  a0 -  a1) T^2 ] / (2 T^5)

Positions may be scalars or vectors (one polynomial per component, e.g. per joint).
The rest-to-rest segment from 0 to 1 is ``s(t) = 10 u^3 - 15 u^4 + 6 u^5`` (u = t / T),
whose peak speed is 15 / (8 T) and peak acceleration 10 / (sqrt(3) T^2).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike

from ..core.errors import InvalidInputError
from ..core.validation import as_positive

REST_TO_REST_PEAK_SPEED = 15.0 / 8.0  #: max ds/du of the rest-to-rest quintic
REST_TO_REST_PEAK_ACCELERATION = 10.0 / np.sqrt(3.0)  #: max d2s/du2 of the rest-to-rest quintic


class Quintic:
    """Quintic segment meeting position, velocity and acceleration at both ends exactly.

    Args:
        start: ``(p0, v0, a0)`` at t = 0 (scalars or arrays of one shape).
        end: ``(p1, v1, a1)`` at t = ``duration``.
        duration: T [s], > 0.

    Calling the segment at ``t`` returns ``(position, velocity, acceleration)``. Outside
    [0, T] time is clamped to the segment: the boundary state is returned.
    """

    def __init__(self, start: Sequence[ArrayLike], end: Sequence[ArrayLike], duration: float) -> None:
        self.duration = as_positive(duration, "duration")
        if len(start) != 3 or len(end) != 3:
            raise InvalidInputError("start and end must each be (position, velocity, acceleration)")
        names = ("p0", "v0", "a0", "p1", "v1", "a1")
        try:
            values = [_finite(x, n) for x, n in zip((*start, *end), names, strict=True)]
            p0, v0, a0, p1, v1, a1 = np.broadcast_arrays(*values)
        except ValueError as exc:
            raise InvalidInputError(f"quintic boundary values have incompatible shapes: {exc}") from exc
        T = self.duration
        h = p1 - p0
        self.coefficients = np.stack([  # A, B, C, D, E, F0 (eq. 9)
            (12 * h - 6 * (v1 + v0) * T - (a0 - a1) * T**2) / (2 * T**5),
            (-30 * h + (14 * v1 + 16 * v0) * T + (3 * a0 - 2 * a1) * T**2) / (2 * T**4),
            (20 * h - (8 * v1 + 12 * v0) * T - (3 * a0 - a1) * T**2) / (2 * T**3),
            a0 / 2, v0, p0,
        ])

    @classmethod
    def rest_to_rest(cls, start: ArrayLike, end: ArrayLike, duration: float) -> Quintic:
        """Segment from ``start`` to ``end`` with zero velocity and acceleration at both ends."""
        start, end = np.asarray(start, dtype=float), np.asarray(end, dtype=float)
        zero = np.zeros_like(start)
        return cls((start, zero, zero), (end, zero, zero), duration)

    def __call__(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        t = min(max(float(t), 0.0), self.duration)
        A, B, C, D, E, F0 = self.coefficients
        position = ((((A * t + B) * t + C) * t + D) * t + E) * t + F0
        velocity = (((5 * A * t + 4 * B) * t + 3 * C) * t + 2 * D) * t + E
        acceleration = ((20 * A * t + 12 * B) * t + 6 * C) * t + 2 * D
        return position, velocity, acceleration


def rest_to_rest_duration(distance: float, max_speed: float, max_acceleration: float | None = None) -> float:
    """Shortest T for which the rest-to-rest quintic over ``distance`` respects the bounds:
    T = max(15/8 d / v_max, sqrt(10/sqrt(3) d / a_max))."""
    distance = as_positive(distance, "distance")
    duration = REST_TO_REST_PEAK_SPEED * distance / as_positive(max_speed, "max_speed")
    if max_acceleration is not None:
        duration = max(duration, np.sqrt(REST_TO_REST_PEAK_ACCELERATION * distance
                                         / as_positive(max_acceleration, "max_acceleration")))
    return float(duration)


def _finite(value: ArrayLike, name: str) -> np.ndarray:
    try:
        array = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InvalidInputError(f"quintic boundary value {name} must be numeric") from exc
    if not np.all(np.isfinite(array)):
        raise InvalidInputError(f"quintic boundary value {name} contains NaN or inf")
    return array
