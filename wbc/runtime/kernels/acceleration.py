"""Acceleration and jerk limits (:class:`wbc.AccelerationLimits`): the braking speed of the
viability bound, and one tick's bounds of every channel in one call.

The math is the constraint's (its module docstring): channels are the joints' velocity
coordinates, the platform's base-frame ``(v_x, v_y)`` and the wheel speeds; their reference
``w_prev`` is the measured velocity, else the previous command, scaled into the speed limits.
"""

from __future__ import annotations

import math

import numpy as np

from . import BASE_X, BASE_Y, BASE_YAW, BASE_YAW_CHANNEL, prepare_cache
from ._lazy import ENTRY, declared

CACHE = prepare_cache()  # before the first @njit below compiles; False: no writable cache (see wbc.runtime.kernels)


@declared("void(float64[:], float64[:], float64, float64[:])", cache=CACHE, nogil=True)
def braking_speed(distance: np.ndarray, a_max: np.ndarray, dt: float, out: np.ndarray) -> None:
    """``out[i]``: the largest speed toward a limit ``distance[i]`` away from which braking at
    ``a_max[i]`` per tick stops short of it (the exact inverse of the discrete braking distance)::

        delta = d / (a dt^2),  m = floor((sqrt(8 delta + 1) - 1) / 2),  v = a dt (delta / (m + 1) + m / 2)

    ``d < 0`` (beyond the limit): ``d / dt``, the speed that lands on it in one tick; ``d = inf``
    (no limit on that side): inf."""
    for i in range(distance.size):
        d = distance[i]
        if d < 0.0:
            out[i] = d / dt
        elif d == math.inf:
            out[i] = math.inf
        else:
            step = a_max[i] * dt
            delta = d / (step * dt)
            m = math.floor((math.sqrt(8.0 * delta + 1.0) - 1.0) / 2.0)
            out[i] = step * (delta / (m + 1) + 0.5 * m)


@declared("void(float64[:], float64, boolean, float64[:], float64, int64[:], int64[:], float64[:], "
          "float64[:, :], float64, float64[:], float64[:], float64[:], float64[:], float64[:], int64[:], int64[:], "
          "float64[:], float64[:], float64[:], float64[:], float64[:], float64[:], float64[:], boolean)",
          cache=CACHE, nogil=True, **ENTRY)
def acceleration_bounds(v: np.ndarray, heading: float, new_tick: bool, q: np.ndarray, dt: float,
                        joints: np.ndarray, base: np.ndarray, twist_speed: np.ndarray, H0: np.ndarray,
                        wheel_speed: float, accel: np.ndarray, jerk: np.ndarray, speed: np.ndarray,
                        prev: np.ndarray, prev2: np.ndarray, viable: np.ndarray, viable_q: np.ndarray,
                        viable_accel: np.ndarray, position_lower: np.ndarray, position_upper: np.ndarray,
                        scratch: np.ndarray, lower: np.ndarray, upper: np.ndarray, h: np.ndarray,
                        base_rows: bool) -> None:
    """One tick of :class:`wbc.AccelerationLimits`.

    History: on a ``new_tick`` ``w_prev2 <- w_prev``; then ``w_prev <-`` the channels of ``v`` (the
    reference velocity; its base twist taken at ``heading`` and scaled as a whole into
    ``twist_speed`` and ``wheel_speed``), clipped into ``speed``. Bounds per channel, each clipped
    into the ones before::

        box:        max(w_prev - a dt, -speed) <= w <= min(w_prev + a dt, speed)
        viability:  -braking_speed(q - q_lower) <= w <= braking_speed(q_upper - q)   (channels ``viable``,
                    braking at ``viable_accel``: their ``accel``)
        jerk:       |w - (2 w_prev - w_prev2)| <= j dt^2

    Written: the joint channels into ``lower[joints]``, ``upper[joints]``; into ``h`` the base rows
    ``+v_x, -v_x, +v_y, -v_y`` (if ``base_rows``), then the wheels' forward rows, then backward.
    ``scratch``: >= 2 (channels + viable channels) floats.
    """
    n, n_joints, n_wheels = prev.size, joints.size, H0.shape[0]
    if new_tick:
        for i in range(n):
            prev2[i] = prev[i]
    for k in range(n_joints):
        prev[k] = v[joints[k]]
    if base[BASE_X] >= 0:
        x, y, yaw = base[BASE_X], base[BASE_Y], base[BASE_YAW]
        c, s = math.cos(heading), math.sin(heading)
        twist = (c * v[x] + s * v[y], -s * v[x] + c * v[y], v[yaw])
        scale = 1.0
        for k in range(3):
            if abs(twist[k]) > twist_speed[k]:
                scale = min(scale, twist_speed[k] / abs(twist[k]))
        fastest = 0.0
        for i in range(n_wheels):
            u = H0[i, 0] * twist[0] + H0[i, 1] * twist[1] + H0[i, 2] * twist[2]
            prev[n_joints + 2 + i] = u
            fastest = max(fastest, abs(u))
        if fastest > wheel_speed:
            scale = min(scale, wheel_speed / fastest)
        if scale < 1.0:
            for i in range(n_wheels):
                prev[n_joints + 2 + i] *= scale
        prev[n_joints], prev[n_joints + 1] = scale * twist[0], scale * twist[1]
        prev[base[BASE_YAW_CHANNEL]] = scale * twist[2]
    for i in range(n):
        prev[i] = min(max(prev[i], -speed[i]), speed[i])
    box_lower, box_upper = scratch[:n], scratch[n:2 * n]
    for i in range(n):
        step = accel[i] * dt
        box_lower[i] = max(prev[i] - step, -speed[i])
        box_upper[i] = min(prev[i] + step, speed[i])
    k = viable.size
    distance, braking = scratch[2 * n:2 * n + k], scratch[2 * n + k:2 * n + 2 * k]
    for j in range(k):
        distance[j] = position_upper[j] - q[viable_q[j]]
    braking_speed(distance, viable_accel, dt, braking)
    for j in range(k):
        i = viable[j]
        box_upper[i] = min(box_upper[i], max(braking[j], box_lower[i]))
        distance[j] = q[viable_q[j]] - position_lower[j]
    braking_speed(distance, viable_accel, dt, braking)
    for j in range(k):
        i = viable[j]
        box_lower[i] = max(box_lower[i], min(-braking[j], box_upper[i]))
    for i in range(n):
        step = jerk[i] * (dt * dt)
        center = 2.0 * prev[i] - prev2[i]
        low = min(max(center - step, box_lower[i]), box_upper[i])
        high = max(min(center + step, box_upper[i]), box_lower[i])
        box_lower[i], box_upper[i] = low, high
    for k in range(n_joints):
        lower[joints[k]] = box_lower[k]
        upper[joints[k]] = box_upper[k]
    row = 0
    if base_rows:
        h[0], h[1] = box_upper[n_joints], -box_lower[n_joints]
        h[2], h[3] = box_upper[n_joints + 1], -box_lower[n_joints + 1]
        row = 4
    for i in range(n_wheels):
        h[row + i] = box_upper[n_joints + 2 + i]
        h[row + n_wheels + i] = -box_lower[n_joints + 2 + i]
