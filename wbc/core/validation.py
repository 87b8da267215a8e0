"""Checks at the API boundary: everything that enters wbc is validated here, once.

All checks raise :class:`~wbc.core.errors.InvalidInputError` with a message that names
the offending argument, before any kinematics or solver code runs.
"""

from __future__ import annotations

import math
from typing import TypeVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..runtime import kernels
from .errors import InvalidInputError

ROTATION_TOLERANCE = kernels.ROTATION_TOLERANCE  # max |R^T R - I| and |det R - 1| accepted for a rotation
#: [m] the largest absolute coordinate of a polygon's vertex (a base footprint, a polygon obstacle, a support
#: polygon): the products of areas and turn tests stay finite (1e150 squared is 1e300)
MAX_COORDINATE = 1e150
_FLOAT64 = np.dtype(np.float64)
_Item = TypeVar("_Item")


def _real_array(value: ArrayLike, shape: tuple[int, ...] | None, name: str) -> NDArray[np.float64]:
    """``value`` as a float64 array of ``shape`` (None: its own); complex, non-numeric or misshapen
    input is refused."""
    try:
        converted = np.asarray(value)  # (once: a list is converted here, and again only to look at its items)
    except (TypeError, ValueError) as exc:  # e.g. ragged nested lists
        raise InvalidInputError(f"{name} must be an array{'' if shape is None else f' of shape {shape}'} (numbers, "
                                f"not ragged nested lists), got {_describe(value)}") from exc
    kind = converted.dtype.kind
    if kind == "c":
        raise InvalidInputError(f"{name} must be real, got complex values")
    # (numpy reads a list [1.0, True] as floats: a list's items are looked at one by one)
    if kind in "bOUSV" and not (kind == "O" and _all_real(value)) or (
            kind in "iuf" and isinstance(value, list | tuple) and not _all_real(value)):
        raise InvalidInputError(f"{name} must be numeric (int or float, not true/false), got {_describe(value)}")
    try:
        array = converted.astype(np.float64, copy=False)
    except (TypeError, ValueError) as exc:
        raise InvalidInputError(f"{name} must be numeric, got {_describe(value)}") from exc
    if shape is not None and array.shape != shape:
        raise InvalidInputError(f"{name} must have shape {shape}, got {array.shape}")
    return array


def real_array(value: ArrayLike, name: str) -> NDArray[np.float64]:
    """``value`` as a float64 array of its own shape; complex, boolean, non-numeric or ragged input
    is refused (:class:`InvalidInputError` naming ``name``)."""
    return _real_array(value, None, name)


def polygon_vertices(value: ArrayLike, name: str) -> NDArray[np.float64]:
    """``value`` as an (m, 2) float64 array (a copy) of m >= 3 finite vertices (x, y) [m], each
    coordinate within :data:`MAX_COORDINATE` (a polygon's area and turn tests stay finite);
    complex, boolean, non-numeric or ragged input is refused (:class:`InvalidInputError` naming
    ``name``)."""
    polygon = np.array(real_array(value, name))
    if polygon.ndim != 2 or polygon.shape[1] != 2 or polygon.shape[0] < 3:
        raise InvalidInputError(f"{name} must be an (m, 2) array of m >= 3 vertices (x, y) [m], got shape "
                                f"{polygon.shape}")
    if not np.all(np.isfinite(polygon)):
        raise InvalidInputError(f"{name} contains NaN or inf")
    if np.abs(polygon).max() > MAX_COORDINATE:
        raise InvalidInputError(f"{name} has a vertex beyond {MAX_COORDINATE:g} m (its area and turn tests would "
                                "overflow): give the vertices in metres")
    return polygon


def _all_real(value: ArrayLike) -> bool:
    """True for an object array / nested list holding only real numbers (not bools)."""
    items = np.asarray(value, dtype=object).ravel()
    return all(isinstance(x, (int, float, np.integer, np.floating)) and not isinstance(x, (bool, np.bool_))
               for x in items)


def _describe(value: object) -> str:
    if isinstance(value, np.ndarray):
        return f"an array of dtype {value.dtype}"
    return f"{type(value).__name__} {value!r}"[:80]


def finite_weights(size: int) -> NDArray[np.float64]:
    """Weights ``w`` (size) for the finiteness screen ``math.isfinite(x.dot(w))`` of a float64
    vector ``x`` of ``size`` entries: true iff every entry is finite, and never a numpy warning.

    ``w_i = 2^-k`` with ``2^k >= size``: scaling by a power of two is exact, and
    ``|x . w| <= max |x_i|``, so the dot product cannot overflow (``x . x`` does from
    ``|x| ~ 1e154`` on, which numpy reports as a RuntimeWarning); it is NaN or inf iff some
    entry is. The same cost as ``x . x``. The arrays are shared: never write into them.
    """
    weights = _FINITE_WEIGHTS.get(size)
    if weights is None:
        weights = np.full(size, 2.0 ** -math.ceil(math.log2(max(size, 1))))
        weights.flags.writeable = False
        _FINITE_WEIGHTS[size] = weights
    return weights


_FINITE_WEIGHTS: dict[int, NDArray[np.float64]] = {}


def all_finite(x: NDArray[np.float64]) -> bool:
    """Whether every entry of the float64 vector ``x`` is finite (:func:`finite_weights`)."""
    return math.isfinite(x.dot(finite_weights(x.size)))


def direction(vector: NDArray[np.float64]) -> tuple[NDArray[np.float64] | None, float]:
    """``(vector / |vector|, |vector|)`` without overflow: the vector is scaled by its largest
    entry first, so entries near 1e308 keep their direction (``np.linalg.norm`` would overflow to
    inf and the quotient to 0); ``|vector|`` itself may be inf then. ``(None, 0.0)`` for the zero
    vector, ``(None, inf)`` for one with an inf entry (no direction either way)."""
    scale = float(np.max(np.abs(vector)))
    if not (scale > 0.0 and math.isfinite(scale)):
        return None, (0.0 if scale == 0.0 else math.inf)
    scaled = vector / scale
    length = float(np.linalg.norm(scaled))  # in [1, sqrt(size)]
    return scaled / length, scale * length


def as_vector(value: ArrayLike, size: int, name: str) -> NDArray[np.float64]:
    """Return ``value`` as a finite float64 vector of length ``size``.

    Fast path for the control loop: a float64 array of the right shape is checked
    with one dot product that cannot overflow (:func:`finite_weights`).
    """
    if type(value) is np.ndarray and value.dtype is _FLOAT64 and value.shape == (size,):
        array = value
    else:
        array = _real_array(value, (size,), name)
    weights = _FINITE_WEIGHTS.get(size)  # (finite_weights(size), without the call on the control loop's path)
    if not math.isfinite(array.dot(finite_weights(size) if weights is None else weights)):
        raise InvalidInputError(f"{name} contains NaN or inf: {array}")
    return array


def as_weights(value: ArrayLike, size: int, name: str) -> NDArray[np.float64]:
    """Return a scalar or per-axis cost as a non-negative finite vector of length ``size``."""
    array = _real_array(value, None, name)
    if array.ndim == 0:
        array = np.full(size, float(array))
    array = as_vector(array, size, name)
    if np.any(array < 0.0):
        raise InvalidInputError(f"{name} must be >= 0, got {array}")
    return array


def as_number(value: object, name: str) -> float:
    """Return a real scalar (int or float, not bool or str) as a float."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise InvalidInputError(f"{name} must be a number, got {_describe(value)}")
    return float(value)


def as_positive(value: float, name: str) -> float:
    """Return ``value`` as a finite float > 0."""
    number = as_number(value, name)
    if not np.isfinite(number) or number <= 0.0:
        raise InvalidInputError(f"{name} must be finite and > 0, got {value!r}")
    return number


def as_nonnegative(value: float, name: str) -> float:
    """Return ``value`` as a finite float >= 0."""
    number = as_number(value, name)
    if not np.isfinite(number) or number < 0.0:
        raise InvalidInputError(f"{name} must be finite and >= 0, got {value!r}")
    return number


def as_items(value: object, kind: type[_Item], name: str) -> list[_Item]:
    """``value`` (a list or tuple of ``kind``) as a list; a single item or anything else is refused."""
    if isinstance(value, kind):
        raise InvalidInputError(f"{name} must be a list of {kind.__name__}s, got a single {type(value).__name__}: "
                                f"write {name}=[...]")
    if not isinstance(value, (list, tuple)):
        raise InvalidInputError(f"{name} must be a list of {kind.__name__}s, got {_describe(value)}")
    for item in value:
        if not isinstance(item, kind):
            raise InvalidInputError(f"{name}: not a {kind.__name__}: {_describe(item)}")
    return list(value)


def as_flag(value: object, name: str) -> bool:
    """Return a boolean option; anything but a bool (e.g. the string ``"false"``) is refused."""
    if not isinstance(value, (bool, np.bool_)):
        raise InvalidInputError(f"{name} must be True or False, got {value!r}")
    return bool(value)


def as_speed_limit(value: float | None, name: str) -> float:
    """Return an optional speed bound: ``None`` means unbounded (inf), else a finite float > 0."""
    return np.inf if value is None else as_positive(value, name)


def as_gain(value: float, name: str = "gain") -> float:
    """Return a per-tick gain in (0, 1]."""
    gain = as_positive(value, name)
    if gain > 1.0:
        raise InvalidInputError(f"{name} must lie in (0, 1], got {gain}")
    return gain


def as_pose(value: ArrayLike, name: str) -> NDArray[np.float64]:
    """Return a 4x4 homogeneous transform, checking finiteness and that R is a rotation.

    Fast path for the control loop: a float64 (4, 4) array is checked by one compiled call
    (:func:`wbc.runtime.kernels.pose_defect`); the messages come from the checks below.
    """
    if type(value) is np.ndarray and value.dtype is _FLOAT64 and value.shape == (4, 4):
        try:
            if kernels.pose_defect(value, ROTATION_TOLERANCE) == kernels.POSE_OK:
                return value
        except TypeError:  # a read-only array (the kernel takes writable ones): the checks below
            pass
    pose = _real_array(value, (4, 4), name)
    if not np.all(np.isfinite(pose)):
        raise InvalidInputError(f"{name} contains NaN or inf")
    if np.max(np.abs(pose[3] - (0.0, 0.0, 0.0, 1.0))) > 1e-12:
        raise InvalidInputError(f"{name}: last row must be [0, 0, 0, 1], got {pose[3]}")
    rotation = pose[:3, :3]
    with np.errstate(over="ignore", invalid="ignore"):  # huge entries: the defect is inf, said below
        orthogonality = np.max(np.abs(rotation.T @ rotation - np.eye(3)))
    if not orthogonality <= ROTATION_TOLERANCE:
        raise InvalidInputError(f"{name}: the 3x3 block is not a rotation matrix: its columns are not orthonormal "
                                f"(|R^T R - I| = {orthogonality:.2e})")
    determinant = np.linalg.det(rotation)
    if abs(determinant - 1.0) > ROTATION_TOLERANCE:  # orthonormal, so det = -1
        raise InvalidInputError(f"{name}: the 3x3 block has determinant {determinant:.6g}: a reflection, not a "
                                "rotation matrix (det +1); flip the sign of one axis (column)")
    return pose
