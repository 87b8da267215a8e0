"""Copies of tasks and constraints: ``copy.copy``, ``copy.deepcopy`` and pickling give an item
whose settings act, independent of the original (``wbc.item.Item``, "Copies").

Tested over every item class the package defines (found by importing every module of ``wbc``
and walking the subclasses of ``wbc.item.Item``), each with an example whose every setting --
``Item.settings()`` and ``set_target`` -- changes the command: a new item, or a new setting,
fails here until it has one.
"""

from __future__ import annotations

import copy
import importlib
import pickle
import pkgutil
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin
import pytest

import wbc
from wbc.constraints.barrier import Barrier
from wbc.constraints.constraint import ConstraintData
from wbc.item import Item
from wbc.tasks.com_task import center_of_mass
from wbc.tasks.error_task import ErrorTask


def _package_items() -> set[type]:
    """Every subclass of Item defined in the wbc package (all of its modules imported)."""
    for module in pkgutil.walk_packages(wbc.__path__, "wbc."):
        if not module.name.endswith(".__main__"):  # (python -m wbc: runs the command line)
            importlib.import_module(module.name)
    found, pending = set(), [Item]
    while pending:
        for subclass in pending.pop().__subclasses__():
            if subclass.__module__.split(".")[0] == "wbc" and subclass not in found:
                found.add(subclass)
                pending.append(subclass)
    return found


#: base classes that are not items of a stack by themselves
BASES = {wbc.Task, wbc.Constraint, ErrorTask, Barrier}

YOUBOT = wbc.load_robot("youbot")
DELUCA = wbc.load_robot("deluca_mm")
Q_YOUBOT = np.array([0.1, -0.2, 0.3, 0.2, 0.4, -0.8, 0.6, 0.1])
Q_DELUCA = np.array([0.0, 0.0, 0.4, 0.2, 0.8, 1.0])


def _shifted_pose(robot: wbc.Robot, q: np.ndarray, shift, rotation) -> np.ndarray:
    pose = robot.frame_pose(q, robot.end_effector).copy()
    pose[:3, :3] = pin.exp3(np.array(rotation)) @ pose[:3, :3]
    pose[:3, 3] += shift
    return pose


def _frame_task() -> wbc.FrameTask:
    task = wbc.FrameTask("ee", position_cost=1.0, orientation_cost=0.5, gain=0.01)
    task.set_target(_shifted_pose(YOUBOT, Q_YOUBOT, [0.1, -0.05, 0.05], [0.1, -0.2, 0.2]))
    return task


def _relative_frame_task() -> wbc.RelativeFrameTask:
    task = wbc.RelativeFrameTask("ee", "base_link", position_cost=1.0, orientation_cost=0.5, gain=0.01)
    task.set_target(np.linalg.solve(YOUBOT.frame_pose(Q_YOUBOT, "base_link"),
                                    _shifted_pose(YOUBOT, Q_YOUBOT, [0.1, -0.05, 0.05], [0.1, -0.2, 0.2])))
    return task


def _position_task(robot: wbc.Robot = YOUBOT, q: np.ndarray = Q_YOUBOT) -> wbc.PositionTask:
    task = wbc.PositionTask(robot.end_effector, cost=1.0, gain=0.01)
    task.set_target(robot.frame_pose(q, robot.end_effector)[:3, 3] + [0.1, 0.3, -0.05])
    return task


def _ball_ahead() -> wbc.Sphere:
    """A ball 0.054 m ahead of the gripper at Q_YOUBOT."""
    return wbc.Sphere(YOUBOT.frame_pose(Q_YOUBOT, "ee")[:3, 3] + [0.12, 0.0, 0.0], 0.05)


def _toward_ball() -> wbc.PositionTask:
    task = wbc.PositionTask("ee", cost=1.0, gain=0.5)
    task.set_target(YOUBOT.frame_pose(Q_YOUBOT, "ee")[:3, 3] + [0.3, 0.0, 0.0])  # through the ball
    return task


def _point_ahead_of_the_base() -> wbc.BaseFootprintAvoidance:
    """A scan point 5.2 cm ahead of the youBot's footprint at Q_YOUBOT (its rows bind at 0.1 m/s)."""
    c, s = np.cos(Q_YOUBOT[2]), np.sin(Q_YOUBOT[2])
    point = Q_YOUBOT[:2] + np.array([[c, -s], [s, c]]) @ [0.29 + 0.052, 0.0]
    return wbc.BaseFootprintAvoidance([[-0.29, -0.19], [0.29, -0.19], [0.29, 0.19], [-0.29, 0.19]], points=[point])


def _base_velocity_task() -> wbc.BaseVelocityTask:
    task = wbc.BaseVelocityTask(cost=1e-2)
    task.set_target([0.2, -0.1, 0.3])
    return task


def _near_limit(robot: wbc.Robot, q: np.ndarray, joint: int, margin: float) -> np.ndarray:
    """``q`` with coordinate ``joint`` ``margin`` below its upper limit."""
    q = q.copy()
    q[joint] = robot.upper[joint] - margin
    return q


@dataclass
class Example:
    """An item in a stack where each of its settings changes the command.

    ``make()``: a new item; ``stack()``: the other tasks and constraints; ``changes``: for each
    setting (and ``set_target``) a function that changes it on an item.
    """

    robot: wbc.Robot
    q: np.ndarray
    make: Callable[[], Item]
    changes: dict[str, Callable[[Item], None]]
    stack: Callable[[], list[Item]] = list
    options: dict = field(default_factory=dict)


Q_LIMIT = _near_limit(YOUBOT, Q_YOUBOT, 5, 0.01)
Q_AT_LIMIT = np.where(np.arange(8) == 5, YOUBOT.upper, Q_YOUBOT)  # arm_joint_3 on its upper limit
#: the youBot's arm stretched toward its singular upright pose, where m is small
Q_STRETCHED = np.array([0.1, -0.2, 0.3, 0.2, 0.05, 0.05, 0.05, 0.1])


def _com_task() -> wbc.CoMTask:
    task = wbc.CoMTask(cost=[1.0, 1.0, 0.5], gain=0.01)
    task.set_target(center_of_mass(YOUBOT, Q_YOUBOT) + [0.02, -0.01, 0.01])
    return task


def _support_polygon() -> wbc.SupportPolygon:
    """A square 5 mm ahead of the centre of mass in the platform's frame at Q_YOUBOT (a reach
    forward pushes it into the front edge)."""
    pose = YOUBOT.frame_pose(Q_YOUBOT, "base_link")
    front = (pose[:3, :3].T @ (center_of_mass(YOUBOT, Q_YOUBOT) - pose[:3, 3]))[0] + 0.005
    return wbc.SupportPolygon([[-0.3, -0.3], [front, -0.3], [front, 0.3], [-0.3, 0.3]], frame="base_link", gain=0.5)


def _reach_forward() -> wbc.PositionTask:
    task = wbc.PositionTask("ee", gain=0.5)
    task.set_target(YOUBOT.frame_pose(Q_YOUBOT, "ee")[:3, 3] + [0.3, 0.0, -0.05])
    return task


def _still_base() -> wbc.BaseVelocityTask:
    still = wbc.BaseVelocityTask(100.0)
    still.set_target([0.0, 0.0, 0.0])
    return still

EXAMPLES: dict[type, Example] = {
    wbc.FrameTask: Example(YOUBOT, Q_YOUBOT, _frame_task, {
        "gain": lambda t: setattr(t, "gain", 0.03),
        "max_speed": lambda t: setattr(t, "max_speed", 0.02),
        "max_angular_speed": lambda t: setattr(t, "max_angular_speed", 0.02),
        "position_cost": lambda t: setattr(t, "position_cost", [3.0, 1.0, 0.2]),
        "orientation_cost": lambda t: setattr(t, "orientation_cost", 0.05),
        "set_target": lambda t: t.set_target(_shifted_pose(YOUBOT, Q_YOUBOT, [-0.1, 0.1, 0.0], [0.3, 0.0, 0.0]),
                                             twist=[0.01, 0, 0, 0, 0.02, 0]),
    }, stack=lambda: [wbc.PostureTask(1e-2)]),
    wbc.RelativeFrameTask: Example(YOUBOT, Q_YOUBOT, _relative_frame_task, {
        "gain": lambda t: setattr(t, "gain", 0.03),
        "position_cost": lambda t: setattr(t, "position_cost", [3.0, 1.0, 0.2]),
        "orientation_cost": lambda t: setattr(t, "orientation_cost", 0.05),
        "set_target": lambda t: t.set_target(np.linalg.solve(YOUBOT.frame_pose(Q_YOUBOT, "base_link"), _shifted_pose(
            YOUBOT, Q_YOUBOT, [-0.1, 0.1, 0.0], [0.3, 0.0, 0.0])), twist=[0.01, 0, 0, 0, 0.02, 0]),
    }, stack=lambda: [wbc.PostureTask(1e-2)]),
    wbc.PositionTask: Example(YOUBOT, Q_YOUBOT, _position_task, {
        "gain": lambda t: setattr(t, "gain", 0.03),
        "max_speed": lambda t: setattr(t, "max_speed", 0.01),
        "cost": lambda t: setattr(t, "cost", [0.1, 2.0, 1.0]),
        "set_target": lambda t: t.set_target([0.2, 0.3, 0.4], velocity=[0.0, 0.01, 0.0]),
    }, stack=lambda: [wbc.PostureTask(1e-2)]),
    wbc.LookAtTask: Example(YOUBOT, Q_YOUBOT, lambda: wbc.LookAtTask("ee", gain=0.01, target=[1.0, 0.5, 0.3]), {
        "cost": lambda t: setattr(t, "cost", [3.0, 0.1, 1.0]),
        "gain": lambda t: setattr(t, "gain", 0.03),
        "set_target": lambda t: t.set_target([0.5, -0.5, 1.0]),
    }, stack=lambda: [wbc.PostureTask(1e-2)]),
    wbc.AxisAlignTask: Example(YOUBOT, Q_YOUBOT, lambda: wbc.AxisAlignTask("ee", cost=1.0, gain=0.01), {
        "cost": lambda t: setattr(t, "cost", 0.1),
        "gain": lambda t: setattr(t, "gain", 0.03),
        "set_target": lambda t: t.set_target([1.0, 0.0, 0.0]),
    }, stack=lambda: [wbc.PostureTask(1e-2)]),
    wbc.DampingTask: Example(YOUBOT, Q_YOUBOT, lambda: wbc.DampingTask(1e-2), {
        "cost": lambda t: setattr(t, "cost", [1.0, 1.0, 1.0, 1e-3, 1e-3, 1e-3, 1e-3, 1e-3]),
    }, stack=lambda: [_position_task()]),
    wbc.KineticEnergyRegularization: Example(YOUBOT, Q_YOUBOT, lambda: wbc.KineticEnergyRegularization(1e-2), {
        "cost": lambda t: setattr(t, "cost", 1.0),
    }, stack=lambda: [_position_task()]),
    wbc.LinearTask: Example(YOUBOT, Q_YOUBOT, lambda: wbc.LinearTask([[0, 0, 0, 1, -1, 0, 0, 0]], b=[0.1], cost=1.0), {
        "cost": lambda t: setattr(t, "cost", 1e-2),
        "set_target": lambda t: t.set_target([-0.2]),
    }, stack=lambda: [_position_task()]),
    wbc.LinearCost: Example(YOUBOT, Q_YOUBOT, lambda: wbc.LinearCost(np.full(8, 1e-3)), {
        "c": lambda t: setattr(t, "c", [0.0, 2e-3, 0.0, -1e-3, 0.0, 0.0, 1e-3, 0.0]),
    }, stack=lambda: [_position_task()]),
    wbc.ManipulabilityGradient: Example(YOUBOT, Q_YOUBOT, lambda: wbc.ManipulabilityGradient("ee", 1e-3), {
        "cost": lambda t: setattr(t, "cost", 1e-2),
    }, stack=lambda: [_position_task()]),
    wbc.LinearConstraint: Example(YOUBOT, Q_YOUBOT, lambda: wbc.LinearConstraint([[0, 0, 0, 1, -1, 0, 0, 0]]), {
        "set_target": lambda t: t.set_target([0.05]),
    }, stack=lambda: [_position_task()]),
    wbc.PostureTask: Example(YOUBOT, Q_YOUBOT, lambda: wbc.PostureTask(1e-2, gain=0.1), {
        "gain": lambda t: setattr(t, "gain", 0.5),
        "set_target": lambda t: t.set_target(Q_YOUBOT + 0.2),
    }, stack=lambda: [_position_task()]),
    wbc.BaseVelocityTask: Example(YOUBOT, Q_YOUBOT, _base_velocity_task, {
        "cost": lambda t: setattr(t, "cost", [1.0, 1e-3, 1e-2]),
        "set_target": lambda t: t.set_target([-0.1, 0.2, 0.0]),
    }, stack=lambda: [_position_task()]),
    wbc.ManipulabilityTask: Example(YOUBOT, Q_STRETCHED, lambda: wbc.ManipulabilityTask("ee", 1e-3, target=0.1), {
        "cost": lambda t: setattr(t, "cost", 1e-1),
        "gain": lambda t: setattr(t, "gain", 0.5),
        "target": lambda t: setattr(t, "target", 0.01),
    }, stack=lambda: [wbc.PostureTask(1e-2)]),
    wbc.SteeringTask: Example(DELUCA, Q_DELUCA, lambda: wbc.SteeringTask(cost=1.0, gain=0.1, speed_scale=0.1), {
        "cost": lambda t: setattr(t, "cost", 10.0),
        "gain": lambda t: setattr(t, "gain", 0.5),
        "speed_scale": lambda t: setattr(t, "speed_scale", 1e3),
    }, stack=lambda: [_position_task(DELUCA, Q_DELUCA), wbc.PostureTask(1e-3), wbc.NonholonomicBase()]),
    wbc.JointPositionLimits: Example(YOUBOT, Q_LIMIT, lambda: wbc.JointPositionLimits(gain=0.5), {
        "gain": lambda c: setattr(c, "gain", 0.1),
    }, stack=lambda: [wbc.PostureTask(1.0, target=Q_LIMIT + 0.5, gain=0.5)]),
    wbc.JointVelocityLimits: Example(YOUBOT, Q_YOUBOT, wbc.JointVelocityLimits, {},
                                     stack=lambda: [wbc.PostureTask(1.0, target=-Q_YOUBOT, gain=1.0),
                                                    _base_velocity_task()]),
    wbc.ManipulabilityBarrier: Example(YOUBOT, Q_STRETCHED, lambda: wbc.ManipulabilityBarrier("ee", 0.02, gain=0.5), {
        "gain": lambda c: setattr(c, "gain", 0.1),
        "min_value": lambda c: setattr(c, "min_value", 0.025),
    }, stack=lambda: [wbc.PostureTask(1.0, target=np.zeros(8), gain=0.5)]),
    wbc.WheelSpeedLimits: Example(YOUBOT, Q_YOUBOT, lambda: wbc.WheelSpeedLimits(max_speed=2.0), {},
                                  stack=lambda: [_base_velocity_task(), wbc.PostureTask(1e-3)]),
    wbc.MecanumWheelLimits: Example(YOUBOT, Q_YOUBOT, lambda: wbc.MecanumWheelLimits(max_speed=2.0), {},
                                    stack=lambda: [_base_velocity_task(), wbc.PostureTask(1e-3)]),
    wbc.CollisionAvoidance: Example(YOUBOT, Q_YOUBOT, lambda: wbc.CollisionAvoidance([_ball_ahead()]), {
        "gain": lambda c: setattr(c, "gain", 0.1),
        "min_distance": lambda c: setattr(c, "min_distance", 0.04),
        "detection_distance": lambda c: setattr(c, "detection_distance", 0.05),  # the ball's pair (0.054 m) leaves
    }, stack=lambda: [_toward_ball(), wbc.PostureTask(1e-2)]),
    # arm_joint_3 on its limit: the braking bound stops it; the other joints' demand is inside one tick's
    # acceleration (0.02 < pi * 0.01 rad/s), so the command is the same every tick at this q
    wbc.AccelerationLimits: Example(YOUBOT, Q_AT_LIMIT, wbc.AccelerationLimits, {},
                                    stack=lambda: [wbc.PostureTask(1.0, target=Q_AT_LIMIT + 0.002, gain=0.1)]),
    wbc.CoMTask: Example(YOUBOT, Q_YOUBOT, _com_task, {
        "cost": lambda t: setattr(t, "cost", [0.1, 2.0, 1.0]),
        "gain": lambda t: setattr(t, "gain", 0.05),
        "set_target": lambda t: t.set_target(center_of_mass(YOUBOT, Q_YOUBOT) + [-0.02, 0.0, 0.0], [0.0, 0.01, 0.0]),
    }, stack=lambda: [wbc.PostureTask(1e-2)]),
    wbc.SupportPolygon: Example(YOUBOT, Q_YOUBOT, _support_polygon, {
        "gain": lambda c: setattr(c, "gain", 0.1),
        "margin": lambda c: setattr(c, "margin", 0.003),
    }, stack=lambda: [_reach_forward(), _still_base(), wbc.PostureTask(1e-3)]),
    wbc.DofFreezing: Example(YOUBOT, Q_YOUBOT, lambda: wbc.DofFreezing(["arm_joint_2"]), {},
                             stack=lambda: [wbc.PostureTask(1.0, target=-Q_YOUBOT, gain=1.0)]),
    wbc.MimicJoints: Example(YOUBOT, Q_YOUBOT, lambda: wbc.MimicJoints([("arm_joint_4", "arm_joint_3", 0.5)]), {},
                             stack=lambda: [wbc.PostureTask(1.0, target=-Q_YOUBOT, gain=1.0)]),
    wbc.BaseFootprintAvoidance: Example(YOUBOT, Q_YOUBOT, _point_ahead_of_the_base, {
        "gain": lambda c: setattr(c, "gain", 0.1),
        "min_distance": lambda c: setattr(c, "min_distance", 0.051),
        "detection_distance": lambda c: setattr(c, "detection_distance", 0.051),  # the point (0.052 m) leaves
    }, stack=lambda: [_base_velocity_task(), wbc.PostureTask(1e-3)]),
    wbc.NonholonomicBase: Example(DELUCA, Q_DELUCA, wbc.NonholonomicBase, {},
                                  stack=lambda: [_position_task(DELUCA, Q_DELUCA), wbc.PostureTask(1e-3)]),
}

COPIES = {
    "copy.copy": copy.copy,
    "copy.deepcopy": copy.deepcopy,
    "pickle": lambda item: pickle.loads(pickle.dumps(item)),
}


def _controller(example: Example, item: Item | None) -> wbc.Controller:
    items = example.stack() + ([item] if item is not None else [])
    return wbc.Controller(example.robot, [i for i in items if isinstance(i, wbc.Task)],
                          [i for i in items if isinstance(i, wbc.Constraint)], dt=0.01, **example.options)


def _command(example: Example, item: Item | None) -> np.ndarray:
    controller = _controller(example, item)
    v = controller.step(example.q)
    assert controller.last.success, controller.last.status
    return v


def test_every_item_of_the_package_has_an_example_of_each_setting():
    items = _package_items() - BASES
    missing, extra = items - set(EXAMPLES), set(EXAMPLES) - items
    assert not missing and not extra, (f"items without an example here: {sorted(c.__name__ for c in missing)}; "
                                       f"examples of no item: {sorted(c.__name__ for c in extra)}")
    for cls, example in EXAMPLES.items():
        settings = set(cls.settings()) | ({"set_target"} if hasattr(cls, "set_target") else set())
        assert set(example.changes) == settings, f"{cls.__name__}: settings {sorted(settings)}"
        assert type(example.make()) is cls


@pytest.mark.parametrize("cls", sorted(EXAMPLES, key=lambda c: c.__name__), ids=lambda c: c.__name__)
def test_each_example_acts_and_each_setting_changes_the_command(cls):
    """The examples are sharp: the item changes the command, and so does each setting."""
    example = EXAMPLES[cls]
    command = _command(example, example.make())
    try:
        without = _command(example, None)
    except wbc.InvalidInputError:  # required (NonholonomicBase without reduced=True)
        without = None
    assert without is None or np.max(np.abs(command - without)) > 1e-6
    for name, change in example.changes.items():
        item = example.make()
        change(item)
        assert np.max(np.abs(_command(example, item) - command)) > 1e-9, f"{cls.__name__}.{name}"


@pytest.mark.parametrize("how", COPIES)
@pytest.mark.parametrize("cls", sorted(EXAMPLES, key=lambda c: c.__name__), ids=lambda c: c.__name__)
def test_a_copy_acts_with_its_settings_and_leaves_the_original_alone(cls, how):
    """A copy of an item (new, or used by a controller) commands what a new item does; each
    setting changed on it afterwards -- once a controller uses it -- acts as on a new item,
    and the original's controller commands what it did."""
    example, duplicate = EXAMPLES[cls], COPIES[how]
    original = example.make()
    original_controller = _controller(example, original)
    before = original_controller.step(example.q)
    for name, change in {"": None, **example.changes}.items():
        item = duplicate(original)
        assert type(item) is cls and item is not original
        controller = _controller(example, item)
        fresh = example.make()
        if change is not None:
            change(item)  # after the controller was built with it
            change(fresh)
        np.testing.assert_allclose(controller.step(example.q), _command(example, fresh), rtol=1e-12, atol=1e-12,
                                   err_msg=f"{how} of a {cls.__name__}, then {name or 'nothing'} changed")
        # (a warm-started solve of the same QP: the same answer to rounding)
        np.testing.assert_allclose(original_controller.step(example.q), before, rtol=1e-12, atol=1e-12,
                                   err_msg=f"{how} of a {cls.__name__}: {name} changed on the copy moved the "
                                              "original")
        if hasattr(item, "target") and name == "set_target":
            assert not np.array_equal(np.asarray(item.target), np.asarray(original.target))
            np.testing.assert_array_equal(np.asarray(item.target), np.asarray(fresh.target))


class StopJoint(wbc.Constraint, ConstraintData):
    """A constraint that is its own data: ``v[index] = 0``."""

    n_equalities = 1

    def __init__(self, index: int) -> None:
        super().__init__()
        self.index = index

    def write_static(self, rows):
        rows.A[0, self.index] = 1.0

    def compute(self, kin, dt, rows):
        pass


@pytest.mark.parametrize("how", COPIES)
def test_a_copy_of_a_used_item_starts_unused(how):
    """The copy of an item a controller uses may still have any attribute set, and a copy of an
    item that is its own data serves another robot object (the original is bound to the first)."""
    task, stop = wbc.PositionTask("ee"), StopJoint(4)
    wbc.Controller(YOUBOT, [task, wbc.PostureTask(1.0)], [stop])
    with pytest.raises(wbc.InvalidInputError, match="cannot change once a controller uses"):
        task.frame = "arm_link_5"
    other = wbc.load_robot("youbot")
    with pytest.raises(wbc.InvalidInputError, match="bound to another robot object"):
        wbc.Controller(other, [wbc.PostureTask(1.0)], [stop])
    copied, copied_stop = COPIES[how](task), COPIES[how](stop)
    copied.frame = "arm_link_5"
    assert copied.frame == "arm_link_5" and task.frame == "ee"
    posture = wbc.PostureTask(1.0, target=Q_YOUBOT + 1.0)
    v = wbc.Controller(other, [posture], [copied_stop]).step(Q_YOUBOT)
    assert v[4] == 0.0 and abs(v[5]) > 0.1
