"""Joint-space kernels: PostureTask and SteeringTask rows, position-limit bounds, heading rows,
the integration of vector-space coordinates.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from . import (
    POSTURE_GAIN,
    POSTURE_SETTINGS,
    STEERING_GAIN,
    STEERING_SETTINGS,
    STEERING_SPEED_SCALE,
    STEERING_WEIGHT,
    prepare_cache,
)
from ._lazy import ENTRY, declared
from .ops import STACK, Op

CACHE = prepare_cache()  # before the first @njit below compiles; False: no writable cache (see wbc.runtime.kernels)

# ---------------------------------------------------------- configuration


# GIL held: see set_frame_pose
@declared("boolean(float64[:], float64[:], float64, float64[::1])", cache=CACHE, **ENTRY)
def integrate_vector_space(q: np.ndarray, v: np.ndarray, dt: float, reached: np.ndarray) -> bool:
    """``reached = q + v dt`` (``pinocchio.integrate`` on coordinates that form a vector space:
    1-DOF revolute and prismatic joints), the control loop's ``robot.integrate`` in one call.
    True when ``q``, ``v`` and ``reached`` have one size, ``dt > 0`` and every entry of ``reached``
    is finite -- which holds only if every entry of ``q`` and ``v`` is (and ``dt`` finite);
    False otherwise (``reached`` then holds no answer: the caller takes its checked path)."""
    n = reached.size
    if q.size != n or v.size != n or not dt > 0.0:
        return False
    screen = 0.0
    for i in range(n):
        value = q[i] + v[i] * dt
        reached[i] = value
        screen += value - value  # NaN for an inf or NaN entry, else 0
    return screen == 0.0


# ------------------------------------------------------------------- tasks


@declared("void(float64[:], float64[:], float64[:], float64[:], float64, float64[:], float64[:])", cache=CACHE,
          nogil=True)
def posture_rows(q: np.ndarray, reference: np.ndarray, weights: np.ndarray, settings: np.ndarray, dt: float,
                 error: np.ndarray, target: np.ndarray) -> None:
    """:class:`~wbc.PostureTask` on a block of 1-DOF joints: ``e = q* - q``, ``target = W gain/dt e``
    (settings layout: ``POSTURE_*``)."""
    scale = settings[POSTURE_GAIN] / dt
    for i in range(len(q)):
        error[i] = reference[i] - q[i]
        target[i] = weights[i] * scale * error[i]


@declared("void(float64[:], float64[:], int64, int64, int64, float64[:], float64, float64[:], float64[:], float64[:])",
          cache=CACHE, nogil=True)
def steering_row(preview: np.ndarray, q: np.ndarray, x: int, y: int, heading: int, parameters: np.ndarray,
                 dt: float, error: np.ndarray, jacobian: np.ndarray, target: np.ndarray) -> None:
    """Row of :class:`~wbc.SteeringTask` from the holonomic ``preview`` velocity:
    ``delta = wrap_[-pi/2, pi/2)(atan2(ydot, xdot) - heading)``, weight
    ``sqrt(cost) min(1, speed / speed_scale)``; ``parameters``: layout ``STEERING_*``."""
    xdot, ydot = preview[x], preview[y]
    speed = math.sqrt(xdot * xdot + ydot * ydot)
    delta = 0.0
    if speed > 0.0:
        delta = math.atan2(ydot, xdot) - q[heading]
        delta = (delta + math.pi / 2) % math.pi - math.pi / 2  # drive forward or backward
    weight = parameters[STEERING_WEIGHT] * min(1.0, speed / parameters[STEERING_SPEED_SCALE])
    error[0] = delta
    for k in range(len(jacobian)):
        jacobian[k] = 0.0
    jacobian[heading] = weight
    target[0] = weight * parameters[STEERING_GAIN] * delta / dt


# ------------------------------------------------------------- constraints


@declared("void(float64[:], float64[:], float64[:], float64, float64, float64[:], float64[:])", cache=CACHE, nogil=True)
def position_limit_bounds(q: np.ndarray, lower_limit: np.ndarray, upper_limit: np.ndarray, gain: float,
                          dt: float, lower: np.ndarray, upper: np.ndarray) -> None:
    """Velocity-damper bounds of :class:`~wbc.JointPositionLimits`: inside the limits the
    fraction ``gain`` of each margin per tick; outside them the full margins (``gain = 1``),
    so the joint may land on the violated limit in one tick and ``lower <= upper`` holds
    whatever the gain (a small gain on one side only would exclude the way back)."""
    for i in range(len(q)):
        low = (lower_limit[i] - q[i]) / dt
        high = (upper_limit[i] - q[i]) / dt
        scale = gain if low <= 0.0 <= high else 1.0
        lower[i] = scale * low
        upper[i] = scale * high


@declared("void(float64[:, :], float64[:, :], float64[:], int64, float64[:, :], int64, int64)", cache=CACHE, nogil=True)
def heading_rows(cos_part: np.ndarray, sin_part: np.ndarray, q: np.ndarray, heading: int, G: np.ndarray,
                 x: int, y: int) -> None:
    """Base-frame rows: columns ``x, y`` of ``G`` = ``cos(q[heading]) A + sin(q[heading]) B``."""
    c, s = math.cos(q[heading]), math.sin(q[heading])
    for r in range(G.shape[0]):
        G[r, x] = c * cos_part[r, 0] + s * sin_part[r, 0]
        G[r, y] = c * cos_part[r, 1] + s * sin_part[r, 1]


# ------------------------------------------------------- tick-program ops


@njit(inline="always")
def _posture(q: np.ndarray, reference: np.ndarray, weights: np.ndarray, settings: np.ndarray, error: np.ndarray,
             stack: np.ndarray, start: int, dim: int, nv: int, rows: int, dt: float) -> None:
    posture_rows(q, reference, weights, settings, dt, error, stack[nv, start:start + dim])


#: PostureTask's targets into columns start:start + dim of the stack (its W J is static)
POSTURE = Op("POSTURE", _posture, (
    ("q", ("dim",)), ("reference", ("dim",)), ("weights", ("dim",)), ("settings", (POSTURE_SETTINGS,)),
    ("error", ("dim",)), STACK, ("start", None), ("dim", None), ("nv", None), ("rows", None)),
    checks=("0 <= start", "start + dim <= rows"))


@njit(inline="always")
def _steering(preview: np.ndarray, q: np.ndarray, x: int, y: int, heading: int, settings: np.ndarray,
              error: np.ndarray, stack: np.ndarray, start: int, nv: int, rows: int, nq: int, dt: float) -> None:
    steering_row(preview, q, x, y, heading, settings, dt, error, stack[:nv, start], stack[nv, start:start + 1])


#: SteeringTask's row into column start of the stack, from the holonomic preview
STEERING = Op("STEERING", _steering, (
    ("preview", ("nv",)), ("q", ("nq",)), ("x", None), ("y", None), ("heading", None),
    ("settings", (STEERING_SETTINGS,)), ("error", (1,)), STACK, ("start", None), ("nv", None), ("rows", None),
    ("nq", None)),
    checks=("0 <= start", "start < rows", "0 <= x < nv", "0 <= y < nv", "0 <= heading < nq"))


@njit(inline="always")
def _position_limits(q: np.ndarray, lower_limit: np.ndarray, upper_limit: np.ndarray, gain: np.ndarray,
                     lower: np.ndarray, upper: np.ndarray, k: int, dt: float) -> None:
    position_limit_bounds(q, lower_limit, upper_limit, gain[0], dt, lower, upper)


#: JointPositionLimits' velocity bounds of k joints
POSITION_LIMITS = Op("POSITION_LIMITS", _position_limits, (
    ("q", ("k",)), ("lower_limit", ("k",)), ("upper_limit", ("k",)), ("gain", (1,)), ("lower", ("k",)),
    ("upper", ("k",)), ("k", None)))


@njit(inline="always")
def _heading_rows(cos_part: np.ndarray, sin_part: np.ndarray, q: np.ndarray, heading: int, G: np.ndarray, rows: int,
                  nq: int, nv: int, x: int, y: int, dt: float) -> None:
    heading_rows(cos_part, sin_part, q, heading, G, x, y)


#: base-frame rows: columns x, y of G rotated by the heading q[heading]
HEADING_ROWS = Op("HEADING_ROWS", _heading_rows, (
    ("cos_part", ("rows", 2)), ("sin_part", ("rows", 2)), ("q", ("nq",)), ("heading", None),
    ("G", ("rows", "nv")), ("rows", None), ("nq", None), ("nv", None), ("x", None), ("y", None)),
    checks=("0 <= heading < nq", "0 <= x < nv", "0 <= y < nv"))
