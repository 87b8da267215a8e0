"""Declarative scenarios (``tasks/*.toml``): robot, task stack, constraints, solver, reference.

Schema (see ``tasks/youbot_circle.toml`` for a commented example); every key is checked,
strictly, by the pydantic models below (:mod:`wbc.core.schema`): unknown sections or keys,
wrong types (``dt = "0.01"``, ``reduced = "false"``) and out-of-range values are a
:class:`~wbc.core.errors.ScenarioError` naming the file, the key and the fix::

    name = "..."      optional, default: the file name
    description = "..."  optional: what the scenario shows, one line (``wbc scenarios`` lists it)
    [robot]           name = shipped model ("youbot") or URDF / sidecar path (relative to the file)
                      initial_configuration = [nq numbers] (default: the model's neutral pose)
    [controller]      solver = "daqp", dt = 0.01 [s] (> 0, <= duration), duration = 10.0 [s]
                      (> 0, at most 10^7 ticks), damping = 1e-3 (>= 0), reduced = false (a boolean:
                      solve over the real inputs of a nonholonomic base)
    [[tasks]]         type = a name in TASK_TYPES; the other keys are arguments of its constructor;
                      level = 0 (optional, an integer >= 0): the task's priority level, 0 highest
                      (strict priorities, wbc.control.hierarchy; all at 0: one weighted level); levels
                      must be 0, 1, ... without gaps
    [[constraints]]   type = a name in CONSTRAINT_TYPES; likewise; ``CollisionAvoidance`` takes
                      ``obstacles = [{ type = "Sphere", center = [...], radius = ... }, ...]``
                      (:func:`wbc.collision.obstacles.obstacle_from_table`); ``BaseFootprintAvoidance``
                      takes ``footprint = [[x, y], ...]``, ``points = [[x, y], ...]``, ``polygons =
                      [[[x, y], ...], ...]`` and ``walls = [{ start = [x, y], end = [x, y], spacing =
                      0.02 }, ...]``: scan points along each wall, added to ``points`` (world frame [m])
                      (``target = "initial"`` in a PostureTask means initial_configuration)
    [reference]       type = "circle" (radius, period [s], normal, start_axis, ramp_time [s])
                      | "pose" | "line" (speed [m/s], ramp_time [s]) for the first FrameTask,
                      "point" (position) for the first PositionTask (or ``task = name``); the goal
                      of "pose", "line" and "planned" is the start pose with ``configuration`` (the
                      frame's pose there), ``position`` and/or ``rpy`` applied in that order;
                      "planned" (+ path, centre, duration, threshold, reroute, margin, wrist) is
                      the singular-region-aware plan of wbc.trajectory.scenario_spec

Constructor arguments are checked against the constructor's signature and type hints
(strictly: a quoted number is refused); unannotated ones must be numbers or arrays of numbers.
"""

from __future__ import annotations

import functools
import inspect
import math
import operator
import types
import typing
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Any, Literal, TypeVar, Union

import numpy as np
from numpy.typing import ArrayLike, NDArray
from pydantic import ConfigDict, Field, TypeAdapter, ValidationError, model_validator

from .. import constraints as constraint_module
from .. import tasks as task_module
from ..collision import BaseFootprintAvoidance, CollisionAvoidance
from ..collision.footprint import wall_points
from ..collision.obstacles import obstacle_from_table
from ..constraints import Constraint
from ..control.controller import DEFAULT_LM_DAMPING, Controller
from ..core.errors import ScenarioError, WbcError
from ..core.schema import NonNegative, Positive, Table, Vector3, explain, read_toml, suggest
from ..model import shipped
from ..model.robot import Robot, load_robot, rpy_matrix
from ..runtime import kernels
from ..tasks import FrameTask, PositionTask, PostureTask, Task
from ..trajectory.scenario_spec import plan_from_spec
from .references import Circle, ConstantPoint, ConstantPose, Line, ReferenceMotion

TASK_TYPES: dict[str, type[Task]] = {name: getattr(task_module, name) for name in task_module.__all__ if name != "Task"}
CONSTRAINT_TYPES: dict[str, type[Constraint]] = {name: getattr(constraint_module, name)
                                                 for name in constraint_module.__all__
                                                 if name not in ("Constraint", "ConstraintRows")}
CONSTRAINT_TYPES["CollisionAvoidance"] = CollisionAvoidance
CONSTRAINT_TYPES["BaseFootprintAvoidance"] = BaseFootprintAvoidance
#: keys whose values the constructor checks itself (obstacle tables)
_CHECKED_BY_CONSTRUCTOR = {CollisionAvoidance: ("obstacles",)}
_POINTS = list[list[float]]
_POLYGONS = list[list[list[float]]]
#: keys holding arrays of [x, y] points [m]: numbers only, checked here (``true`` is no coordinate;
#: numpy would read it as 1.0), their shapes by the constructor
_POINT_ARRAYS = {BaseFootprintAvoidance: {"footprint": _POINTS, "points": _POINTS, "polygons": _POLYGONS}}
MAX_TICKS = 10**7  #: longest run a scenario may ask for (duration / dt)
_Item = TypeVar("_Item", Task, Constraint)


# ------------------------------------------------------------------------------ schema
class RobotTable(Table):
    name: str
    initial_configuration: list[float] | None = None


class ControllerTable(Table):
    solver: str = "daqp"
    dt: Positive = 0.01
    duration: Positive = 10.0
    damping: NonNegative = 1e-3
    lm_damping: NonNegative = DEFAULT_LM_DAMPING
    reduced: bool = False

    @model_validator(mode="after")
    def _ticks(self) -> ControllerTable:
        if self.dt > self.duration:
            raise ValueError(f"dt = {self.dt} s is longer than duration = {self.duration} s; "
                             "make dt smaller or duration longer")
        if self.duration / self.dt > MAX_TICKS:
            raise ValueError(f"duration / dt = {self.duration / self.dt:.3g} ticks, more than {MAX_TICKS:.0e}; "
                             "shorten duration or lengthen dt")
        return self


class Entry(Table):
    """A ``[[tasks]]`` / ``[[constraints]]`` entry: ``type`` + constructor arguments (checked later)."""

    model_config = ConfigDict(extra="allow")
    type: str


class TaskEntry(Entry):
    """A ``[[tasks]]`` entry: also its priority ``level`` (0 highest)."""

    level: Annotated[int, Field(ge=0)] = 0


class CircleReference(Table):
    type: Literal["circle"]
    task: str | None = None
    radius: Positive
    period: Positive
    normal: Vector3 = [0.0, 0.0, 1.0]
    start_axis: Vector3 = [1.0, 0.0, 0.0]
    ramp_time: NonNegative = 1.0


class PointReference(Table):
    type: Literal["point"]
    task: str | None = None
    position: Vector3


class GoalKeys(Table):
    """The goal of "pose", "line" and "planned": the start pose with these applied in order."""

    task: str | None = None
    configuration: list[float] | None = None
    position: Vector3 | None = None
    rpy: Vector3 | None = None


class PoseReference(GoalKeys):
    type: Literal["pose"]


class LineReference(GoalKeys):
    type: Literal["line"]
    speed: Positive
    ramp_time: NonNegative = 0.5


class PlannedReference(GoalKeys):
    type: Literal["planned"]
    path: Literal["line", "arc"] = "line"
    centre: Vector3 | None = None
    duration: Positive
    threshold: Positive
    reroute: bool = True
    margin: Positive | None = None
    wrist: Annotated[list[str], Field(min_length=3, max_length=3)] | None = None

    @model_validator(mode="after")
    def _centre(self) -> PlannedReference:
        if (self.path == "arc") != (self.centre is not None):
            raise ValueError("path = \"arc\" needs centre = [x, y, z]; path = \"line\" takes no centre")
        return self


Reference = Annotated[CircleReference | PoseReference | LineReference | PointReference | PlannedReference,
                      Field(discriminator="type")]


class ScenarioFile(Table):
    """The whole file."""

    name: str | None = None
    description: str = ""
    robot: RobotTable
    controller: ControllerTable = ControllerTable()
    tasks: list[TaskEntry] = []
    constraints: list[Entry] = []
    reference: Reference | None = None


@dataclass
class Scenario:
    """A parsed scenario, ready to run."""

    name: str
    robot: Robot
    q0: NDArray[np.float64]
    tasks: list[Task]
    constraints: list[Constraint]
    solver: str
    dt: float
    duration: float
    damping: float
    reduced: bool = False
    lm_damping: float = DEFAULT_LM_DAMPING
    reference: ReferenceMotion | None = None
    reference_task: FrameTask | PositionTask | None = None
    source: Path | None = None
    spec: dict[str, Any] = field(default_factory=dict)
    #: the priority level of each task (``[[tasks]] level``); empty: one level
    levels: list[int] = field(default_factory=list)
    #: what the scenario shows, one line (the file's ``description``)
    description: str = ""

    def __post_init__(self) -> None:
        if type(self.reduced) is not bool:
            raise ScenarioError(f"reduced must be True or False, got {self.reduced!r}")
        for name in ("dt", "duration"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not (0 < value < math.inf):
                raise ScenarioError(f"{name} must be a finite number > 0 [s], got {value!r}")

    @property
    def task_levels(self) -> list[Task] | list[list[Task]]:
        """The ``tasks`` argument of the controller: the tasks, or one list per level (highest first)."""
        if not self.levels:
            return self.tasks
        return [[task for task, level in zip(self.tasks, self.levels, strict=True) if level == k]
                for k in range(max(self.levels) + 1)]

    def make_controller(self, solver: str | None = None, warm_up: bool = True) -> Controller:
        return Controller(self.robot, self.task_levels, self.constraints, solver=solver or self.solver,
                          dt=self.dt, damping=self.damping, reduced=self.reduced, lm_damping=self.lm_damping,
                          warm_up=warm_up)

    @property
    def ticks(self) -> int:
        return int(round(self.duration / self.dt))


def scenario_file(name_or_path: str | Path) -> Path:
    """The file of a scenario given by path, or by the name of a shipped scenario
    (``"youbot_circle"``: a string without a folder or a suffix that names no existing file;
    :func:`wbc.model.shipped.scenario_names` lists them)."""
    path = Path(name_or_path)
    if isinstance(name_or_path, str) and path.name == name_or_path and not path.suffix and not path.exists():
        if name_or_path in shipped.scenario_names():
            return shipped.scenario_path(name_or_path)
        raise ScenarioError(f"no scenario file or shipped scenario {name_or_path!r}"
                            f"{suggest(name_or_path, shipped.scenario_names())}; shipped scenarios "
                            f"(`wbc scenarios`): {', '.join(shipped.scenario_names())}")
    return path


def load_scenario(path: str | Path) -> Scenario:
    """Parse and validate a scenario file, given by path or by the name of a shipped scenario
    (:func:`scenario_file`).

    Returns:
        The scenario: robot, initial configuration, tasks, constraints, reference, controller settings.

    Raises:
        ScenarioError: any mistake (unreadable file, unknown or misspelt key, wrong type,
            out-of-range value, an item that does not fit the robot), naming the file and key.
    """
    path = scenario_file(path)
    spec = read_toml(path, ScenarioError, "scenario")
    try:
        with kernels.batch():  # a first start's kernels compile in parallel processes (the first controller's)
            return _build(ScenarioFile.model_validate(spec), spec, path)
    except ValidationError as exc:
        raise ScenarioError(f"{path}: {explain(exc, ScenarioFile)}") from None
    except ScenarioError as exc:
        raise ScenarioError(f"{path}: {exc}") from exc


def _build(checked: ScenarioFile, spec: dict[str, Any], path: Path) -> Scenario:
    robot = _robot(checked.robot, path)
    q0 = _initial_configuration(checked.robot, robot)
    tasks = [_instantiate(entry, TASK_TYPES, f"[[tasks]] #{i + 1}", robot, q0) for i, entry in enumerate(checked.tasks)]
    constraints = [_instantiate(entry, CONSTRAINT_TYPES, f"[[constraints]] #{i + 1}", robot, q0)
                   for i, entry in enumerate(checked.constraints)]
    control = checked.controller
    scenario = Scenario(
        name=checked.name or path.stem, robot=robot, q0=q0, tasks=tasks, constraints=constraints,
        solver=control.solver, dt=control.dt, duration=control.duration, damping=control.damping,
        reduced=control.reduced, lm_damping=control.lm_damping, source=path, spec=spec, levels=_levels(checked.tasks),
        description=checked.description,
    )
    if checked.reference is not None:
        scenario.reference_task, scenario.reference = _reference(checked.reference, tasks, robot, q0)
    try:  # what only the whole stack can tell (a base that needs a no-slip row, ...): before any run starts
        scenario.make_controller("daqp", warm_up=False)  # (a check: never ticked)
    except WbcError as exc:
        raise ScenarioError(f"the controller cannot be built: {exc}") from exc
    return scenario


def _levels(entries: list[TaskEntry]) -> list[int]:
    """The ``level`` of each ``[[tasks]]`` entry, or ``[]`` when all are at level 0 (one level)."""
    levels = [entry.level for entry in entries]
    if not any(levels):
        return []
    present = set(levels)
    # the first level without a task: one of 0..len(levels) is free, so this never counts past the tasks
    # (a level = 10^9 once built a set of every level below it)
    missing = next(level for level in range(len(levels) + 1) if level not in present)
    if missing < max(levels):
        raise ScenarioError(f"[[tasks]] level = {max(levels)} but no task has level = {missing}; "
                            "levels must be 0, 1, 2, ... without gaps (0 is the highest priority)")
    return levels


def _robot(table: RobotTable, path: Path) -> Robot:
    name = table.name
    try:
        return load_robot(path.parent / name if name.endswith((".urdf", ".toml")) else name)
    except WbcError as exc:
        raise ScenarioError(f"[robot] name = {name!r}: {exc}") from exc


def _initial_configuration(table: RobotTable, robot: Robot) -> NDArray[np.float64]:
    if table.initial_configuration is None:
        return robot.neutral()
    try:
        return robot.check_configuration(table.initial_configuration)
    except WbcError as exc:
        raise ScenarioError(f"[robot] initial_configuration: {exc}; give the {robot.nq} coordinates of "
                            f"{robot.name} ({', '.join(robot.joint_names)})") from exc


def _instantiate(entry: Entry, registry: dict[str, type[_Item]], label: str, robot: Robot,
                 q0: NDArray[np.float64]) -> _Item:
    """The task / constraint of one ``[[tasks]]`` / ``[[constraints]]`` entry, bound once to the
    robot (its frames, joints and sizes checked here, so the error names this entry)."""
    if entry.type not in registry:
        raise ScenarioError(f"{label}: type {entry.type!r} unknown{suggest(entry.type, registry)} "
                            f"(known: {', '.join(sorted(registry))})")
    cls, label = registry[entry.type], f"{label} ({entry.type})"
    arguments = dict(entry.model_extra or {})
    walls = arguments.pop("walls", None) if cls is BaseFootprintAvoidance else None
    _check_arguments(cls, arguments, label)
    if walls is not None:
        arguments["points"] = _scan_with_walls(arguments.get("points"), walls, label)
    if cls is CollisionAvoidance:  # obstacles are tables: { type = "Sphere", center = [...], radius = ... }
        arguments["obstacles"] = _obstacles(arguments.get("obstacles", []), label)
    if cls is PostureTask and arguments.get("target") == "initial":
        arguments["target"] = q0
    try:
        item = cls(**arguments)
        item.bind(robot)  # frames, joints and target sizes checked against the robot here, naming this entry
        return item
    except (WbcError, TypeError, ValueError) as exc:
        raise ScenarioError(f"{label}: {exc}") from exc


def _obstacles(tables: object, label: str) -> list[Any]:
    if not isinstance(tables, list):
        raise ScenarioError(f"{label} obstacles: expected an array of tables, e.g. obstacles = "
                            f"[{{ type = \"Sphere\", center = [0.5, 0.0, 0.4], radius = 0.1 }}], got {tables!r}")
    try:
        return [obstacle_from_table(table, f"obstacles[{k}]") for k, table in enumerate(tables)]
    except WbcError as exc:
        raise ScenarioError(f"{label}: {exc}") from exc


def _scan_with_walls(points: object, walls: object, label: str) -> NDArray[np.float64]:
    """``points`` with the points along each wall table ``{ start = [x, y], end = [x, y], spacing = s }``."""
    example = "walls = [{ start = [1.0, -1.0], end = [1.0, 1.0], spacing = 0.02 }]"
    if not isinstance(walls, list) or not all(isinstance(wall, dict) for wall in walls):
        raise ScenarioError(f"{label} walls: expected an array of tables, e.g. {example}, got {walls!r}")
    try:
        pieces = [np.asarray(points, dtype=np.float64).reshape(-1, 2)] if points is not None else []
    except (TypeError, ValueError):
        raise ScenarioError(f"{label} points: expected an array of [x, y] pairs, got {points!r}") from None
    for k, wall in enumerate(walls):
        unknown = set(wall) - {"start", "end", "spacing"}
        if unknown or not {"start", "end"} <= set(wall):
            raise ScenarioError(f"{label} walls[{k}]: keys start, end (and spacing) expected, e.g. {example}; "
                                f"got {sorted(wall)}")
        try:
            pieces.append(wall_points(wall["start"], wall["end"], wall.get("spacing", 0.02)))
        except (WbcError, TypeError, ValueError) as exc:
            raise ScenarioError(f"{label} walls[{k}]: {exc}") from exc
    return np.concatenate(pieces) if pieces else np.zeros((0, 2))


def _check_arguments(cls: type[Any], arguments: dict[str, Any], label: str) -> None:
    """Keys must be constructor parameters, values must fit their type hints (strictly)."""
    parameters = {name: p for name, p in inspect.signature(cls).parameters.items()
                  if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)}
    for key in arguments:
        if key not in parameters:
            raise ScenarioError(f"{label}: unknown key {key!r}{suggest(key, parameters)} "
                                f"(parameters: type, {', '.join(parameters)})")
    missing = [n for n, p in parameters.items() if p.default is p.empty and n not in arguments]
    if missing:
        raise ScenarioError(f"{label}: required key {missing[0]!r} missing; add `{missing[0]} = ...`")
    hints = typing.get_type_hints(cls.__init__)
    for key, value in arguments.items():
        if key in _CHECKED_BY_CONSTRUCTOR.get(cls, ()):
            continue  # tables and arrays, checked by _obstacles and the constructor
        hint = _POINT_ARRAYS.get(cls, {}).get(key) or (_toml_hint(hints[key]) if key in hints else _Numbers)
        if cls is PostureTask and key == "target":
            hint = Literal["initial"] | hint
        try:
            _adapter(hint).validate_python(value)
        except ValidationError:
            raise ScenarioError(f"{label} {key} = {value!r}: expected {_describe(hint)}"
                                f"{' (numbers without quotes)' if isinstance(value, str) else ''}") from None


_Numbers = float | list[float]  # unannotated or array-like constructor arguments: costs, targets
_ARRAY_LIKE = frozenset(typing.get_args(ArrayLike))  # the members of numpy's ArrayLike union


def _toml_hint(hint: Any) -> Any:
    """A constructor's type hint as TOML values meet it: numpy's ``ArrayLike`` is a number or
    an array of numbers (:data:`_Numbers`), a ``Sequence[X]`` an array (``list[X]``), a
    ``Literal`` of names a string."""
    if typing.get_origin(hint) in (Union, types.UnionType):
        options = typing.get_args(hint)
        if _ARRAY_LIKE <= set(options):
            options = (_Numbers, *(option for option in options if option not in _ARRAY_LIKE))
        return functools.reduce(operator.or_, [_toml_hint(option) for option in options])
    if typing.get_origin(hint) is Sequence:
        return types.GenericAlias(list, typing.get_args(hint))
    if typing.get_origin(hint) is Literal and all(isinstance(option, str) for option in typing.get_args(hint)):
        return str  # a choice of names: the constructor checks it and lists the valid ones
    return hint


@functools.cache
def _adapter(hint: Any) -> TypeAdapter[Any]:
    return TypeAdapter(hint, config=ConfigDict(strict=True, allow_inf_nan=False))


def _describe(hint: Any) -> str:
    names = {float: "a finite number", int: "an integer", str: "a string", bool: "true or false",
             type(None): "nothing", list[float]: "an array of numbers", list[str]: "an array of strings",
             _POINTS: "an array of [x, y] points (numbers)",
             _POLYGONS: "an array of polygons, each an array of [x, y] points (numbers)"}
    options = typing.get_args(hint) if typing.get_origin(hint) in (Union, types.UnionType) else (hint,)
    return " or ".join(names.get(o) or " or ".join(map(repr, typing.get_args(o))) for o in options
                       if o is not type(None))


def _reference(spec: Reference, tasks: list[Task], robot: Robot,
               q0: NDArray[np.float64]) -> tuple[FrameTask | PositionTask, ReferenceMotion]:
    """(task, reference) of the validated ``[reference]`` table."""
    task_type = PositionTask if spec.type == "point" else FrameTask
    matches = [t for t in tasks if isinstance(t, task_type) and spec.task in (None, t.name)]
    if not matches:
        raise ScenarioError(f"[reference] of type {spec.type!r} needs a {task_type.__name__}"
                            f"{'' if spec.task is None else f' named {spec.task!r}'} in [[tasks]]")
    task = matches[0]
    try:
        return task, _make_reference(spec, robot, task.frame, q0)
    except WbcError as exc:
        raise ScenarioError(f"[reference] ({spec.type}): {exc}") from exc


def _make_reference(spec: Reference, robot: Robot, frame: str, q0: NDArray[np.float64]) -> ReferenceMotion:
    start = robot.frame_pose(q0, frame)
    if isinstance(spec, CircleReference):
        return Circle(start=start, radius=spec.radius, period=spec.period, normal=np.array(spec.normal),
                      start_axis=np.array(spec.start_axis), ramp_time=spec.ramp_time)
    if isinstance(spec, PointReference):
        return ConstantPoint(np.array(spec.position))
    goal = _goal_pose(spec, start, robot, frame)
    if isinstance(spec, PoseReference):
        return ConstantPose(goal)
    if isinstance(spec, LineReference):
        return Line(start=start, end=goal, speed=spec.speed, ramp_time=spec.ramp_time)
    plan_keys = spec.model_dump(exclude_unset=True, exclude=set(GoalKeys.model_fields) | {"type"})
    return plan_from_spec(plan_keys, robot, frame, q0, start, goal).reference


def _goal_pose(spec: GoalKeys, start: NDArray[np.float64], robot: Robot, frame: str) -> NDArray[np.float64]:
    """The start pose, replaced by the frame's pose at ``configuration`` if given, then
    with ``position`` and/or ``rpy`` overridden."""
    pose = start.copy()
    if spec.configuration is not None:
        pose = robot.frame_pose(spec.configuration, frame).copy()
    if spec.position is not None:
        pose[:3, 3] = spec.position
    if spec.rpy is not None:
        pose[:3, :3] = rpy_matrix(*spec.rpy)
    return pose
