"""A mobile base that keeps its footprint clear of 2-D obstacles: points (a laser scan, replaced
every tick) and polygons in the world frame; velocity-damper rows on the base velocity only."""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..constraints.constraint import Constraint, ConstraintData, ConstraintRows
from ..core.errors import InvalidInputError
from ..core.settings import Operand
from ..core.validation import as_gain, as_positive, polygon_vertices, real_array
from ..model.kinematics import Kinematics
from ..model.mobile_base import BaseKind
from ..model.robot import Robot
from ..model.tick_context import TickContext
from .avoidance import INERT, DistanceMargins
from .braking import RowBraking
from .layout import GAIN, GRID_CELL_START, GRID_CELLS, GRID_ORDERED, GRID_POINTS

if TYPE_CHECKING:  # pragma: no cover
    from ..runtime.compiled_op import CompiledOp
    from ..runtime.program import TickProgram

#: [m] spacing of the points that stand for a polygon obstacle's edges: the footprint keeps
#: ``min_distance - POLYGON_SPACING / 2`` from the edges themselves (a corner between two samples)
POLYGON_SPACING = 0.01
#: the most points a wall or a polygon edge is cut into (16 MB of points: a 20 km wall at 2 cm)
MAX_SEGMENT_POINTS = 1_000_000
_MIN_CELLS = 1024  # grid cells allocated at least (grown with the points: 4 per point)


def as_polygon(value: ArrayLike, name: str) -> NDArray[np.float64]:
    """``value`` as a simple polygon, an (m, 2) float array with m >= 3 vertices [m], returned
    counter-clockwise (a clockwise one is reversed).

    Raises:
        InvalidInputError: not an (m, 2) finite array, fewer than 3 vertices, zero area, repeated
            vertices or crossing edges (not a simple polygon).
    """
    polygon = polygon_vertices(value, name)
    following = np.roll(polygon, -1, axis=0)
    edges = following - polygon
    if np.any(np.hypot(edges[:, 0], edges[:, 1]) <= 1e-9):
        raise InvalidInputError(f"{name}: two consecutive vertices coincide; give each corner once")
    m = len(polygon)
    for i in range(m):
        for j in range(i + 2, m):
            if i == 0 and j == m - 1:
                continue  # adjacent through the closing edge
            if _segments_cross(polygon[i], following[i], polygon[j], following[j]):
                raise InvalidInputError(f"{name} is not a simple polygon: edge {i} crosses edge {j}; give the "
                                        "vertices in order around the boundary")
    area = 0.5 * float(np.sum(polygon[:, 0] * following[:, 1] - following[:, 0] * polygon[:, 1]))
    if abs(area) <= 1e-12:
        raise InvalidInputError(f"{name} has zero area: give the corners of a polygon, not points on a line")
    return polygon if area > 0 else polygon[::-1].copy()


def _segments_cross(a: NDArray[np.float64], b: NDArray[np.float64], c: NDArray[np.float64],
                    d: NDArray[np.float64]) -> bool:
    def side(p: NDArray[np.float64], q: NDArray[np.float64], r: NDArray[np.float64]) -> float:
        return float((q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0]))
    return side(a, b, c) * side(a, b, d) <= 0.0 and side(c, d, a) * side(c, d, b) <= 0.0


def _pieces(a: NDArray[np.float64], b: NDArray[np.float64], spacing: float, what: str) -> int:
    """How many pieces of at most ``spacing`` [m] the segment ``a``-``b`` takes (>= 1); refused
    beyond :data:`MAX_SEGMENT_POINTS` (endpoints near 1e308: an inf length, refused)."""
    with np.errstate(over="ignore"):  # (an inf difference: too many points, refused below)
        difference = b - a
    count = math.hypot(*difference) / spacing
    if not count <= MAX_SEGMENT_POINTS:
        raise InvalidInputError(f"{what} from {a.tolist()} to {b.tolist()} at most {spacing:g} m apart would take "
                                f"more than {MAX_SEGMENT_POINTS} points: give a larger spacing or a shorter segment")
    return max(math.ceil(count), 1)


def polygon_boundary_points(polygon: NDArray[np.float64], spacing: float = POLYGON_SPACING) -> NDArray[np.float64]:
    """Points along the edges of ``polygon`` at most ``spacing`` apart, its vertices included."""
    pieces = []
    for a, b in zip(polygon, np.roll(polygon, -1, axis=0), strict=True):
        count = _pieces(a, b, spacing, "a polygon edge's points")
        pieces.append(a + np.outer(np.arange(count) / count, b - a))
    return np.concatenate(pieces)


def wall_points(start: ArrayLike, end: ArrayLike, spacing: float = 0.02) -> NDArray[np.float64]:
    """Points every ``spacing`` [m] (at most) from ``start`` to ``end`` (both included), e.g. a wall
    as a laser scan sees it."""
    a = np.asarray(start, dtype=np.float64)
    b = np.asarray(end, dtype=np.float64)
    if a.shape != (2,) or b.shape != (2,) or not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
        raise InvalidInputError(f"a wall's start and end must be finite points (x, y) [m], got {start!r}, {end!r}")
    spacing = as_positive(spacing, "spacing")
    count = _pieces(a, b, spacing, "a wall's points")
    return a + np.outer(np.linspace(0.0, 1.0, count + 1), b - a)


class BaseFootprintAvoidance(DistanceMargins, Constraint):
    """Keep the mobile base's footprint at least ``min_distance`` from 2-D obstacles in the world
    frame: points (a laser scan, replaced every tick if need be by
    :meth:`~wbc.collision.footprint.BaseFootprintAvoidance.set_points`) and polygons.

    For an obstacle point p and the chassis pose (x, y, theta): ``p_b = R(theta)^T (p - (x, y))``,
    d its signed distance to the footprint polygon (< 0 inside), n the unit normal at the
    closest footprint point (``n = grad_{p_b} d``). With ``J = [[0, -1], [1, 0]]``::

        d_dot = -n . R^T (xdot, ydot) - omega n . (J p_b)

    and the velocity damper ``-d_dot <= gain (d - min_distance) / dt`` on the base columns of v
    (``robot.base.indices``; the reduced form of a nonholonomic base maps the rows through its
    input map like any row). To first order the margin ``d - min_distance`` shrinks at most by the
    fraction ``gain`` per tick; from ``d < min_distance`` the base is pushed out at that rate. A
    synchro drive's chassis does not turn with its heading (the steering angle): its footprint
    stays aligned with the world axes (theta = 0, no omega column).

    **Rows.** ``capacity`` rows, one per angular sector about the footprint's centroid: the closest
    point of each sector within ``detection_distance`` gets its sector's row (a wall and a box on
    two sides both get rows), the other rows are inert (``G = 0``, ``h = 1``). Soft
    (``hard = False``) like :class:`~wbc.CollisionAvoidance`.

    **Cost.** The points are bucketed into a uniform grid when they are set (``O(N)``); a tick
    visits only the cells within ``detection_distance`` of the footprint's bounding circle
    (docs/collision.md gives measured costs).

    Args:
        footprint: the footprint polygon in the base frame [m], (m, 2) vertices around the boundary
            (counter-clockwise; a clockwise one is reversed), convex or simple.
        points: initial obstacle points, an (N, 2) array in the world frame [m] (None: none).
        polygons: fixed obstacle polygons in the world frame [m]; their edges are sampled every
            :data:`POLYGON_SPACING` m, so the footprint keeps ``min_distance - POLYGON_SPACING / 2``
            from the edges.
        min_distance: [m] >= 0, the clearance kept.
        detection_distance: [m] > ``min_distance``: farther points get no row.
        gain: fraction (0, 1] of the margin one tick may consume.
        capacity: number of rows (angular sectors), >= 1. The default 64 gives each sector about one
            point of a scan every 5 cm near the base (docs/collision.md: a turning base along a
            sparse scan loses margin on the points a sector's closest one hides; 16 sectors cost
            10.8 of a 20 mm margin, 64 sectors 0.35 mm).

    Raises:
        InvalidInputError: a footprint or polygon that is not a simple polygon, points that are not
            a finite (N, 2) array, a distance or gain out of range (named); at bind, a fixed base.
    """

    gain = Operand("_settings", GAIN, as_gain)
    hard = False

    def __init__(self, footprint: ArrayLike, points: ArrayLike | None = None,
                 polygons: Sequence[ArrayLike] | None = None, min_distance: float = 0.05,
                 detection_distance: float = 0.5, gain: float = 0.5, capacity: int = 64,
                 name: str | None = None) -> None:
        super().__init__(name)
        self.footprint = as_polygon(footprint, "footprint")
        self._set_margins(min_distance, detection_distance)
        self.gain = gain
        if isinstance(capacity, bool) or not isinstance(capacity, int | np.integer) or capacity < 1:
            raise InvalidInputError(f"capacity must be an int >= 1 (rows, one per angular sector), got {capacity!r}")
        self.capacity = int(capacity)
        if polygons is not None and not isinstance(polygons, list | tuple):
            raise InvalidInputError(f"polygons must be a list of (m, 2) vertex arrays, got {polygons!r}")
        self.polygons = [as_polygon(p, f"polygons[{k}]") for k, p in enumerate(polygons or [])]
        self._fixed = (np.concatenate([polygon_boundary_points(p) for p in self.polygons]) if self.polygons
                       else np.zeros((0, 2)))
        self._cell = 0.5 * self.detection_distance  # grid cell side [m]
        self._scan = np.zeros((0, 2))  # the current scan, copied (grown when a larger one comes)
        self._n_scan = 0
        self._cell_of = np.zeros(0, dtype=np.int64)
        self._cell_start = np.zeros(_MIN_CELLS + 1, dtype=np.int64)
        self._ordered = np.zeros((0, 2))  # fixed and scan points in grid order
        self._meta = np.zeros(5)  # grid (x0, y0, cell, nx, ny)
        self._n_points = 0
        #: what the tick program's op reads the points through (footprint_kernels.GRID_*): the addresses of
        #: the buffers above, which set_points replaces when a scan outgrows them, and the counts
        self._grid = np.zeros(4, dtype=np.int64)
        self.set_points(np.zeros((0, 2)) if points is None else points)

    def set_points(self, points: ArrayLike) -> None:
        """Replace the obstacle points (the scan): an (N, 2) array in the world frame [m]; N = 0
        means none (the polygons remain). Copied, and bucketed into the grid (``O(N)``; no
        allocation unless N exceeds every earlier scan).

        Raises:
            InvalidInputError: not an (N, 2) array, or a NaN/inf point (its index is named): the
                previous points stay in force.
        """
        if type(points) is np.ndarray and points.dtype == np.float64:  # a scan from a driver: no conversion
            scan = np.ascontiguousarray(points)
        else:  # (numbers only: complex, bool, strings refused; not copied: the kernel copies)
            scan = np.ascontiguousarray(real_array(points, "points"))
        if scan.size == 0:
            scan = scan.reshape(0, 2)
        if scan.ndim != 2 or scan.shape[1] != 2:
            raise InvalidInputError(f"points must be an (N, 2) array of (x, y) [m], got shape {scan.shape}")
        from . import footprint_kernels as kernels  # compiled on first use, never by ``import wbc``

        n, total = scan.shape[0], self._fixed.shape[0] + scan.shape[0]
        ordered, cell_of, cell_start = self._ordered, self._cell_of, self._cell_start
        if total > ordered.shape[0]:  # grown (kept only when the scan is valid)
            ordered, cell_of = np.zeros((total, 2)), np.zeros(total, dtype=np.int64)
            cell_start = np.zeros(max(4 * total, _MIN_CELLS) + 1, dtype=np.int64)
        built = kernels.build_grid(self._fixed, scan, n, self._cell, cell_of, cell_start, ordered,
                                   self._meta)  # checks every point before it writes anything
        if built < 0:
            raise InvalidInputError(f"points[{-built - 1}] is {scan[-built - 1]} (NaN or inf): a scan must be "
                                    "finite; drop invalid returns (e.g. out-of-range readings) before set_points "
                                    "(the previous points stay in force)")
        if n > self._scan.shape[0]:
            self._scan = np.zeros((n, 2))
        self._scan[:n] = scan
        self._ordered, self._cell_of, self._cell_start = ordered, cell_of, cell_start
        self._n_scan, self._n_points = n, built
        self._point_grid()

    def _point_grid(self) -> None:
        """:attr:`_grid`: this object's point buffers' addresses and counts."""
        grid = self._grid
        grid[GRID_ORDERED], grid[GRID_CELL_START] = self._ordered.ctypes.data, self._cell_start.ctypes.data
        grid[GRID_POINTS], grid[GRID_CELLS] = self._n_points, self._cell_start.size

    def __setstate__(self, state: dict[str, Any]) -> None:
        """Copies and pickles: the grid points to the copy's own buffers."""
        self.__dict__.update(state)
        self._point_grid()

    @property
    def points(self) -> NDArray[np.float64]:
        """The current scan points (a read-only view), (N, 2) [m]."""
        view = self._scan[:self._n_scan]
        view.flags.writeable = False
        return view

    def bind(self, robot: Robot) -> BaseFootprintAvoidanceData:
        return BaseFootprintAvoidanceData(self, robot)

    def __repr__(self) -> str:
        return (f"BaseFootprintAvoidance(footprint={self.footprint.tolist()}, points=<{self._n_scan} points>, "
                f"polygons=<{len(self.polygons)}>, min_distance={self.min_distance}, "
                f"detection_distance={self.detection_distance}, gain={self.gain}, capacity={self.capacity})")


class BaseFootprintAvoidanceData(ConstraintData):
    """:class:`BaseFootprintAvoidance` in one controller: the base's columns, and each sector's
    closest point of the last tick (:attr:`closest`)."""

    constraint: BaseFootprintAvoidance

    def __init__(self, avoidance: BaseFootprintAvoidance, robot: Robot) -> None:
        super().__init__(avoidance)
        if not robot.base.is_mobile:
            raise InvalidInputError(f"{avoidance.name}: robot '{robot.name}' has a {robot.base.name} base; "
                                    "BaseFootprintAvoidance keeps a ground base on (x, y, heading) clear (use "
                                    "CollisionAvoidance for an arm)")
        from . import footprint_kernels as kernels

        self._kernels = kernels
        self.n_inequalities = avoidance.capacity
        self._columns = np.array(robot.base.indices, dtype=np.int64)
        self._heading = robot.base.indices[2]
        #: the chassis turns with the heading (a synchro drive's does not: the heading steers its wheels)
        self._turns = 0.0 if robot.base.kind is BaseKind.SYNCHRO else 1.0
        vertices = avoidance.footprint
        self._edges = np.zeros((len(vertices), kernels.EDGE_COLUMNS))
        kernels.edge_table(np.ascontiguousarray(vertices), self._edges)
        centroid = vertices.mean(axis=0)
        self._shape = np.r_[centroid, np.max(np.linalg.norm(vertices - centroid, axis=1))]
        self._pose = np.array([0.0, 0.0, 0.0, self._turns])  # the chassis (x, y, theta), then _turns (the op's)
        angles = -np.pi + 2 * np.pi * np.arange(self.n_inequalities) / self.n_inequalities
        self._sectors = np.array([kernels.diamond_angle(np.cos(a), np.sin(a)) for a in angles])
        self._sectors[0] = 0.0  # -pi exactly (cos(-pi), sin(-pi) = -1, -1.2e-16 would give ~4)
        #: per sector: (d, n_b (2), p_b (2), point index) of the last tick's closest point (d = inf: none)
        self.closest = np.full((self.n_inequalities, kernels.BEST_COLUMNS), np.inf)
        self._braking = RowBraking(self.n_inequalities)  # with acceleration bounds in the stack

    def use_context(self, context: TickContext) -> None:
        self._braking.use_context(context)

    def write_static(self, rows: ConstraintRows) -> None:
        rows.G[:] = 0.0
        rows.h[:] = INERT

    def add_ops(self, program: TickProgram, kin: Kinematics, rows: ConstraintRows) -> bool:
        """The rows as one op of the tick program (:func:`footprint_op`) when the kinematics are the
        compiled chain's (its configuration the program's) and no acceleration bounds ask for
        braking (:class:`~wbc.collision.braking.RowBraking`, in Python); else :meth:`compute` every tick.
        (Warns here, where the stack is known, when the detection distance is shorter than the
        braking distance: :meth:`~wbc.collision.braking.RowBraking.check_detection`.)"""
        avoidance = self.constraint
        self._braking.check_detection(kin.robot, avoidance.name, avoidance.detection_distance, avoidance.min_distance)
        if not (kin.native and rows.G.flags.c_contiguous and not self._braking.active):
            return False
        program.add(footprint_op(), grid=avoidance._grid, meta=avoidance._meta, edges=self._edges, shape=self._shape,
                    q=kin.q, pose=self._pose, settings=avoidance._settings, columns=self._columns,
                    sectors=self._sectors, best=self.closest, G=rows.G, h=rows.h, vertices=self._edges.shape[0],
                    capacity=self.n_inequalities, nv=rows.G.shape[1], nq=kin.q.shape[0])
        program.keep_alive(avoidance)  # (the buffers the grid's addresses point to)
        return True

    def prepare_compute(self) -> None:
        """Compile what :meth:`compute` calls (:func:`~wbc.collision.footprint_kernels.footprint_rows`)."""
        from ..runtime.kernels._lazy import compile_named  # (numba: not by ``import wbc``)

        compile_named(self._kernels, "footprint_rows")

    def compute(self, kin: Kinematics, dt: float, rows: ConstraintRows) -> None:
        avoidance, pose = self.constraint, self._pose
        x, y, _ = self._columns
        pose[0], pose[1], pose[2] = kin.q[x], kin.q[y], kin.q[self._heading] * self._turns
        self._kernels.footprint_rows(avoidance._ordered, avoidance._cell_start, avoidance._meta, avoidance._n_points,
                                     self._edges, self._shape, pose, self._turns, avoidance._settings, dt,
                                     self._columns, self._sectors, self.closest, rows.G, rows.h)
        self._braking.apply(kin.q, rows.G, rows.h, avoidance.gain, dt)  # with acceleration bounds: in time

    @property
    def min_distance(self) -> float:
        """The smallest signed distance [m] of the last tick's points to the footprint (inf when
        none was within the detection distance)."""
        return float(self.closest[:, 0].min())

    def row_labels(self) -> list[str]:
        """``"sector k"`` of each row (its closest point's distance when it has one)."""
        return [f"sector {k} (d = {d:.3f} m)" if np.isfinite(d) else f"sector {k} (no point)"
                for k, d in enumerate(self.closest[:, 0].tolist())]


@functools.cache
def footprint_op() -> CompiledOp:
    """The op of the tick program that computes a :class:`BaseFootprintAvoidance`'s rows
    (:func:`wbc.collision.footprint_kernels.footprint_op`): compiled once per process, when a
    controller first uses it."""
    from ..runtime.compiled_op import CompiledOp
    from . import footprint_kernels as kernels

    return CompiledOp("BASE_FOOTPRINT", kernels.footprint_op, (
        ("grid", (4,), "int64"), ("meta", (5,)), ("edges", ("vertices", kernels.EDGE_COLUMNS)), ("shape", (3,)),
        ("q", ("nq",)), ("pose", (4,)), ("settings", (3,)), ("columns", (3,), "int64"), ("sectors", ("capacity",)),
        ("best", ("capacity", kernels.BEST_COLUMNS)), ("G", ("capacity", "nv")), ("h", ("capacity",)),
        ("vertices", None), ("capacity", None), ("nv", None), ("nq", None)),
        checks=("vertices >= 3", "capacity >= 1", "nq >= 3", "nv >= 3"))
