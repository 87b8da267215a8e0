"""The robot's collision geometry: Pinocchio's ``GeometryModel`` of the URDF's ``<collision>``
elements, its shapes in the table of :mod:`wbc.collision.layout`, and the pairs of links that
may collide.

**Capsules.** URDF has no capsule element: a capsule is written as a ``<cylinder>`` with a
``<sphere>`` of the same radius centred on each end of its axis (the shipped models do). The union
of the three is exactly the capsule, so :class:`RobotGeometry` reads such a triple back as one
capsule (one ``coal.Capsule`` in the geometry model, one row of the table). Spheres, capsules and
boxes have compiled distances (:mod:`wbc.collision.kernels`); any other shape (a cylinder alone,
a mesh, a convex hull) is kept as coal loaded it and measured by coal.

**Pairs.** Every two shapes on different joints are a candidate pair, except
(1) *adjacent* links -- one joint the parent of the other's in the kinematic tree (links joined
by a fixed joint share a joint and are no pair at all) --, (2) pairs *always in contact*: in
contact at every one of ``samples`` configurations drawn uniformly within the joint limits
(default 1000, seed 0; see :class:`RobotGeometry` for why that is enough), (3) the pairs that an
SRDF's ``<disable_collisions link1="..." link2="..."/>`` names.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ElementTree
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import coal
import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from ..core.errors import InvalidInputError, ModelError
from ..model.meshes import package_dirs as mesh_folders
from ..model.robot import Robot
from . import layout

#: how close [m] a sphere's centre and radius must match a cylinder's end and radius to be read as
#: the cap of a capsule
CAPSULE_TOLERANCE = 1e-9
#: default number of random configurations that decide which pairs are always in contact
CONTACT_SAMPLES = 1000


@dataclass(frozen=True)
class ExcludedPair:
    """A pair of robot shapes that gets no distance, and why."""

    link_a: str
    link_b: str
    reason: str  #: "adjacent", "always in contact" or "SRDF"


class RobotGeometry:
    """The collision shapes of a robot and its candidate self-collision pairs.

    Args:
        robot: the robot; its URDF (``robot.source``) is read for ``<collision>`` elements.
        srdf: optional SRDF file whose ``<disable_collisions>`` pairs get no distance.
        package_dirs: folders where ``package://`` mesh paths are resolved (Pinocchio's
            ``package_dirs``; the URDF's folder and every folder above it, and ``ROS_PACKAGE_PATH``,
            are always searched: :func:`wbc.model.meshes.package_dirs`).
        samples: configurations drawn uniformly within the joint limits (unbounded axes in
            [-1, 1]) to find the pairs that are always in contact. A pair in contact at every
            sample is excluded; a pair that is free in a fraction f of the joint space survives
            all samples with probability 1 - (1 - f)^samples: with 1000 samples, a pair free in
            0.5 % of the space is kept with probability 0.993, and one free in 1 % with
            probability 0.99996. A pair free in less is in contact almost everywhere: rows for it
            would confine the robot to that sliver, the modelling error the exclusion is for.
        seed: seed of the sampling (the result is reproducible).

    Raises:
        ModelError: the robot has no URDF, its URDF no ``<collision>`` element (the message
            names the fix), a mesh that cannot be loaded, an SRDF that cannot be read or names
            a link the robot lacks.
    """

    def __init__(self, robot: Robot, srdf: str | Path | None = None, package_dirs: Sequence[str | Path] = (),
                 samples: int = CONTACT_SAMPLES, seed: int = 0) -> None:
        if isinstance(samples, bool) or not isinstance(samples, int) or samples < 1:
            raise InvalidInputError(f"samples must be an int >= 1, got {samples!r}")
        self.robot = robot
        loaded = _load_collision_model(robot, package_dirs)
        self.model: pin.GeometryModel = _merge_capsules(loaded)
        self.names: list[str] = [obj.name for obj in self.model.geometryObjects]
        #: the link (body frame) of each shape
        self.links: list[str] = [robot.model.frames[obj.parentFrame].name for obj in self.model.geometryObjects]
        self.table: NDArray[np.float64] = np.array([_row(obj) for obj in self.model.geometryObjects])
        self.excluded: list[ExcludedPair] = []
        candidates = self._adjacency_filter()
        candidates = self._srdf_filter(candidates, srdf)
        #: the candidate self-collision pairs, as indices of shapes (rows of ``table``)
        self.pairs: list[tuple[int, int]] = self._contact_filter(candidates, samples, seed)

    @property
    def size(self) -> int:
        """Number of shapes."""
        return len(self.names)

    # ------------------------------------------------------------- filters
    def _adjacency_filter(self) -> list[tuple[int, int]]:
        objects, parents = self.model.geometryObjects, self.robot.model.parents
        pairs = []
        for a in range(self.size):
            for b in range(a + 1, self.size):
                joint_a, joint_b = objects[a].parentJoint, objects[b].parentJoint
                if joint_a == joint_b:
                    continue
                if parents[joint_a] == joint_b or parents[joint_b] == joint_a:
                    self._exclude(a, b, "adjacent")
                    continue
                pairs.append((a, b))
        return pairs

    def _srdf_filter(self, pairs: list[tuple[int, int]], srdf: str | Path | None) -> list[tuple[int, int]]:
        if srdf is None:
            return pairs
        disabled = read_disabled_pairs(srdf, set(self.robot.frame_names))
        kept = []
        for a, b in pairs:
            if frozenset((self.links[a], self.links[b])) in disabled:
                self._exclude(a, b, "SRDF")
            else:
                kept.append((a, b))
        return kept

    def _contact_filter(self, pairs: list[tuple[int, int]], samples: int, seed: int) -> list[tuple[int, int]]:
        """Drop the pairs in contact at every sampled configuration (coal's collision test)."""
        if not pairs:
            return pairs
        model = pin.GeometryModel()
        for obj in self.model.geometryObjects:
            model.addGeometryObject(obj)
        for a, b in pairs:
            model.addCollisionPair(pin.CollisionPair(a, b))
        data, robot_data = pin.GeometryData(model), self.robot.model.createData()
        always = np.ones(len(pairs), dtype=bool)
        rng = np.random.default_rng(seed)
        for _ in range(samples):
            q = self.robot.random_configuration(rng)
            pin.computeCollisions(self.robot.model, robot_data, model, data, q, False)
            for k in np.flatnonzero(always).tolist():
                if not data.collisionResults[k].isCollision():
                    always[k] = False
                    data.deactivateCollisionPair(k)  # settled: later samples test the others only
            if not always.any():
                break
        kept = []
        for k, (a, b) in enumerate(pairs):
            if always[k]:
                self._exclude(a, b, "always in contact")
            else:
                kept.append((a, b))
        return kept

    def _exclude(self, a: int, b: int, reason: str) -> None:
        self.excluded.append(ExcludedPair(self.links[a], self.links[b], reason))


# ------------------------------------------------------------------ loading
def _load_collision_model(robot: Robot, package_dirs: Sequence[str | Path]) -> pin.GeometryModel:
    if robot.source is None:
        raise ModelError(f"robot '{robot.name}' has no URDF file to read collision geometry from; load it with "
                         "wbc.load_robot(path) from a URDF with <collision> elements")
    folders = [str(Path(folder)) for folder in package_dirs] + mesh_folders(robot.source)
    try:
        model = pin.buildGeomFromUrdf(robot.model, str(robot.source), pin.GeometryType.COLLISION,
                                      package_dirs=folders)
    except (ValueError, RuntimeError, OSError) as exc:
        raise ModelError(f"{robot.source}: cannot load the collision geometry: {exc} (a package://NAME/... mesh "
                         "is looked up as NAME/... in the URDF's folder and every folder above it, in "
                         "ROS_PACKAGE_PATH, and in RobotGeometry's package_dirs: add the folder that holds NAME "
                         "to ROS_PACKAGE_PATH)") from exc
    if model.ngeoms == 0:
        raise ModelError(f"robot '{robot.name}' has no collision geometry: its URDF {robot.source} has no "
                         "<collision> element that Pinocchio could read; add <collision> elements (box, sphere, "
                         "cylinder, or a capsule written as a cylinder with a sphere on each end) to its links, or "
                         "leave self-collision off")
    return model


def _merge_capsules(model: pin.GeometryModel) -> pin.GeometryModel:
    """The same shapes, each cylinder with a sphere of its radius on both ends of its axis (same
    joint and frame) replaced by one ``coal.Capsule``."""
    objects = list(model.geometryObjects)
    caps: dict[int, tuple[int, int]] = {}
    used: set[int] = set()
    for index, cylinder in enumerate(objects):
        if not isinstance(cylinder.geometry, coal.Cylinder):
            continue
        radius, half = cylinder.geometry.radius, cylinder.geometry.halfLength
        ends = [cylinder.placement.act(np.array([0.0, 0.0, sign * half])) for sign in (-1.0, 1.0)]
        found = []
        for end in ends:
            match = next((k for k, obj in enumerate(objects)
                          if k not in used and isinstance(obj.geometry, coal.Sphere)
                          and obj.parentJoint == cylinder.parentJoint and obj.parentFrame == cylinder.parentFrame
                          and abs(obj.geometry.radius - radius) <= CAPSULE_TOLERANCE
                          and np.linalg.norm(obj.placement.translation - end) <= CAPSULE_TOLERANCE), None)
            if match is None:
                break
            found.append(match)
            used.add(match)
        if len(found) == 2:
            caps[index] = (found[0], found[1])
        else:
            used.difference_update(found)
    merged = pin.GeometryModel()
    for index, obj in enumerate(objects):
        if index in used:
            continue
        if index in caps:
            capsule = coal.Capsule(obj.geometry.radius, 2.0 * obj.geometry.halfLength)
            obj = pin.GeometryObject(obj.name, obj.parentJoint, obj.parentFrame, obj.placement, capsule)
        merged.addGeometryObject(obj)
    return merged


def _row(obj: pin.GeometryObject) -> NDArray[np.float64]:
    """The table row of a robot shape (layout of :mod:`wbc.collision.layout`)."""
    row = np.zeros(layout.ROW)
    geometry = obj.geometry
    row[layout.JOINT] = obj.parentJoint
    row[layout.ROTATION] = np.asarray(obj.placement.rotation).ravel()
    row[layout.TRANSLATION] = obj.placement.translation
    if isinstance(geometry, coal.Sphere):
        row[layout.KIND], row[layout.RADIUS] = layout.SPHERE, geometry.radius
        row[layout.BOUND_RADIUS] = geometry.radius
    elif isinstance(geometry, coal.Capsule):
        row[layout.KIND], row[layout.RADIUS] = layout.CAPSULE, geometry.radius
        row[layout.HALF_LENGTH] = geometry.halfLength
        row[layout.BOUND_RADIUS] = geometry.radius + geometry.halfLength
    elif isinstance(geometry, coal.Box):
        row[layout.KIND] = layout.BOX
        row[layout.HALF_EXTENTS] = geometry.halfSide
        row[layout.BOUND_RADIUS] = float(np.linalg.norm(geometry.halfSide))
    else:
        row[layout.KIND] = layout.COAL
        geometry.computeLocalAABB()
        low, high = np.asarray(geometry.aabb_local.min_), np.asarray(geometry.aabb_local.max_)
        row[layout.BOUND_CENTER] = (low + high) / 2.0
        row[layout.BOUND_RADIUS] = float(np.linalg.norm(high - low)) / 2.0
    if not all(math.isfinite(x) for x in row):
        raise ModelError(f"collision shape {obj.name!r}: its size or placement is not finite")
    return row


def read_disabled_pairs(srdf: str | Path, links: set[str]) -> set[frozenset[str]]:
    """The link pairs of an SRDF's ``<disable_collisions link1="..." link2="..."/>`` elements.

    Raises:
        ModelError: the file cannot be read or parsed, or names a link not in ``links``.
    """
    try:
        root = ElementTree.parse(Path(srdf)).getroot()
    except (OSError, ElementTree.ParseError) as exc:
        raise ModelError(f"cannot read the SRDF {srdf}: {exc}") from exc
    pairs: set[frozenset[str]] = set()
    for element in root.iter("disable_collisions"):
        names = [element.get("link1"), element.get("link2")]
        known = [name for name in names if name is not None and name in links]
        if len(known) != 2:
            missing = next(name for name in names if name not in known)
            raise ModelError(f"{srdf}: <disable_collisions> names link {missing!r}, which the robot does not have")
        pairs.add(frozenset(known))
    return pairs


__all__ = ["RobotGeometry", "ExcludedPair", "read_disabled_pairs", "CONTACT_SAMPLES"]
