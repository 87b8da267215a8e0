"""The node's configuration file (``wbc ros SCENARIO --config FILE``): how the robot's ROS 2
topics and joints map onto the controller. Every key is checked, strictly, like a scenario's::

    [node]          name = "wbc", namespace = "/", world_frame = "odom" (the frame of the
                    odometry and of every target pose; the controller's world)
    [state]         joint_states = "/joint_states" (sensor_msgs/JointState), odometry = "/odom"
                    (nav_msgs/Odometry; omitted: the node integrates its own base commands),
                    timeout = 0.25 [s] (older states stop the robot: the watchdog)
    [joints.NAME]   name = the joint's name on the robot (default NAME, the model's), zero = the
                    robot's position where the model's coordinate is 0 [rad or m], sign = 1 or -1
    [[controllers]] topic = a JointGroupVelocityController's commands (std_msgs/Float64MultiArray),
                    joints = the model's joints it drives, in the controller's order
    [base]          topic = "/cmd_vel", stamped = false (TwistStamped instead of Twist),
                    frame_id = "base_link" (of a TwistStamped); mobile bases only
    [targets]       poses = { FRAME = topic } (geometry_msgs/PoseStamped for the FrameTask or
                    PositionTask of FRAME, or of the task of that name; default ``~/FRAME/target``),
                    base_velocity = topic (geometry_msgs/Twist for the BaseVelocityTask; default
                    ``~/base_velocity/target``), twist_timeout = 0.5 [s] (an older twist is zero)
    [diagnostics]   topic = "/diagnostics" (diagnostic_msgs/DiagnosticArray), period = 1.0 [s]

Every joint of the model that is not a base coordinate must be driven by exactly one
controller. A configuration is read without a robot (:func:`read_config`) and then fitted to a
controller's robot and tasks (:func:`resolve`), which names what does not fit.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Literal

import numpy as np
from numpy.typing import NDArray
from pydantic import Field, ValidationError

from ..core.schema import Positive, Table, explain, read_toml, suggest
from ..model.robot import Robot
from ..tasks import BaseVelocityTask, FrameTask, PositionTask, Task
from .errors import RosConfigError
from .names import NODE_NAME, check_namespace, check_node_name, resolve_topic

#: the folder of the shipped configurations (``--config youbot``)
SHIPPED = Path(__file__).resolve().parent / "configs"
Topic = Annotated[str, Field(min_length=1)]


# ------------------------------------------------------------------------------ schema
class NodeTable(Table):
    name: str = "wbc"
    namespace: str = "/"
    world_frame: Annotated[str, Field(min_length=1)] = "odom"


class StateTable(Table):
    joint_states: Topic = "/joint_states"
    odometry: Topic | None = None
    timeout: Positive = 0.25


class JointTable(Table):
    name: Annotated[str, Field(min_length=1)] | None = None
    zero: float = 0.0
    sign: Literal[1, -1] = 1


class ControllerTable(Table):
    topic: Topic
    joints: Annotated[list[str], Field(min_length=1)]


class BaseTable(Table):
    topic: Topic = "/cmd_vel"
    stamped: bool = False
    frame_id: Annotated[str, Field(min_length=1)] = "base_link"


class TargetsTable(Table):
    poses: dict[str, Topic] = {}
    base_velocity: Topic | None = None
    twist_timeout: Positive = 0.5


class DiagnosticsTable(Table):
    topic: Topic = "/diagnostics"
    period: Positive = 1.0


class ConfigFile(Table):
    """The whole file."""

    node: NodeTable = NodeTable()
    state: StateTable = StateTable()
    joints: dict[str, JointTable] = {}
    controllers: list[ControllerTable] = []
    base: BaseTable | None = None
    targets: TargetsTable = TargetsTable()
    diagnostics: DiagnosticsTable = DiagnosticsTable()


# ----------------------------------------------------------------------- resolved form
@dataclass(frozen=True)
class JointWiring:
    """One joint of the model read from the joint states: ``q = sign (position - zero)``."""

    model_name: str
    ros_name: str
    q_index: int  #: its coordinate in q (the first of two, cos and sin, for a continuous joint)
    v_index: int  #: its coordinate in v
    continuous: bool  #: an unbounded revolute joint: q holds (cos, sin) of the angle
    zero: float
    sign: float


@dataclass(frozen=True)
class ControllerWiring:
    """One JointGroupVelocityController: ``data = sign * v[v_indices]`` on ``topic``."""

    topic: str
    joints: tuple[str, ...]  #: the model's joint names, in the controller's order
    v_indices: NDArray[np.intp]
    signs: NDArray[np.float64]


@dataclass(frozen=True)
class BaseWiring:
    """The base command: the base-frame twist on ``topic`` (a TwistStamped if ``stamped``)."""

    topic: str
    stamped: bool
    frame_id: str


@dataclass(frozen=True)
class PoseTarget:
    """PoseStamped messages on ``topic`` set the target of ``task``."""

    topic: str
    task: FrameTask | PositionTask


@dataclass(frozen=True)
class TwistTarget:
    """Twist messages on ``topic`` set the twist of ``task`` (zero after ``timeout`` [s])."""

    topic: str
    task: BaseVelocityTask
    timeout: float


@dataclass(frozen=True)
class NodeConfig:
    """A configuration fitted to a robot and its tasks: every topic fully qualified."""

    node: str
    namespace: str
    world_frame: str
    joint_states: str
    odometry: str | None
    timeout: float  #: [s] the watchdog
    joints: tuple[JointWiring, ...]
    controllers: tuple[ControllerWiring, ...]
    base: BaseWiring | None
    pose_targets: tuple[PoseTarget, ...]
    twist_target: TwistTarget | None
    diagnostics: str
    diagnostics_period: float
    source: Path | None = None

    @property
    def node_name(self) -> str:
        """The node's fully qualified name, e.g. ``/wbc``."""
        return f"{self.namespace.rstrip('/')}/{self.node}"


# ----------------------------------------------------------------------------- reading
def shipped_configs() -> list[str]:
    """The names of the shipped configurations (``--config NAME``)."""
    return sorted(path.stem for path in SHIPPED.glob("*.toml"))


def config_file(name_or_path: str | Path) -> Path:
    """The file of a configuration given by path, or by the name of a shipped one (a string
    without a folder or suffix that names no existing file, e.g. ``"youbot"``; a folder of that
    name in the working directory does not hide it).

    Raises:
        RosConfigError: a name that is no shipped configuration.
    """
    path = Path(name_or_path)
    if isinstance(name_or_path, str) and path.name == name_or_path and not path.suffix and not path.is_file():
        if name_or_path in shipped_configs():
            return SHIPPED / f"{name_or_path}.toml"
        raise RosConfigError(f"no configuration file or shipped configuration {name_or_path!r}"
                             f"{suggest(name_or_path, shipped_configs())}; shipped: {', '.join(shipped_configs())}")
    return path


def read_config(name_or_path: str | Path) -> tuple[ConfigFile, Path]:
    """The checked tables of a configuration file (given by path or shipped name) and its path.

    Raises:
        RosConfigError: an unreadable file, an unknown key, a wrong type, naming file and key.
    """
    path = config_file(name_or_path)
    return parse_config(read_toml(path, RosConfigError, "node configuration"), str(path)), path


def parse_config(tables: dict[str, object], where: str = "node configuration") -> ConfigFile:
    """The checked tables of a configuration given as parsed TOML.

    Raises:
        RosConfigError: an unknown key, a wrong type or value, naming ``where`` and the key.
    """
    try:
        return ConfigFile.model_validate(tables)
    except ValidationError as exc:
        raise RosConfigError(f"{where}: {explain(exc, ConfigFile)}") from None


def load_config(name_or_path: str | Path, robot: Robot, tasks: Sequence[Task]) -> NodeConfig:
    """Read a configuration file and fit it to ``robot`` and its controller's ``tasks``.

    Raises:
        RosConfigError: anything wrong in the file or anything that does not fit the robot,
            naming the file, the key and the fix.
    """
    tables, path = read_config(name_or_path)
    try:
        return resolve(tables, robot, tasks, path)
    except RosConfigError as exc:
        raise RosConfigError(f"{path}: {exc}") from None


# ----------------------------------------------------------------------------- fitting
def resolve(tables: ConfigFile, robot: Robot, tasks: Sequence[Task], source: Path | None = None) -> NodeConfig:
    """Fit checked tables to ``robot`` and ``tasks``: joints, controllers, base and targets.

    Raises:
        RosConfigError: a joint, frame or task the model does not have, a joint driven twice or
            not at all, a base table for a fixed base, a bad ROS 2 name, a topic used twice.
    """
    node, namespace = check_node_name(tables.node.name), check_namespace(tables.node.namespace)
    _check_frame(tables.node.world_frame, "[node] world_frame")

    def topic(name: str) -> str:
        return resolve_topic(name, namespace, node)

    joints = _joints(tables, robot)
    base = _base(tables, robot, topic)
    pose_targets, twist_target = _targets(tables.targets, tasks, topic)
    config = NodeConfig(
        node=node, namespace=namespace, world_frame=tables.node.world_frame,
        joint_states=topic(tables.state.joint_states),
        odometry=None if tables.state.odometry is None else topic(tables.state.odometry),
        timeout=tables.state.timeout, joints=tuple(joints), controllers=_controllers(tables, robot, joints, topic),
        base=base, pose_targets=pose_targets, twist_target=twist_target,
        diagnostics=topic(tables.diagnostics.topic), diagnostics_period=tables.diagnostics.period, source=source)
    _check_distinct_topics(config)
    return config


def _check_frame(frame: str, key: str) -> None:
    if frame.startswith("/") or not frame.strip():
        raise RosConfigError(f"{key} = {frame!r}: a tf2 frame name, without a leading \"/\" (e.g. \"odom\")")


def _joint_models(robot: Robot) -> dict[str, tuple[int, int, int, int]]:
    """name -> (q index, v index, nq, nv) of every joint of the model."""
    model = robot.model
    return {name: (joint.idx_q, joint.idx_v, joint.nq, joint.nv)
            for name, joint in zip(robot.joint_names, list(model.joints)[1:], strict=True)}


def _base_joints(robot: Robot) -> set[str]:
    """The model's joints that are base coordinates (read from odometry, commanded as a twist)."""
    if not robot.base.is_mobile:
        return set()
    indices = set(robot.base.indices)
    return {name for name, (_, v, _, _) in _joint_models(robot).items() if v in indices}


def _joints(tables: ConfigFile, robot: Robot) -> list[JointWiring]:
    """The wiring of every joint of the model that is not a base coordinate."""
    models, base = _joint_models(robot), _base_joints(robot)
    for name in tables.joints:
        if name not in models:
            raise RosConfigError(f"[joints.{name}]: robot {robot.name!r} has no joint {name!r}"
                                 f"{suggest(name, models)} (joints: {', '.join(robot.joint_names)})")
        if name in base:
            raise RosConfigError(f"[joints.{name}]: {name!r} is a base coordinate: it comes from [state] odometry "
                                 "(or the node's own integration), not from the joint states; remove the table")
    wiring: list[JointWiring] = []
    ros_names: dict[str, str] = {}
    for name, (q, v, nq, nv) in models.items():
        if name in base:
            continue
        if nv != 1 or nq not in (1, 2):
            raise RosConfigError(f"joint {name!r} of robot {robot.name!r} has {nq} position and {nv} velocity "
                                 "coordinates; the node reads revolute, prismatic and continuous joints only")
        table = tables.joints.get(name, JointTable())
        ros_name = table.name or name
        if ros_name in ros_names:
            raise RosConfigError(f"[joints]: joints {ros_names[ros_name]!r} and {name!r} both read the robot's "
                                 f"joint {ros_name!r}; give each its own name")
        ros_names[ros_name] = name
        wiring.append(JointWiring(name, ros_name, q, v, nq == 2, table.zero, float(table.sign)))
    return wiring


def _controllers(tables: ConfigFile, robot: Robot, joints: list[JointWiring],
                 topic: Callable[[str], str]) -> tuple[ControllerWiring, ...]:
    by_name = {joint.model_name: joint for joint in joints}
    base, driven, result = _base_joints(robot), dict[str, str](), []
    for k, table in enumerate(tables.controllers):
        label = f"[[controllers]] #{k + 1} ({table.topic})"
        for name in table.joints:
            if name in base:
                raise RosConfigError(f"{label}: {name!r} is a base coordinate, commanded through [base]; remove it")
            if name not in by_name:
                raise RosConfigError(f"{label}: robot {robot.name!r} has no joint {name!r}{suggest(name, by_name)} "
                                     f"(joints: {', '.join(by_name)})")
            if name in driven:
                raise RosConfigError(f"{label}: joint {name!r} is driven by {driven[name]} too; "
                                     "each joint belongs to one controller")
            driven[name] = label
        wired = [by_name[name] for name in table.joints]
        result.append(ControllerWiring(topic(table.topic), tuple(table.joints),
                                       np.array([joint.v_index for joint in wired], dtype=np.intp),
                                       np.array([joint.sign for joint in wired])))
    missing = [name for name in by_name if name not in driven]
    if missing:
        raise RosConfigError(f"joints {missing} are driven by no controller: add them to a [[controllers]] table, "
                             f"e.g.\n[[controllers]]\ntopic = \"/velocity_controller/commands\"\n"
                             f"joints = {missing!r}".replace("'", '"'))
    return tuple(result)


def _base(tables: ConfigFile, robot: Robot, topic: Callable[[str], str]) -> BaseWiring | None:
    if not robot.base.is_mobile:
        if tables.base is not None:
            raise RosConfigError(f"[base]: robot {robot.name!r} has a fixed base; remove the [base] table")
        if tables.state.odometry is not None:
            raise RosConfigError(f"[state] odometry: robot {robot.name!r} has a fixed base; remove the key")
        return None
    table = tables.base or BaseTable()
    _check_frame(table.frame_id, "[base] frame_id")
    return BaseWiring(topic(table.topic), table.stamped, table.frame_id)


def _targets(table: TargetsTable, tasks: Sequence[Task],
             topic: Callable[[str], str]) -> tuple[tuple[PoseTarget, ...], TwistTarget | None]:
    pose_tasks = [task for task in tasks if isinstance(task, (FrameTask, PositionTask))]
    frames = [task.frame for task in pose_tasks]
    targets = {}
    for key, name in table.poses.items():
        matches = [task for task in pose_tasks if task.name == key] or [t for t in pose_tasks if t.frame == key]
        if not matches:
            raise RosConfigError(f"[targets] poses: no FrameTask or PositionTask of frame or name {key!r}"
                                 f"{suggest(key, frames)} (frames: {', '.join(frames) or 'none'})")
        if len(matches) > 1:
            raise RosConfigError(f"[targets] poses: {len(matches)} tasks on frame {key!r}; key them by task name "
                                 f"({', '.join(repr(task.name) for task in matches)})")
        targets[id(matches[0])] = PoseTarget(topic(name), matches[0])
    for task in pose_tasks:  # the default topic of the others: ~/FRAME/target, if FRAME is a ROS name token
        if id(task) not in targets and frames.count(task.frame) == 1 and NODE_NAME.match(task.frame):
            targets[id(task)] = PoseTarget(topic(f"~/{task.frame}/target"), task)
    twist_tasks = [task for task in tasks if isinstance(task, BaseVelocityTask)]
    if table.base_velocity is not None and not twist_tasks:
        raise RosConfigError("[targets] base_velocity: the controller has no BaseVelocityTask; remove the key")
    twist = None
    if twist_tasks:
        twist = TwistTarget(topic(table.base_velocity or "~/base_velocity/target"), twist_tasks[0],
                            table.twist_timeout)
    ordered = tuple(targets[id(task)] for task in pose_tasks if id(task) in targets)
    return ordered, twist


def _check_distinct_topics(config: NodeConfig) -> None:
    roles = [("[state] joint_states", config.joint_states), ("[state] odometry", config.odometry),
             ("[base] topic", None if config.base is None else config.base.topic),
             ("[diagnostics] topic", config.diagnostics),
             *((f"[[controllers]] {c.joints[0]}...", c.topic) for c in config.controllers),
             *((f"[targets] poses {t.task.name}", t.topic) for t in config.pose_targets),
             ("[targets] base_velocity", None if config.twist_target is None else config.twist_target.topic)]
    seen: dict[str, str] = {}
    for role, name in roles:
        if name is None:
            continue
        if name in seen:
            raise RosConfigError(f"{seen[name]} and {role} are both topic {name}; give each its own topic")
        seen[name] = role
