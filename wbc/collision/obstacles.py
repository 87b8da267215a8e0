"""Obstacles in the world frame: :class:`Sphere`, :class:`Box`, :class:`Capsule`, :class:`Plane`.

An obstacle is a shape fixed in the world that the robot must keep clear of. Each one may be
moved between ticks -- through ``obstacle.pose = T`` (a 4x4 world pose, every kind) or its own
setters (``sphere.center = ...``, ``box.size = ...``, ``capsule.set_points(p0, p1)``,
``plane.set(normal, offset)``) -- and the distances computed afterwards use the new place: the
obstacle writes its row of the shape table (:mod:`wbc.collision.layout`) into every table that
holds it, so a tick reads obstacles without a Python loop over them. Every value is checked
when it is set (finite, sizes > 0, a rotation for a pose, a non-zero normal) and a bad one raises
:class:`~wbc.core.errors.InvalidInputError` naming the argument; the obstacle keeps its previous place.
"""

from __future__ import annotations

import copy
import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.errors import InvalidInputError
from ..core.validation import as_pose, as_positive, as_vector, direction
from ..model.robot import rpy_matrix
from . import layout


class Obstacle:
    """Base of the obstacle shapes: a row of the shape table (world frame, joint 0) and the
    views of that row in the tables of the distance computations that use the obstacle."""

    kind: int

    def __init__(self, name: str | None) -> None:
        if name is not None and not isinstance(name, str):
            raise InvalidInputError(f"name must be a string, got {type(name).__name__}")
        self.name = name
        self._row = np.zeros(layout.ROW)
        self._row[layout.KIND] = self.kind
        self._views: list[NDArray[np.float64]] = []

    @property
    def pose(self) -> NDArray[np.float64]:
        """World pose (4x4) of the shape's frame (a new array); assign a pose to move the shape rigidly."""
        pose = np.eye(4)
        pose[:3, :3] = self._row[layout.ROTATION].reshape(3, 3)
        pose[:3, 3] = self._row[layout.TRANSLATION]
        return pose

    @pose.setter
    def pose(self, value: ArrayLike) -> None:
        pose = as_pose(value, f"{type(self).__name__}.pose")
        self._place(pose[:3, :3], pose[:3, 3])
        self._publish()

    def bind(self, view: NDArray[np.float64]) -> None:
        """Let ``view`` (a row of a shape table) follow this obstacle from now on."""
        view[:] = self._row
        self._views.append(view)

    def row(self) -> NDArray[np.float64]:
        """The obstacle's row of the shape table (a copy)."""
        return self._row.copy()

    # -------------------------------------------------------------- internals
    def _place(self, rotation: NDArray[np.float64], translation: NDArray[np.float64]) -> None:
        self._row[layout.ROTATION] = rotation.ravel()
        self._row[layout.TRANSLATION] = translation
        self._row[layout.BOUND_CENTER] = 0.0

    def _publish(self) -> None:
        for view in self._views:
            view[:] = self._row

    def __getstate__(self) -> dict[str, Any]:
        """Copies and pickles: the shape and its name, followed by no table."""
        state = dict(self.__dict__)
        state["_views"] = []
        return state

    def __copy__(self) -> Obstacle:
        return copy.deepcopy(self)

    def __repr__(self) -> str:
        name = "" if self.name is None else f"{self.name!r}, "
        return f"{type(self).__name__}({name}{self._describe()})"

    def _describe(self) -> str:  # pragma: no cover - every subclass overrides it
        return ""


def _point(value: ArrayLike, name: str) -> NDArray[np.float64]:
    return as_vector(value, 3, name).astype(np.float64, copy=True)


def _frame_along(axis: NDArray[np.float64]) -> NDArray[np.float64]:
    """A rotation whose z column is the unit vector ``axis``."""
    helper = np.array([1.0, 0.0, 0.0]) if abs(axis[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(helper, axis)
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(axis, x), axis])


class Sphere(Obstacle):
    """The ball of ``radius`` [m] about ``center`` (world, [m]).

    Raises:
        InvalidInputError: a centre that is not 3 finite numbers, a radius not finite and > 0.
    """

    kind = layout.SPHERE

    def __init__(self, center: ArrayLike, radius: float, name: str | None = None) -> None:
        super().__init__(name)
        self._place(np.eye(3), _point(center, "Sphere center"))
        self.radius = radius

    @property
    def center(self) -> NDArray[np.float64]:
        """Centre [m], world (a copy)."""
        return self._row[layout.TRANSLATION].copy()

    @center.setter
    def center(self, value: ArrayLike) -> None:
        self.set_center(value)

    def set_center(self, center: ArrayLike) -> None:
        """Move the sphere to ``center`` [m], world."""
        self._row[layout.TRANSLATION] = _point(center, "Sphere center")
        self._publish()

    @property
    def radius(self) -> float:
        """Radius [m]."""
        return float(self._row[layout.RADIUS])

    @radius.setter
    def radius(self, value: float) -> None:
        radius = as_positive(value, "Sphere radius")
        self._row[layout.RADIUS] = self._row[layout.BOUND_RADIUS] = radius
        self._publish()

    def _describe(self) -> str:
        return f"center={self.center.tolist()}, radius={self.radius}"


class Box(Obstacle):
    """A box of edge lengths ``size`` [m] (along its own x, y, z) centred at the origin of ``pose``
    (4x4 world pose).

    Raises:
        InvalidInputError: a pose that is not a finite 4x4 rigid transform, a size not three
            finite numbers > 0.
    """

    kind = layout.BOX

    def __init__(self, pose: ArrayLike, size: ArrayLike, name: str | None = None) -> None:
        super().__init__(name)
        self.pose = pose
        self.size = size

    @property
    def size(self) -> NDArray[np.float64]:
        """Edge lengths [m] along the box's x, y, z (a copy)."""
        return 2.0 * self._row[layout.HALF_EXTENTS]

    @size.setter
    def size(self, value: ArrayLike) -> None:
        self.set_size(value)

    def set_size(self, size: ArrayLike) -> None:
        """Resize the box (edge lengths [m], centre and orientation kept)."""
        edges = _point(size, "Box size")
        if not np.all(edges > 0.0):
            raise InvalidInputError(f"Box size must be three edge lengths > 0 [m], got {edges.tolist()}")
        self._row[layout.HALF_EXTENTS] = edges / 2.0
        self._row[layout.BOUND_RADIUS] = direction(edges)[1] / 2.0  # (inf past ~1e308: never culled)
        self._publish()

    def _describe(self) -> str:
        return f"center={self._row[layout.TRANSLATION].tolist()}, size={self.size.tolist()}"


class Capsule(Obstacle):
    """The points within ``radius`` [m] of the segment from ``p0`` to ``p1`` (world, [m]); its
    pose has z along the segment and its origin at the segment's midpoint.

    Raises:
        InvalidInputError: end points that are not 3 finite numbers, a radius not finite and > 0.
    """

    kind = layout.CAPSULE

    def __init__(self, p0: ArrayLike, p1: ArrayLike, radius: float, name: str | None = None) -> None:
        super().__init__(name)
        self.set_points(p0, p1)
        self.radius = radius

    def set_points(self, p0: ArrayLike, p1: ArrayLike) -> None:
        """Put the segment's ends at ``p0`` and ``p1`` [m], world (they may coincide: a sphere)."""
        start, end = _point(p0, "Capsule p0"), _point(p1, "Capsule p1")
        with np.errstate(over="ignore"):  # (an inf difference: refused below)
            axis, length = direction(end - start)
        if not math.isfinite(length):
            raise InvalidInputError(f"Capsule p0, p1 are too far apart: {start.tolist()}, {end.tolist()}")
        self._place(_frame_along(np.array([0.0, 0.0, 1.0]) if axis is None else axis), start / 2.0 + end / 2.0)
        self._row[layout.HALF_LENGTH] = length / 2.0
        self._row[layout.BOUND_RADIUS] = length / 2.0 + self._row[layout.RADIUS]
        self._publish()

    @property
    def points(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The segment's ends ``(p0, p1)`` [m], world (copies)."""
        axis = self._row[layout.ROTATION].reshape(3, 3)[:, 2] * self._row[layout.HALF_LENGTH]
        middle = self._row[layout.TRANSLATION]
        return middle - axis, middle + axis

    @property
    def radius(self) -> float:
        """Radius [m]."""
        return float(self._row[layout.RADIUS])

    @radius.setter
    def radius(self, value: float) -> None:
        radius = as_positive(value, "Capsule radius")
        self._row[layout.RADIUS] = radius
        self._row[layout.BOUND_RADIUS] = self._row[layout.HALF_LENGTH] + radius
        self._publish()

    def _describe(self) -> str:
        p0, p1 = self.points
        return f"p0={p0.tolist()}, p1={p1.tolist()}, radius={self.radius}"


class Plane(Obstacle):
    """The plane ``normal·x = offset`` (world); the obstacle is the half-space below it,
    ``normal·x <= offset``, and ``normal`` points to the free side (a floor:
    ``Plane((0, 0, 1), height)``). A normal that is not of unit length is normalised, and the
    offset with it (the same plane). Its pose has z along the normal and its origin at the plane's
    point nearest the world origin.

    Raises:
        InvalidInputError: a normal that is not 3 finite numbers or is zero, an offset not finite.
    """

    kind = layout.PLANE

    def __init__(self, normal: ArrayLike, offset: float, name: str | None = None) -> None:
        super().__init__(name)
        self.set(normal, offset)

    def set(self, normal: ArrayLike, offset: float) -> None:
        """Move the plane to ``normal·x = offset``."""
        given = _point(normal, "Plane normal")
        unit, length = direction(given)
        if unit is None:
            raise InvalidInputError(f"Plane normal must be a non-zero vector, got {given.tolist()}")
        if not math.isfinite(length):
            raise InvalidInputError(f"Plane normal {given.tolist()} is too long (its length overflows): give a unit "
                                    "normal and the offset along it")
        distance = as_vector([offset], 1, "Plane offset")[0] / length
        self._place(_frame_along(unit), unit * distance)
        self._publish()

    @property
    def normal(self) -> NDArray[np.float64]:
        """Unit normal, pointing to the free side (a copy)."""
        return self._row[layout.ROTATION].reshape(3, 3)[:, 2].copy()

    @property
    def offset(self) -> float:
        """``normal·x`` of the plane's points [m]."""
        return float(self.normal @ self._row[layout.TRANSLATION])

    def _describe(self) -> str:
        return f"normal={self.normal.tolist()}, offset={self.offset}"


#: the keys of an obstacle's table in a scenario file, by type (besides ``type`` and ``name``)
TABLE_KEYS = {"Sphere": ("center", "radius"), "Box": ("center", "size", "rpy"), "Capsule": ("p0", "p1", "radius"),
              "Plane": ("normal", "offset")}


def obstacle_from_table(table: object, label: str = "obstacle") -> Obstacle:
    """An obstacle from its table in a scenario file (world frame, [m], [rad])::

        { type = "Sphere", center = [x, y, z], radius = r }
        { type = "Box", center = [x, y, z], size = [sx, sy, sz], rpy = [roll, pitch, yaw] }   (rpy optional)
        { type = "Capsule", p0 = [x, y, z], p1 = [x, y, z], radius = r }
        { type = "Plane", normal = [nx, ny, nz], offset = h }

    each with an optional ``name``.

    Raises:
        InvalidInputError: not a table, an unknown type or key, a missing key, a bad value
            (named, with ``label``).
    """
    if not isinstance(table, dict):
        raise InvalidInputError(f"{label}: expected a table such as {{ type = \"Sphere\", center = [0.5, 0, 0.4], "
                                f"radius = 0.1 }}, got {table!r}")
    kind = table.get("type")
    if kind not in TABLE_KEYS:
        raise InvalidInputError(f"{label}: type {kind!r} unknown (known: {', '.join(TABLE_KEYS)})")
    allowed = (*TABLE_KEYS[kind], "type", "name")
    for key in table:
        if key not in allowed:
            raise InvalidInputError(f"{label} ({kind}): unknown key {key!r} (keys: {', '.join(allowed)})")
    required = [key for key in TABLE_KEYS[kind] if key != "rpy" and key not in table]
    if required:
        raise InvalidInputError(f"{label} ({kind}): required key {required[0]!r} missing")
    name = table.get("name")
    try:
        if kind == "Sphere":
            return Sphere(table["center"], table["radius"], name=name)
        if kind == "Capsule":
            return Capsule(table["p0"], table["p1"], table["radius"], name=name)
        if kind == "Plane":
            return Plane(table["normal"], table["offset"], name=name)
        pose = np.eye(4)
        pose[:3, 3] = _point(table["center"], "Box center")
        pose[:3, :3] = rpy_matrix(*_point(table.get("rpy", (0.0, 0.0, 0.0)), "Box rpy"))
        return Box(pose, table["size"], name=name)
    except InvalidInputError as exc:
        raise InvalidInputError(f"{label}: {exc}") from exc


__all__ = ["Obstacle", "Sphere", "Box", "Capsule", "Plane", "obstacle_from_table", "TABLE_KEYS"]
