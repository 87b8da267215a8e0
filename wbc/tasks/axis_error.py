"""The rotation that turns one unit vector onto another, and its derivative (LookAtTask, AxisAlignTask).

For unit vectors ``a`` (an axis of a frame) and ``d`` (where it should point), with
``s = a x d``, ``c = a . d``, ``sigma = |s|``, the angle-axis error is::

    theta = atan2(sigma, c),   n = s / sigma,   e = theta n        # [rad]

the rotation about ``n`` (perpendicular to both) that turns ``a`` onto ``d``. Its
differential ``de = E_a da + E_d dd`` follows from ``ds = da x d + a x dd``,
``dc = d . da + a . dd`` and ``dtheta = c n . ds - sigma dc``::

    K = (theta/sigma) (I - n n^T) + c n n^T
    E_a = -K [d]x - sigma n d^T,     E_d = K [a]x - sigma n a^T

Aligned (``sigma -> 0``, ``c > 0``): ``K -> I``, so ``E_a = -[d]x``, ``E_d = [a]x``, ``e = 0``.
Opposed (``sigma -> 0``, ``c < 0``) the axis of the half turn is undefined: ``n`` is then a
fixed unit vector perpendicular to ``a``, ``e = pi n``, and only the rate of ``theta`` about
``n`` is kept (``K = -n n^T``): the rows turn the axis about ``n``, off the unstable point.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.errors import InvalidInputError
from ..core.validation import as_vector, direction

#: below this ``|a x d|`` the vectors count as aligned or opposed (the limits above)
PARALLEL = 1e-9
#: an axis shorter than this is refused (no direction)
MIN_AXIS_NORM = 1e-9


def as_unit_axis(value: ArrayLike, name: str) -> NDArray[np.float64]:
    """``value`` (3 finite numbers, not zero) scaled to unit length."""
    axis = as_vector(value, 3, name)
    unit, norm = direction(axis)  # (entries near 1e308 keep their direction)
    if unit is None or not norm > MIN_AXIS_NORM:
        raise InvalidInputError(f"{name} must be a non-zero direction (3 numbers, e.g. [0, 0, 1]), got {axis}")
    return unit


def skew(x: np.ndarray) -> NDArray[np.float64]:
    """``[x]x``, the matrix of ``y -> x cross y``."""
    return np.array([[0.0, -x[2], x[1]], [x[2], 0.0, -x[0]], [-x[1], x[0], 0.0]])


def axis_error(a: np.ndarray, d: np.ndarray, error: np.ndarray) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Write ``e = theta n`` (turning unit ``a`` onto unit ``d``) into ``error`` (3); return
    ``(E_a, E_d)``, the 3 x 3 partial derivatives of ``e`` (module docstring)."""
    s = np.cross(a, d)
    c = float(a @ d)
    sigma = math.hypot(*s.tolist())
    if sigma > PARALLEL:
        n = s / sigma
        theta = math.atan2(sigma, c)
        nn = np.outer(n, n)
        k = (theta / sigma) * (np.eye(3) - nn) + c * nn
        error[:] = theta * n
        return -k @ skew(d) - sigma * np.outer(n, d), k @ skew(a) - sigma * np.outer(n, a)
    if c > 0.0:
        error[:] = s  # theta n to first order (zero when exactly aligned)
        return -skew(d), skew(a)
    n = perpendicular(a)
    error[:] = math.pi * n
    nn = np.outer(n, n)
    return nn @ skew(d), -nn @ skew(a)


def perpendicular(a: np.ndarray) -> NDArray[np.float64]:
    """A unit vector perpendicular to unit ``a``, always the same for the same ``a``."""
    helper = np.zeros(3)
    helper[int(np.argmin(np.abs(a)))] = 1.0
    n = np.cross(a, helper)
    return n / np.linalg.norm(n)
