"""Declarative scenarios (``tasks/*.toml``): robot, task stack, constraints, solver, reference.

Schema (see ``tasks/youbot_circle.toml`` for a commented example)::

    [robot]       name = "youbot" | path, initial_configuration = [...]
    [controller]  solver, dt [s], duration [s], damping
    [controller]  ... reduced = true|false (solve over the real inputs of a nonholonomic base)
    [[tasks]]     type = any name in TASK_TYPES, + constructor arguments
    [[constraints]] type = any name in CONSTRAINT_TYPES, + constructor arguments
    [reference]   type = "circle" | "pose" | "line" for the first FrameTask, "point" for the
                  first PositionTask (or ``task = name``); the goal of "pose" and "line" is the
                  start pose with ``configuration`` (the frame's pose there), ``position`` and/or
                  ``rpy`` applied in that order; "planned" (same goal keys) is the singular-region-
                  aware plan of wbc.trajectory.scenario_spec
"""

from __future__ import annotations

import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import constraints as constraint_module
from . import tasks as task_module
from .controller import Controller
from .errors import ScenarioError, WbcError
from .references import Circle, ConstantPoint, ConstantPose, Line, rpy_matrix
from .robot import Robot, load_robot
from .tasks import FrameTask, PositionTask, PostureTask
from .trajectory.scenario_spec import plan_from_spec

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

TASK_TYPES = {name: getattr(task_module, name) for name in task_module.__all__ if name != "Task"}
CONSTRAINT_TYPES = {name: getattr(constraint_module, name) for name in constraint_module.__all__
                    if name not in ("Constraint", "ConstraintRows")}


@dataclass
class Scenario:
    """A parsed scenario, ready to run."""

    name: str
    robot: Robot
    q0: np.ndarray
    tasks: list
    constraints: list
    solver: str
    dt: float
    duration: float
    damping: float
    reduced: bool = False
    reference: object | None = None
    reference_task: FrameTask | PositionTask | None = None
    source: Path | None = None
    spec: dict = field(default_factory=dict)

    def make_controller(self, solver: str | None = None) -> Controller:
        return Controller(self.robot, self.tasks, self.constraints, solver=solver or self.solver,
                          dt=self.dt, damping=self.damping, reduced=self.reduced)

    @property
    def ticks(self) -> int:
        return int(round(self.duration / self.dt))


def load_scenario(path: str | Path) -> Scenario:
    """Parse a scenario file; raises ScenarioError with the offending key on any mistake."""
    path = Path(path)
    try:
        with open(path, "rb") as stream:
            spec = tomllib.load(stream)
    except (OSError, tomllib.TOMLDecodeError) as exc:
        raise ScenarioError(f"cannot read scenario {path}: {exc}") from exc
    try:
        return _build(spec, path)
    except ScenarioError:
        raise
    except (WbcError, TypeError, ValueError, KeyError) as exc:
        raise ScenarioError(f"{path}: {exc}") from exc


def _build(spec: dict, path: Path) -> Scenario:
    robot_spec = _section(spec, "robot")
    name = robot_spec.get("name")
    if name is None:
        raise ScenarioError(f"{path}: [robot] needs a name")
    model_ref = name if not str(name).endswith((".urdf", ".toml")) else (path.parent / name)
    robot = load_robot(model_ref)
    q0 = robot.check_configuration(robot_spec.get("initial_configuration", robot.neutral()))

    control = _section(spec, "controller")
    tasks = [_instantiate(entry, TASK_TYPES, "tasks", robot, q0) for entry in spec.get("tasks", [])]
    constraints = [_instantiate(entry, CONSTRAINT_TYPES, "constraints", robot, q0)
                   for entry in spec.get("constraints", [])]
    scenario = Scenario(
        name=spec.get("name", path.stem), robot=robot, q0=q0, tasks=tasks, constraints=constraints,
        solver=control.get("solver", "daqp"), dt=float(control.get("dt", 0.01)),
        duration=float(control.get("duration", 10.0)), damping=float(control.get("damping", 1e-3)),
        reduced=bool(control.get("reduced", False)), source=path, spec=spec,
    )
    if "reference" in spec:
        scenario.reference_task, scenario.reference = _reference(spec["reference"], tasks, robot, q0)
    return scenario


def _section(spec: dict, key: str) -> dict:
    value = spec.get(key, {})
    if not isinstance(value, dict):
        raise ScenarioError(f"[{key}] must be a table")
    return value


def _instantiate(entry: dict, registry: dict, section: str, robot: Robot, q0: np.ndarray):
    entry = dict(entry)
    kind = entry.pop("type", None)
    if kind not in registry:
        raise ScenarioError(f"[[{section}]] type {kind!r} unknown; known: {sorted(registry)}")
    if registry[kind] is PostureTask and entry.get("target") == "initial":
        entry["target"] = q0
    try:
        return registry[kind](**entry)
    except TypeError as exc:
        raise ScenarioError(f"[[{section}]] {kind}: {exc}") from exc


def _reference(spec: dict, tasks: list, robot: Robot, q0: np.ndarray):
    spec = dict(spec)
    kind = spec.pop("type", None)
    task_type = PositionTask if kind == "point" else FrameTask
    wanted = spec.pop("task", None)
    matches = [t for t in tasks if isinstance(t, task_type) and (wanted is None or t.name == wanted)]
    if not matches:
        raise ScenarioError(f"[reference] of type {kind!r} needs a {task_type.__name__}"
                            f"{'' if wanted is None else f' named {wanted!r}'}")
    task = matches[0]
    start = robot.frame_pose(q0, task.frame)
    if kind == "circle":
        reference = Circle(start=start, radius=spec.pop("radius"), period=spec.pop("period"),
                           normal=spec.pop("normal", [0.0, 0.0, 1.0]),
                           start_axis=spec.pop("start_axis", [1.0, 0.0, 0.0]),
                           ramp_time=spec.pop("ramp_time", 1.0))
    elif kind == "pose":
        reference = ConstantPose(_goal_pose(spec, start, robot, task.frame))
    elif kind == "line":
        reference = Line(start=start, end=_goal_pose(spec, start, robot, task.frame), speed=spec.pop("speed"),
                         ramp_time=spec.pop("ramp_time", 0.5))
    elif kind == "point":
        reference = ConstantPoint(spec.pop("position"))
    elif kind == "planned":
        goal = _goal_pose(spec, start, robot, task.frame)
        reference = plan_from_spec(spec, robot, task.frame, q0, start, goal).reference
    else:
        raise ScenarioError(f"[reference] type {kind!r} unknown; known: circle, pose, line, point, planned")
    if spec:
        raise ScenarioError(f"[reference] unknown keys for type {kind!r}: {sorted(spec)}")
    return task, reference


def _goal_pose(spec: dict, start: np.ndarray, robot: Robot, frame: str) -> np.ndarray:
    """The start pose, replaced by the frame's pose at ``configuration`` if given, then
    with ``position`` and/or ``rpy`` overridden (keys are consumed from ``spec``)."""
    pose = start.copy()
    if "configuration" in spec:
        pose = robot.frame_pose(spec.pop("configuration"), frame).copy()
    if "position" in spec:
        pose[:3, 3] = spec.pop("position")
    if "rpy" in spec:
        pose[:3, :3] = rpy_matrix(*spec.pop("rpy"))
    return pose
