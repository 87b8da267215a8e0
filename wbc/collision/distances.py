"""Signed distances of the robot's collision pairs, their witness points and gradient rows.

:class:`Distances` holds the shape table (the robot's shapes, then the obstacles' rows, which
the obstacles keep up to date) and the candidate pairs: the robot's self-collision pairs
(:class:`~wbc.collision.geometry.RobotGeometry`) and every moving robot shape against every
obstacle. :meth:`Distances.compute` fills a :class:`PairBuffers` -- caller-owned arrays of a
fixed capacity -- with the pairs closer than ``detection_distance``: one compiled call
(:func:`wbc.collision.kernels.pair_distances`) for the broad phase, the exact distances of
spheres, capsules, boxes (apart or overlapping) and planes and every row; coal measures the
other pairs (cylinders, meshes) in Python, only when they pass the broad phase.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import coal
import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike, NDArray

from ..core.errors import InvalidInputError
from ..core.validation import as_items, as_positive
from ..model.kinematics import Kinematics, fill_kinematics
from ..model.robot import Robot
from ..runtime import kernels as runtime_kernels
from . import layout
from .geometry import RobotGeometry
from .obstacles import Obstacle
from .reach import lever_bounds

#: coal's GJK tolerance on the coal path [m]
COAL_GJK_TOLERANCE = 1e-9


@dataclass
class PairBuffers:
    """Caller-owned results of :meth:`Distances.compute`: entries ``0..count-1`` are valid.

    ``pair`` indexes :attr:`Distances.pairs` (and :attr:`Distances.labels`); ``distance`` [m] is
    signed (< 0: penetration depth); ``witness_a``, ``witness_b`` are the witness points (world)
    on the pair's first and second shape and ``normal`` the unit vector from a to b, with
    ``witness_b - witness_a = distance * normal``; ``rows[i] = grad d(q)^T`` (1 x nv): d grows
    by ``rows[i] @ v * dt`` to first order when the robot moves at velocity v for dt.
    """

    pair: NDArray[np.int64]
    distance: NDArray[np.float64]
    witness_a: NDArray[np.float64]
    witness_b: NDArray[np.float64]
    normal: NDArray[np.float64]
    rows: NDArray[np.float64]
    count: int = 0
    #: the pairs that coal measures this call (internal; one entry per candidate pair)
    pending: NDArray[np.int64] = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    #: (pair, pending) in one array, ``pair`` and ``pending`` its views (internal: one kernel argument)
    index: NDArray[np.int64] = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    #: (witness_a, witness_b, normal) in one array, those three its views (internal: one kernel argument)
    points: NDArray[np.float64] = field(default_factory=lambda: np.zeros((3, 0, 3)))

    @classmethod
    def allocate(cls, capacity: int, nv: int, pairs: int) -> PairBuffers:
        """Buffers for at most ``capacity`` entries of a robot with ``nv`` velocity coordinates and
        ``pairs`` candidate pairs."""
        index, points = np.zeros(capacity + max(1, pairs), dtype=np.int64), np.zeros((3, capacity, 3))
        return cls(index[:capacity], np.zeros(capacity), points[0], points[1], points[2], np.zeros((capacity, nv)),
                   pending=index[capacity:], index=index, points=points)

    @property
    def capacity(self) -> int:
        """Number of entries."""
        return self.distance.size


class Distances:
    """The collision pairs of a robot and its obstacles, and their distances per configuration.

    Args:
        robot: the robot.
        obstacles: :class:`~wbc.collision.obstacles.Obstacle` objects (world frame); they may move
            between calls.
        self_collision: measure the robot's self-collision pairs too.
        detection_distance: [m] pairs farther apart get no entry.
        capacity: entries of :meth:`buffers` (default: every candidate pair, so none is ever
            dropped); when more pairs are within ``detection_distance``, the closest are kept.
        geometry: the robot's :class:`~wbc.collision.geometry.RobotGeometry` (built from its URDF
            when not given: pass one to share it, or to give an SRDF).
        prepare: compile the kernels :meth:`compute` calls now (seconds on the first start after an
            install, then read from numba's cache); False: at the first :meth:`compute` (a
            :class:`~wbc.collision.CollisionAvoidance` compiles the ones its controller calls).

    Raises:
        InvalidInputError: ``obstacles`` not a list of obstacles, ``detection_distance`` or
            ``capacity`` not > 0.
        ModelError: the robot has no collision geometry (see
            :class:`~wbc.collision.geometry.RobotGeometry`).
    """

    def __init__(self, robot: Robot, obstacles: Sequence[Obstacle] = (), self_collision: bool = True,
                 detection_distance: float = 0.3, capacity: int | None = None,
                 geometry: RobotGeometry | None = None, *, prepare: bool = True) -> None:
        from . import kernels  # (never imported by ``import wbc``; its kernels compile when prepared)

        self._kernels = kernels
        self.robot = robot
        self.obstacles = as_items(list(obstacles) if isinstance(obstacles, tuple) else obstacles, Obstacle,
                                  "obstacles")
        self.detection_distance = as_positive(detection_distance, "detection_distance")
        self.geometry = geometry if geometry is not None else RobotGeometry(robot)
        geometry = self.geometry
        robot_rows = geometry.size
        self.table = np.zeros((robot_rows + len(self.obstacles), layout.ROW))
        self.table[:robot_rows] = geometry.table
        names = list(geometry.links)
        for index, obstacle in enumerate(self.obstacles):
            obstacle.bind(self.table[robot_rows + index])
            names.append(obstacle.name or f"{layout.KIND_NAMES[obstacle.kind]}{index}")
        pairs = list(geometry.pairs) if self_collision else []
        moving = [s for s in range(robot_rows) if geometry.table[s, layout.JOINT] != 0]
        pairs += [(s, robot_rows + index) for index in range(len(self.obstacles)) for s in moving]
        #: candidate pairs: rows of ``table`` (a, b); an obstacle is always b
        self.pairs = np.array([(a, b, k) for k, (a, b) in enumerate(pairs)], dtype=np.int64).reshape(-1, 3)
        #: "link_a↔link_b" (an obstacle by its name, or kind and index: "sphere0")
        self.labels = [f"{names[a]}↔{names[b]}" for a, b in pairs]
        self.capacity = max(1, len(pairs)) if capacity is None else _as_capacity(capacity)
        self._coal_shapes: dict[int, tuple[tuple[float, ...], coal.CollisionGeometry]] = {}
        self._support = _support(robot.model)
        #: per pair and velocity coordinate, a bound of how fast the coordinate moves the pair's shape
        #: at any configuration (:func:`~wbc.collision.reach.lever_bounds`): the pairs' reach
        self.levers = lever_bounds(robot.model, self.table, self.pairs, self._support)
        self._world = np.zeros((self.table.shape[0], self._kernels.POSE_COLUMNS))
        self._scratch = np.zeros(layout.SCRATCH)
        self._entry = np.zeros(10)  # one pair measured by coal: (d, w_a, w_b, normal)
        self._kinematics = Kinematics(robot)
        if self._kinematics.native:
            runtime_kernels.prepare("forward_kinematics")  # compute() calls it (kinematics.update): compiled now
            self._placements = self._kinematics.placements
            self._jacobians_t = self._kinematics.joint_jacobians.T
        else:
            self._placements = np.zeros((robot.model.njoints, 12))
            self._jacobians_t = np.zeros((robot.nv, 6))
        self._request, self._result = coal.DistanceRequest(), coal.DistanceResult()
        # GJK converges from above on curved shapes (cylinders): coal's default 1e-6 leaves the
        # witness points, and so the rows, ~1e-3 off; 1e-9 brings them to ~1e-4 (relative)
        self._request.gjk_tolerance = COAL_GJK_TOLERANCE
        self._transforms = coal.Transform3s(), coal.Transform3s()
        self._prepared = False
        if prepare:
            self.prepare()

    def prepare(self) -> None:
        """Compile the kernels :meth:`compute` calls, if not yet: the distances, and coal's pairs'
        entries when some pair has no compiled distance (:func:`~wbc.collision.kernels.insert_pair`)."""
        if not self._prepared:
            from ..runtime.kernels._lazy import compile_named  # (numba: not by ``import wbc``)

            compile_named(self._kernels, "pair_distances", *(() if compiled_pairs_only(self) else ("insert_pair",)))
            self._prepared = True

    def buffers(self) -> PairBuffers:
        """Result arrays of this object's capacity."""
        return PairBuffers.allocate(self.capacity, self.robot.nv, self.pairs.shape[0])

    def compute(self, q: ArrayLike, out: PairBuffers) -> int:
        """Fill ``out`` with the pairs within ``detection_distance`` at configuration ``q``.

        Returns:
            The number of entries (also ``out.count``).

        Raises:
            InvalidInputError: a malformed ``q``, buffers of another capacity or robot.
        """
        kinematics = self._kinematics
        kinematics.update(self.robot.check_configuration(q))
        if not kinematics.native:
            fill_kinematics(kinematics.data, self._placements, self._jacobians_t)
        return self.compute_from(self._placements, self._jacobians_t, out)

    def compute_from(self, placements: NDArray[np.float64], jacobians_t: NDArray[np.float64],
                     out: PairBuffers) -> int:
        """:meth:`compute` from this tick's joint placements and Jacobians, in the layouts of
        :class:`wbc.model.kinematics.Kinematics` (``placements``: njoints x 12, rotation column-major
        then translation; ``jacobians_t``: nv x 6, Pinocchio's ``data.J`` transposed), read in place.

        Returns:
            The number of entries (also ``out.count``).

        Raises:
            InvalidInputError: buffers of another capacity or robot.
        """
        if (out.capacity != self.capacity or out.rows.shape[1] != self.robot.nv
                or out.pending.size < self.pairs.shape[0]):
            raise InvalidInputError(f"buffers of capacity {out.capacity} and {out.rows.shape[1]} columns; this "
                                    f"Distances needs {self.capacity} and {self.robot.nv}: use its buffers()")
        self.prepare()
        packed = self._kernels.pair_distances(
            self.table, self.pairs, placements, jacobians_t, self._support, self._world, self.detection_distance,
            out.pair, out.distance, out.witness_a, out.witness_b, out.normal, out.rows, out.pending, self._scratch)
        out.count = self.finish_with_coal(out, packed, jacobians_t) if packed > self.capacity else packed
        return out.count

    def finish_with_coal(self, out: PairBuffers, packed: int, jacobians_t: NDArray[np.float64]) -> int:
        """After a kernel call that returned ``packed`` (count and pairs left for coal): measure
        those pairs with coal, add the ones within the detection distance; returns the count."""
        count, pending = packed % (self.capacity + 1), packed // (self.capacity + 1)
        return self._measure_with_coal(out, count, pending, jacobians_t)

    # ------------------------------------------------------------ the coal path
    def _measure_with_coal(self, out: PairBuffers, count: int, pending: int, jacobians_t: NDArray[np.float64]) -> int:
        """Measure the pairs without a compiled distance with coal and add those within the
        detection distance (keeping the closest when the buffers are full)."""
        entry = self._entry
        for k in out.pending[:pending].tolist():
            a, b, _ = self.pairs[k].tolist()
            entry[0] = self._coal_distance(a, b, entry)
            if entry[0] < self.detection_distance:
                count = self._kernels.insert_pair(k, entry, count, self.table, self.pairs, self._support, jacobians_t,
                                                  out.pair, out.distance, out.witness_a, out.witness_b, out.normal,
                                                  out.rows)
        return count

    def _coal_distance(self, a: int, b: int, entry: NDArray[np.float64]) -> float:
        """coal's signed distance of shapes a and b (world poses of the last kernel call); the
        witness points and normal go to ``entry[1:10]``."""
        for transform, shape in zip(self._transforms, (a, b), strict=True):
            pose = self._world[shape]
            transform.setRotation(pose[:9].reshape(3, 3))
            transform.setTranslation(pose[9:12])
        result = self._result
        result.clear()
        coal.distance(self.coal_shape(a), self._transforms[0], self.coal_shape(b), self._transforms[1],
                      self._request, result)
        entry[1:4] = result.getNearestPoint1()
        entry[4:7] = result.getNearestPoint2()
        entry[7:10] = result.normal
        return float(result.min_distance)

    def coal_shape(self, shape: int) -> coal.CollisionGeometry:
        """coal's geometry of row ``shape`` of ``table``, in its local frame (the coal path,
        and the oracle of the tests)."""
        if shape < self.geometry.size:
            return self.geometry.model.geometryObjects[int(shape)].geometry
        row = self.table[shape]
        key = tuple(row[[layout.KIND, layout.RADIUS, layout.HALF_LENGTH, *range(16, 19)]])
        cached = self._coal_shapes.get(shape)
        if cached is None or cached[0] != key:
            cached = self._coal_shapes[shape] = (key, _coal_geometry(row))
        return cached[1]


def _coal_geometry(row: NDArray[np.float64]) -> coal.CollisionGeometry:
    kind = row[layout.KIND]
    if kind == layout.SPHERE:
        return coal.Sphere(row[layout.RADIUS])
    if kind == layout.CAPSULE:
        return coal.Capsule(row[layout.RADIUS], 2.0 * row[layout.HALF_LENGTH])
    if kind == layout.BOX:
        return coal.Box(*(2.0 * row[layout.HALF_EXTENTS]))
    return coal.Halfspace(np.array([0.0, 0.0, 1.0]), 0.0)  # a plane: local z up, through the origin


def _as_capacity(value: object) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise InvalidInputError(f"capacity must be an int >= 1, got {value!r}")
    return int(value)


def _support(model: pin.Model) -> NDArray[np.float64]:
    """``support[j, k] = 1`` when velocity coordinate k moves joint j (its joint or an ancestor's)."""
    support = np.zeros((model.njoints, model.nv))
    for joint in range(1, model.njoints):
        for ancestor in model.supports[joint]:
            if ancestor > 0:
                start = model.joints[ancestor].idx_v
                support[joint, start:start + model.joints[ancestor].nv] = 1.0
    return support


def compiled_pairs_only(distances: Distances) -> bool:
    """Whether every candidate pair of ``distances`` has a compiled distance at every configuration
    (:func:`wbc.collision.kernels.pair_distance`), so that a tick never needs coal: no shape of kind
    ``COAL`` (cylinder, mesh), no two planes."""
    kinds = distances.table[:, layout.KIND][distances.pairs[:, [layout.PAIR_A, layout.PAIR_B]]]
    return not ((kinds == layout.COAL).any() or ((kinds[:, 0] == layout.PLANE) & (kinds[:, 1] == layout.PLANE)).any())


__all__ = ["Distances", "PairBuffers"]
