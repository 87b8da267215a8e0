"""3-D view of closed-loop runs in the browser: live (``wbc run ... --view``) or as a
self-contained HTML replay (``wbc run ... --html FILE``).

Built on `viser <https://viser.studio>`_ (the ``[view]`` extra), which only this module
imports: ``import wbc`` does not load it. What is drawn, per run:

* the robot from its URDF: the URDF's visual geometry (boxes, cylinders, spheres, capsules,
  meshes) on the links that have some, and on the others a *skeleton* -- a cylinder from each
  joint to its child joints and frames, a sphere on each joint it links;
* the reference task's targets: a green marker at the current target (with axes if the
  orientation is tracked) and the whole reference as a thin green line;
* the tool path (the reference task's frame) traced up to the current time;
* obstacles (:class:`Obstacle`, translucent red): those of the scenarios' collision
  avoidance (:func:`scenario_obstacles`: spheres, boxes, capsules, and planes as a thin
  3 m square), where they are when the run starts.

Several runs are overlaid, each robot in its own colour, on one timeline (a run that ends
earlier holds its last configuration).
"""

from __future__ import annotations

import contextlib
import io
import math
import threading
import time
import warnings
from collections import deque
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import BinaryIO, Literal, TypeVar

import numpy as np
import pinocchio as pin
import viser
from numpy.typing import ArrayLike, NDArray

from ..collision import Box, Capsule, CollisionAvoidance, Plane, Sphere
from ..collision.obstacles import Obstacle as CollisionObstacle
from ..model.meshes import package_dirs
from ..model.robot import Robot
from .closed_loop import RunResult, TickObserver, orientation_tracked
from .outputs import HTML_FORMATS, check_output, write_atomically
from .references import ReferenceMotion
from .scenario import Scenario

Colour = tuple[int, int, int]
Run = tuple[Scenario, RunResult]  #: a finished run
PlannedRun = tuple[Scenario, int]  #: a run still to come (streamed into a LiveView): scenario, ticks

#: (robot links, tool path) colour of run number i (cycled)
RUN_COLOURS: tuple[tuple[Colour, Colour], ...] = (
    ((235, 120, 20), (30, 90, 230)),
    ((140, 80, 210), (200, 40, 140)),
    ((20, 160, 150), (110, 110, 20)),
    ((200, 60, 120), (40, 150, 220)),
)
JOINT_COLOUR: Colour = (55, 55, 60)
VISUAL_COLOUR: Colour = (80, 80, 90)  #: URDF visual geometry without a material
TARGET_COLOUR: Colour = (30, 170, 70)
OBSTACLE_COLOUR: Colour = (220, 40, 40)
FPS = 30.0  #: frames per second of the replay (and of the live view's updates)
#: joint poses a replay page records at most (~26 kB of memory each while the page is built):
#: a run longer than this allows at FPS is replayed faster, which the page says. The youBot
#: (9 joints) gets 10 000 frames, 5.5 minutes at FPS; a 48-joint robot 2 000 frames.
MAX_POSES = 100_000


@dataclass(frozen=True)
class Obstacle:
    """A static shape in the world, drawn translucent red.

    ``kind`` and ``size``: ``"box"`` (full extents x, y, z), ``"sphere"`` (radius,),
    ``"cylinder"`` (radius, length; axis along the local z); ``pose``: 4x4 world pose of
    its centre.
    """

    kind: Literal["box", "sphere", "cylinder"]
    size: tuple[float, ...]
    pose: NDArray[np.float64] = field(default_factory=lambda: np.eye(4))

    def __post_init__(self) -> None:
        sizes = {"box": 3, "sphere": 1, "cylinder": 2}
        if self.kind not in sizes:
            raise ValueError(f"obstacle kind must be one of {', '.join(sizes)}, got {self.kind!r}")
        size = tuple(float(s) for s in self.size)
        if len(size) != sizes[self.kind] or not all(0.0 < s < math.inf for s in size):
            raise ValueError(f"a {self.kind} obstacle takes {sizes[self.kind]} finite sizes > 0 [m], got {self.size}")
        pose = np.asarray(self.pose, dtype=np.float64)
        if pose.shape != (4, 4) or not np.all(np.isfinite(pose)):
            raise ValueError("obstacle pose must be a finite 4x4 homogeneous transform")
        object.__setattr__(self, "size", size)
        object.__setattr__(self, "pose", pose)


#: [m] side of the square a Plane obstacle is drawn as, and its thickness (below the plane)
PLANE_SIDE, PLANE_THICKNESS = 3.0, 0.002


def scenario_obstacles(scenarios: Sequence[Scenario]) -> list[Obstacle]:
    """The obstacles of the scenarios' :class:`~wbc.CollisionAvoidance` constraints as drawn
    shapes (each obstacle once, where it is now)."""
    seen: dict[int, CollisionObstacle] = {}
    for scenario in scenarios:
        for constraint in scenario.constraints:
            if isinstance(constraint, CollisionAvoidance):
                seen |= {id(obstacle): obstacle for obstacle in constraint.obstacles}
    return [shape for obstacle in seen.values() for shape in drawn_obstacle(obstacle)]


def drawn_obstacle(obstacle: CollisionObstacle) -> list[Obstacle]:
    """The shapes that draw one collision obstacle (a capsule: a cylinder and two spheres)."""
    pose = obstacle.pose
    if isinstance(obstacle, Sphere):
        return [Obstacle("sphere", (obstacle.radius,), pose)]
    if isinstance(obstacle, Box):
        return [Obstacle("box", tuple(obstacle.size.tolist()), pose)]
    if isinstance(obstacle, Capsule):
        p0, p1 = obstacle.points
        length = float(np.linalg.norm(p1 - p0))
        ends = [Obstacle("sphere", (obstacle.radius,), _translation(p)) for p in (p0, p1)]
        return ([Obstacle("cylinder", (obstacle.radius, length), pose)] if length > 0.0 else []) + ends
    if isinstance(obstacle, Plane):
        below = pose @ _translation([0.0, 0.0, -PLANE_THICKNESS / 2])
        return [Obstacle("box", (PLANE_SIDE, PLANE_SIDE, PLANE_THICKNESS), below)]
    raise TypeError(f"no drawing for a {type(obstacle).__name__} obstacle")

@dataclass(frozen=True)
class Shape:
    """A primitive (or mesh) that moves with one joint of a robot.

    ``placement``: 4x4 pose in the joint frame (a cylinder's axis is its local z);
    ``size``: box extents, (radius, length) of a cylinder, (radius,) of a sphere, the scale
    of a mesh; ``vertices``/``faces``: a mesh's triangles.
    """

    kind: Literal["box", "cylinder", "sphere", "mesh"]
    joint: int  #: Pinocchio joint index (0: the world)
    placement: NDArray[np.float64]
    size: tuple[float, ...]
    colour: Colour
    vertices: NDArray[np.float64] | None = None  #: (n, 3) of a mesh [m], scaled
    faces: NDArray[np.int64] | None = None  #: (m, 3) vertex indices of a mesh's triangles


def robot_shapes(robot: Robot, colour: Colour = RUN_COLOURS[0][0]) -> list[Shape]:
    """What is drawn of ``robot``: its URDF visuals, and a skeleton of cylinders (``colour``)
    and joint spheres on the links without visuals (see the module docstring)."""
    visuals = _urdf_visuals(robot)
    covered = {shape.joint for shape in visuals}
    model = robot.model
    data = model.createData()
    pin.forwardKinematics(model, data, robot.neutral())
    origins = [data.oMi[j].translation.copy() for j in range(model.njoints)]
    ends: dict[int, list[NDArray[np.float64]]] = {j: [] for j in range(model.njoints)}
    for j in range(1, model.njoints):
        ends[model.parents[j]].append(model.jointPlacements[j].translation.copy())
    for frame in model.frames:
        # a frame on a joint origin adds nothing; one elsewhere (a tool tip) is a bone end
        world = data.oMi[frame.parentJoint].act(frame.placement.translation)
        if not any(np.linalg.norm(world - origin) < 1e-6 for origin in origins):
            ends[frame.parentJoint].append(frame.placement.translation.copy())
    bones = [(j, end) for j, joint_ends in ends.items() if j not in covered
             for end in _unique(joint_ends) if np.linalg.norm(end) > 1e-6]
    radius = bone_radius(robot)
    shapes = list(visuals)
    linked: set[int] = set()
    for joint, end in bones:
        shapes.append(Shape("cylinder", joint, _segment_placement(end), (radius, float(np.linalg.norm(end))), colour))
        linked.add(joint)
        linked.update(j for j in range(1, model.njoints)
                      if model.parents[j] == joint and np.allclose(model.jointPlacements[j].translation, end))
    shapes += [Shape("sphere", j, np.eye(4), (1.4 * radius,), JOINT_COLOUR) for j in sorted(linked) if j > 0]
    return shapes + _chassis(robot, covered, radius, colour)


def _chassis(robot: Robot, covered: set[int], radius: float, colour: Colour) -> list[Shape]:
    """A mobile base without visual geometry: a disc under its heading joint, with a nose
    (in ``colour``) pointing along the heading."""
    if not robot.base.is_mobile:
        return []
    model = robot.model
    joints = [next(j for j in range(1, model.njoints) if model.idx_vs[j] == index) for index in robot.base.indices]
    if covered & set(joints):
        return []
    disc, thickness, heading = 8 * radius, 2 * radius, joints[2]
    return [Shape("cylinder", heading, _translation([0.0, 0.0, -thickness / 2]), (disc, thickness), VISUAL_COLOUR),
            Shape("box", heading, _translation([0.75 * disc, 0.0, 0.0]), (0.4 * disc, 0.2 * disc, 1.2 * thickness),
                  colour)]


def bone_radius(robot: Robot) -> float:
    """Radius of the skeleton's cylinders [m]: 3 % of the robot's reach (the farthest joint
    origin or frame from the world origin in the neutral configuration, at least 0.1 m)."""
    data = robot.model.createData()
    pin.forwardKinematics(robot.model, data, robot.neutral())
    pin.updateFramePlacements(robot.model, data)
    reach = max([np.linalg.norm(p.translation) for p in list(data.oMi) + list(data.oMf)] + [0.1])
    return 0.03 * float(reach)


def _unique(points: list[NDArray[np.float64]]) -> list[NDArray[np.float64]]:
    kept: list[NDArray[np.float64]] = []
    for point in points:
        if not any(np.linalg.norm(point - other) < 1e-6 for other in kept):
            kept.append(point)
    return kept


def _segment_placement(end: NDArray[np.float64]) -> NDArray[np.float64]:
    """Placement of a cylinder from the origin to ``end``: centred, z along the segment."""
    z = end / np.linalg.norm(end)
    helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    placement = np.eye(4)
    placement[:3, :3] = np.column_stack([x, np.cross(z, x), z])
    placement[:3, 3] = end / 2
    return placement


def _urdf_visuals(robot: Robot) -> list[Shape]:
    """The URDF's visual geometry as shapes (none for a robot without a URDF file)."""
    if robot.source is None or Path(robot.source).suffix != ".urdf":
        return []
    try:
        geometry = pin.buildGeomFromUrdf(robot.model, str(robot.source), pin.GeometryType.VISUAL,
                                         package_dirs=package_dirs(Path(robot.source)))
    except (RuntimeError, ValueError, OSError) as exc:  # e.g. a mesh file not found
        warnings.warn(f"{robot.source}: visual geometry not loaded ({exc}); drawing the skeleton", stacklevel=2)
        return []
    shapes: list[Shape] = []
    for item in geometry.geometryObjects:
        colour = _colour(item.meshColor) if item.overrideMaterial else VISUAL_COLOUR
        placement, g, kind = item.placement.homogeneous, item.geometry, type(item.geometry).__name__
        if kind == "Box":
            shapes.append(Shape("box", item.parentJoint, placement, tuple(2 * g.halfSide), colour))
        elif kind == "Sphere":
            shapes.append(Shape("sphere", item.parentJoint, placement, (g.radius,), colour))
        elif kind in ("Cylinder", "Capsule"):
            shapes.append(Shape("cylinder", item.parentJoint, placement, (g.radius, 2 * g.halfLength), colour))
            if kind == "Capsule":
                for sign in (-1.0, 1.0):
                    cap = placement @ _translation([0.0, 0.0, sign * g.halfLength])
                    shapes.append(Shape("sphere", item.parentJoint, cap, (g.radius,), colour))
        elif item.meshPath:
            shapes.append(_mesh_shape(item, colour))
        else:
            warnings.warn(f"{robot.source}: visual {item.name!r} of type {kind} is not drawn", stacklevel=2)
    return shapes


def _colour(rgba: ArrayLike) -> Colour:
    """A URDF material's colour (RGB(A) in [0, 1]) in 0-255."""
    red, green, blue = (int(round(255 * c)) for c in np.asarray(rgba, dtype=np.float64)[:3])
    return red, green, blue


def _mesh_shape(item: pin.GeometryObject, colour: Colour) -> Shape:
    import trimesh  # a dependency of viser

    mesh = trimesh.load(item.meshPath, force="mesh")
    assert isinstance(mesh, trimesh.Trimesh)  # force="mesh": a scene is concatenated into one mesh
    return Shape("mesh", item.parentJoint, item.placement.homogeneous, tuple(item.meshScale), colour,
                 vertices=np.asarray(mesh.vertices) * np.asarray(item.meshScale), faces=np.asarray(mesh.faces))


def _corners(shape: Shape) -> NDArray[np.float64]:
    """(8, 3) corners of the box around ``shape`` in its own frame."""
    if shape.kind == "mesh":
        assert shape.vertices is not None  # (a mesh's shape has them: _mesh_shape)
        low, high = shape.vertices.min(axis=0), shape.vertices.max(axis=0)
    else:
        if shape.kind == "box":
            high = np.asarray(shape.size) / 2
        elif shape.kind == "sphere":
            high = np.full(3, shape.size[0])
        else:
            high = np.array([shape.size[0], shape.size[0], shape.size[1] / 2])
        low = -high
    return np.array([[(low, high)[i][0], (low, high)[j][1], (low, high)[k][2]]
                     for i in (0, 1) for j in (0, 1) for k in (0, 1)])


def _translation(p: ArrayLike) -> NDArray[np.float64]:
    transform = np.eye(4)
    transform[:3, 3] = p
    return transform


def _wxyz(rotation: NDArray[np.float64]) -> NDArray[np.float64]:
    x, y, z, w = pin.Quaternion(rotation).coeffs()
    return np.array([w, x, y, z])


def _add_shape(scene: viser.SceneApi, name: str, kind: str, size: tuple[float, ...], colour: Colour,
               placement: NDArray[np.float64], opacity: float | None = None,
               vertices: NDArray[np.float64] | None = None, faces: NDArray[np.int64] | None = None) -> None:
    position, wxyz = placement[:3, 3], _wxyz(placement[:3, :3])
    if kind == "box":
        scene.add_box(name, colour, np.asarray(size), opacity=opacity, position=position, wxyz=wxyz)
    elif kind == "sphere":
        scene.add_icosphere(name, size[0], colour, opacity=opacity, position=position, wxyz=wxyz)
    elif kind == "cylinder":
        scene.add_cylinder(name, size[0], size[1], colour, opacity=opacity, position=position, wxyz=wxyz)
    else:
        assert vertices is not None and faces is not None  # (a mesh's shape has them: _mesh_shape)
        scene.add_mesh_simple(name, vertices, faces, color=colour, opacity=opacity, position=position, wxyz=wxyz)


class _RunTrack:
    """One run in the scene: its robot's joint frames, its target marker and tool path.

    Built before the run (:meth:`record` then receives its configurations as they come: the
    live view) or from a finished run (:meth:`from_result`); it shows what has been recorded."""

    def __init__(self, server: viser.ViserServer, index: int, scenario: Scenario, ticks: int,
                 orientation_tracked: bool, stride: int, dt: float | None = None):
        # ``ticks`` rows of ``dt`` seconds (default: the scenario's period; a long run's
        # RunResult keeps one row per RunResult.stride ticks)
        self.server, self.scenario, self.stride = server, scenario, stride
        self.dt = scenario.dt if dt is None else dt
        robot, self.root = scenario.robot, f"/run{index}"
        robot_colour, self.path_colour = RUN_COLOURS[index % len(RUN_COLOURS)]
        self.model, self.data = robot.model, robot.model.createData()
        self.ticks = ticks  # the last configuration is q[ticks]
        self.q = np.tile(scenario.q0, (ticks + 1, 1))
        self.recorded = 0  #: q[0 .. recorded] are known
        task = scenario.reference_task
        self.tool_frame = None if task is None else task.frame
        self.tool_path = None if task is None else np.zeros((ticks + 1, 3))
        self.shapes = shapes = robot_shapes(robot, robot_colour)
        self.frames = {j: server.scene.add_frame(f"{self.root}/j{j}", show_axes=False)
                       for j in sorted({shape.joint for shape in shapes})}
        self.scale = bone_radius(robot)
        for n, shape in enumerate(shapes):
            _add_shape(server.scene, f"{self.root}/j{shape.joint}/s{n}", shape.kind, shape.size, shape.colour,
                       shape.placement, vertices=shape.vertices, faces=shape.faces)
        self.reference_points: NDArray[np.float64] | None = None  #: the reference's target points
        self.target_marker: viser.FrameHandle | None = None  #: at the current target
        if scenario.reference is not None:
            self.reference_points = points = np.array([
                _position(_target(scenario.reference, k * self.dt)) for k in [*range(0, ticks, stride), ticks]])
            server.scene.add_line_segments(f"{self.root}/reference", np.stack([points[:-1], points[1:]], axis=1),
                                           TARGET_COLOUR, thickness=0.3 * self.scale)
            self.target_marker = server.scene.add_frame(
                f"{self.root}/target", show_axes=orientation_tracked, axes_length=4 * self.scale,
                axes_radius=0.2 * self.scale)
            # larger than the tool's bone: a halo around a tool on target
            server.scene.add_icosphere(f"{self.root}/target/ball", 1.8 * self.scale, TARGET_COLOUR, opacity=0.6)
        self.path_segments: list[viser.LineSegmentsHandle] = []
        self.shown_segments = 0
        self.record(0, scenario.q0)

    @classmethod
    def from_result(cls, server: viser.ViserServer, index: int, scenario: Scenario, result: RunResult,
                    stride: int) -> _RunTrack:
        """The track of a finished run (every configuration recorded), ``stride`` rows per segment."""
        track = cls(server, index, scenario, result.time.size, result.orientation_tracked, stride,
                    dt=result.stride * scenario.dt)
        track.q[:] = result.q
        if track.tool_path is not None:
            track.tool_path[:] = result.tool_path
        track.recorded = track.ticks
        track._extend_path()
        return track

    def record(self, k: int, q: NDArray[np.float64]) -> None:
        """The run reached ``q`` = q[k] (``k`` counts up from 0, one tick at a time)."""
        self.q[k] = q
        if self.tool_path is not None and self.tool_frame is not None:  # as wbc.app.closed_loop.run records it
            self.tool_path[k] = self.scenario.robot.frame_pose(self.q[k], self.tool_frame)[:3, 3]
        self.recorded = k
        self._extend_path()

    def _extend_path(self) -> None:
        """Add the tool path's segments (``stride`` ticks each, hidden until shown) that the
        recorded ticks complete."""
        if self.tool_path is None:
            return
        start = len(self.path_segments) * self.stride
        while start < self.ticks and min(start + self.stride, self.ticks) <= self.recorded:
            points = self.tool_path[start:min(start + self.stride, self.ticks) + 1]
            self.path_segments.append(self.server.scene.add_line_segments(
                f"{self.root}/path/{start}", np.stack([points[:-1], points[1:]], axis=1), self.path_colour,
                thickness=0.6 * self.scale, visible=False))
            start += self.stride


    def tick(self, t: float) -> int:
        """The tick shown at time ``t`` [s]: the last one recorded for t past it."""
        return min(max(int(round(t / self.dt)), 0), self.recorded)

    def show(self, t: float) -> None:
        """Move the robot, target and tool path to time ``t`` [s]."""
        k = self.tick(t)
        pin.forwardKinematics(self.model, self.data, self.q[k])
        for j, frame in self.frames.items():
            placement = self.data.oMi[j]
            frame.position, frame.wxyz = placement.translation, _wxyz(placement.rotation)
        reference, marker = self.scenario.reference, self.target_marker
        if reference is not None and marker is not None:  # (a reference has its marker)
            target = _target(reference, k * self.dt)
            marker.position = _position(target)
            if target.shape == (4, 4):
                marker.wxyz = _wxyz(target[:3, :3])
        shown = min(-(-k // self.stride), len(self.path_segments))  # segments that end at or before tick k
        for segment in self.path_segments[min(shown, self.shown_segments):max(shown, self.shown_segments)]:
            segment.visible = shown > self.shown_segments
        self.shown_segments = shown

    def points(self) -> NDArray[np.float64]:
        """World points the camera must see: the corners of the shapes' boxes at the start and
        at the last recorded tick, the tool path so far and the whole reference."""
        points = [] if self.tool_path is None else [self.tool_path[:self.recorded + 1]]
        if self.reference_points is not None:
            points.append(self.reference_points)
        for q in (self.q[0], self.q[self.recorded]):
            pin.forwardKinematics(self.model, self.data, q)
            for shape in self.shapes:
                pose = self.data.oMi[shape.joint].homogeneous @ shape.placement
                points.append(_corners(shape) @ pose[:3, :3].T + pose[:3, 3])
        return np.vstack(points)


def _target(reference: ReferenceMotion, t: float) -> NDArray[np.float64]:
    """The target of ``reference`` at time ``t`` [s] (4x4 or a point), a copy (a reference may
    return a buffer it reuses)."""
    return np.array(reference(t)[0])


def _position(target: NDArray[np.float64]) -> NDArray[np.float64]:
    """The position of a target (4x4 pose or a point)."""
    return target[:3, 3] if target.shape == (4, 4) else target


class Scene:
    """Runs (and obstacles) in a viser scene, on one timeline: :meth:`show` poses everything at a time."""

    def __init__(self, server: viser.ViserServer, runs: Sequence[Run | PlannedRun],
                 obstacles: Sequence[Obstacle] = (), fps: float = FPS, max_frames: int | None = None):
        self.server, self.fps = server, fps
        self.duration = max([_duration(scenario, what) for scenario, what in runs] + [0.0])
        #: run time per frame time: 1, or what keeps a replay within ``max_frames``
        self.speed = 1 if max_frames is None else max(1, math.ceil(self.duration * fps / max_frames - 1e-9))
        self.tracks = [self._track(i, scenario, what) for i, (scenario, what) in enumerate(runs)]
        for n, obstacle in enumerate(obstacles):
            _add_shape(server.scene, f"/obstacles/{n}", obstacle.kind, obstacle.size, OBSTACLE_COLOUR,
                       obstacle.pose, opacity=0.5)
        self._frame_the_view(obstacles)
        self.show(0.0)

    def _track(self, index: int, scenario: Scenario, what: RunResult | int) -> _RunTrack:
        if isinstance(what, RunResult):
            rows_per_frame = self.speed / (self.fps * what.stride * scenario.dt)
            return _RunTrack.from_result(self.server, index, scenario, what, max(1, int(round(rows_per_frame))))
        stride = max(1, int(round(1.0 / (self.fps * scenario.dt))))
        return _RunTrack(self.server, index, scenario, what, orientation_tracked(scenario.reference_task), stride)

    def _frame_the_view(self, obstacles: Sequence[Obstacle]) -> None:
        """Ground grid under everything and a camera that sees it all."""
        seen = [track.points() for track in self.tracks]
        seen += [obstacle.pose[:3, 3] + np.array([[-1], [1]]) * max(obstacle.size) for obstacle in obstacles]
        points = np.vstack(seen) if seen else np.zeros((1, 3))
        low, high = points.min(axis=0), points.max(axis=0)
        centre, radius = (low + high) / 2, max(float(np.linalg.norm(high - low)) / 2, 0.3)
        self.top = np.array([centre[0], centre[1], high[2] + 0.1 * radius])  #: above it all: the note's place
        side = 2 * math.ceil(radius + 0.5)
        scene = self.server.scene
        scene.set_up_direction("+z")
        scene.add_grid("/ground", side, side, position=(centre[0], centre[1], min(low[2], 0.0) - 1e-3),
                       cell_size=0.1, section_size=1.0)
        camera = self.server.initial_camera
        camera.fov = math.radians(50.0)
        camera.look_at = centre
        camera.position = centre + 2.2 * radius * np.array([0.55, -0.7, 0.45])
        camera.up = (0.0, 0.0, 1.0)

    def show(self, t: float) -> None:
        """Everything at time ``t`` [s] of the timeline."""
        with self.server.atomic():
            for track in self.tracks:
                track.show(t)

    def frame_times(self) -> Iterator[float]:
        """The replay's frame times [s of the runs], ``fps / speed`` per second from 0 to the
        end of the longest run."""
        step = self.speed / self.fps
        count = int(math.ceil(self.duration / step - 1e-9))
        return (min(n * step, self.duration) for n in range(count + 1))

    def note(self) -> str:
        """What the replay changes or leaves out: "", or e.g. "replayed at 3× speed;
        youbot_circle: one configuration per 5 ticks kept"."""
        parts = [f"replayed at {self.speed}× speed"] if self.speed > 1 else []
        parts += [f"{track.scenario.name}: one configuration per {track.dt / track.scenario.dt:.0f} ticks kept"
                  for track in self.tracks if track.dt > track.scenario.dt * (1 + 1e-9)]
        return "; ".join(parts)


def _duration(scenario: Scenario, what: RunResult | int) -> float:
    """How long a run lasts on the timeline [s]: its rows (of ``stride`` ticks) or its ticks to come."""
    if isinstance(what, RunResult):
        return what.time.size * what.stride * scenario.dt
    return what * scenario.dt


def _start_server(host: str, port: int) -> viser.ViserServer:
    """A viser server on ``host``:``port`` (the next free port if taken; 0: any), without
    the banner viser prints on stdout (which holds the summaries, or the JSON)."""
    with contextlib.redirect_stdout(io.StringIO()):
        return viser.ViserServer(host=host, port=port, verbose=False)


def _stop_server(server: viser.ViserServer) -> None:
    with contextlib.redirect_stdout(io.StringIO()):
        server.stop()


def replay_html(runs: Sequence[Run], obstacles: Sequence[Obstacle] = (),
                fps: float = FPS) -> str:
    """A self-contained HTML page replaying ``runs`` (viser's client with the recorded scene
    embedded; no server, no network): play/pause, time slider and speed at the bottom."""
    server = _start_server("127.0.0.1", 0)
    try:
        poses_per_frame = sum(scenario.robot.model.njoints + 1 for scenario, _ in runs)  # joints and target
        scene = Scene(server, runs, obstacles, fps, max_frames=max(1, MAX_POSES // max(1, poses_per_frame)))
        if scene.note():
            server.scene.add_label("/note", scene.note(), position=scene.top, anchor="bottom-center")
        recording = server.get_scene_serializer()
        for t in scene.frame_times():
            scene.show(t)
            recording.insert_sleep(1.0 / fps)
        recording.insert_sleep(1.0)  # hold the last frame before looping
        return recording.as_html()
    finally:
        _stop_server(server)


def write_html(runs: Sequence[Run], path: str | Path, obstacles: Sequence[Obstacle] = (),
               fps: float = FPS) -> Path:
    """Write the :func:`replay_html` page of ``runs`` to ``path`` (a name ending in .html or
    .htm) atomically: a temporary file in the same folder, renamed to ``path`` once complete (a
    missing folder is created).

    Args:
        runs: ``(scenario, result)`` pairs (:func:`wbc.app.closed_loop.run`), on one timeline.
        path: the page to write.
        obstacles: static shapes drawn with the runs.
        fps: frames per second of the replay.

    Returns:
        ``path``, as a :class:`~pathlib.Path`.

    Raises:
        OutputError: ``path`` cannot be written (:func:`wbc.app.outputs.check_output`); raised
            before the page is built.
        OSError: writing failed (e.g. the disk is full); ``path`` is left as it was.
    """
    path = check_output(str(path), HTML_FORMATS)
    page = replay_html(runs, obstacles, fps)

    def write(stream: BinaryIO) -> None:
        for start in range(0, len(page), 1 << 20):  # (not a second copy of the whole page)
            stream.write(page[start:start + (1 << 20)].encode("utf-8"))

    return write_atomically(path, write)


_Value = TypeVar("_Value")


def _assign(handle: viser.GuiInputHandle[_Value], value: _Value) -> None:
    """``handle.value = value``: viser's way to set an input (sent to every client). mypy
    reads the property as read-only: viser defines its setter apart from its getter, and mypy
    only pairs a setter that directly follows the getter (python/mypy#1465)."""
    handle.value = value  # type: ignore[misc]  # (viser's setter, which mypy does not see: above)


class LiveView:
    """Runs in a viser server at ``http://host:port``, with play/pause, a time slider and a
    speed setting in its panel.

    ``runs`` may hold finished runs ``(scenario, result)`` and runs still to come
    ``(scenario, ticks)``: :meth:`follow` gives the ``on_tick`` observer of
    :func:`wbc.app.closed_loop.run` that streams one of those into the view while the controller
    runs, paced to real time (times the speed setting; "play" unticked pauses the run).
    :meth:`serve` then plays everything on one timeline, looping, until stopped.

    Args:
        runs: finished runs ``(scenario, result)`` and runs to come ``(scenario, ticks)``.
        host: the address the server listens on.
        port: its TCP port; the next free one if taken, any free one for 0.
        obstacles: static shapes drawn with the runs.
        fps: frames per second of the view's updates.

    Use it as a context manager (or call :meth:`close`) to stop the server.
    """

    def __init__(self, runs: Sequence[Run | PlannedRun], host: str = "127.0.0.1", port: int = 8080,
                 obstacles: Sequence[Obstacle] = (), fps: float = FPS):
        self.server = _start_server(host, port)
        try:
            self.scene = Scene(self.server, runs, obstacles, fps)
        except BaseException:
            _stop_server(self.server)
            raise
        gui = self.server.gui
        self.status = gui.add_markdown("")
        self.playing = gui.add_checkbox("play", initial_value=True)
        self.time = gui.add_slider("time [s]", min=0.0, max=max(self.scene.duration, 1e-3), step=1.0 / fps,
                                   initial_value=0.0)
        self.speed = gui.add_dropdown("speed", ("0.25", "0.5", "1", "2", "4"), initial_value="1")
        #: the slider's last position set by someone else than the view (a user in the browser, or
        #: code): taken by :meth:`serve`; a deque because appending and popping are atomic
        self._moves: deque[float] = deque(maxlen=1)
        self._writer: int | None = None  #: the thread setting the slider as the view, while it does
        self.time.on_update(self._note_move)

    @property
    def url(self) -> str:
        """Where the view is served: ``http://host:port`` (the port the server got)."""
        return f"http://{self.server.get_host()}:{self.server.get_port()}"

    def follow(self, index: int, clock: Callable[[], float] = time.perf_counter,
               sleep: Callable[[float], None] = time.sleep) -> TickObserver:
        """The ``on_tick(k, q)`` observer that streams the run ``runs[index]`` (given as
        ``(scenario, ticks)``) into the view: every configuration is recorded, and every
        1/fps s of the run's time the scene is shown at that time and the run is held until the
        same time has passed on ``clock`` (divided by the speed setting; not made up for when
        the run falls behind real time). The other runs are shown at the same time.

        Raises:
            ValueError: ``runs[index]`` is a finished run (given as ``(scenario, result)``).
        """
        track = self.scene.tracks[index]
        if track.recorded:
            raise ValueError(f"run {index} of the view is a finished run: only a run given as (scenario, ticks) "
                             "can be streamed")
        name, end = track.scenario.name, track.ticks * track.dt
        self.time.disabled = True  # the stream sets the time
        paced = {"time": 0.0, "wall": clock()}

        def on_tick(k: int, q: NDArray[np.float64]) -> None:
            track.record(k, q)
            if k % track.stride and k != track.ticks:
                return
            t = k * track.dt
            self.scene.show(t)
            self._show_time(t)
            self.status.content = f"**live**: {name}, {t:.2f} / {end:.2f} s"
            while not self.playing.value:
                sleep(1.0 / self.scene.fps)
                paced["wall"] = clock()
            deadline = paced["wall"] + (t - paced["time"]) / float(self.speed.value)
            now = clock()
            if deadline > now:
                sleep(deadline - now)
            paced["time"], paced["wall"] = t, max(deadline, now)

        return on_tick

    def serve(self, stop: threading.Event) -> None:
        """Play until ``stop`` is set: time advances while ``play`` is ticked, wraps at the
        end; moving the slider pauses and shows that time."""
        self.time.disabled = False
        self.status.content = "**replay** of the run(s)"
        t, last = 0.0, time.perf_counter()
        self._moves.clear()
        while not stop.wait(1.0 / self.scene.fps):
            now = time.perf_counter()
            if self._moves:  # the user moved the slider (only this loop pops)
                t = self._moves.pop()
                _assign(self.playing, False)
            elif self.playing.value:
                t += (now - last) * float(self.speed.value)
                t = 0.0 if t > self.scene.duration + 1.0 else t  # hold the end 1 s, then loop
            last = now
            self.scene.show(t)
            self._show_time(min(t, self.scene.duration))

    def _show_time(self, t: float) -> None:
        """Set the slider to ``t`` as the view does (not a move of the user's)."""
        self._writer = threading.get_ident()
        try:
            _assign(self.time, t)
        finally:
            self._writer = None

    def _note_move(self, event: viser.GuiEvent[viser.GuiSliderHandle[float]]) -> None:
        """The slider changed: a move of the user's unless the view itself is setting it in this
        thread. (Compared with a value written back, a move made while the view writes is never
        lost: the view's write cannot overwrite it unseen.)"""
        if self._writer != threading.get_ident():
            self._moves.append(float(event.target.value))

    def close(self) -> None:
        """Stop the server."""
        _stop_server(self.server)

    def __enter__(self) -> LiveView:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
