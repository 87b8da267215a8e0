"""RelativeFrameTask: the pose of a frame in another (moving) frame, written as an ErrorTask."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

import wbc
from conftest import random_youbot_configurations
from wbc.model.kinematics import Kinematics

DT = 0.01
#: (frame, root): the gripper in the platform, and in a link that shares joints with it
PAIRS = [("ee", "base_link"), ("ee", "arm_link_2"), ("arm_link_5", "arm_link_1")]


def relative_pose(robot: wbc.Robot, q: np.ndarray, frame: str, root: str) -> np.ndarray:
    return np.linalg.inv(robot.frame_pose(q, root)) @ robot.frame_pose(q, frame)


def rows(robot: wbc.Robot, q: np.ndarray, task: wbc.RelativeFrameTask) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The task data's (error, J, W J, W r) after one compute at q."""
    data = task.bind(robot)
    kin = Kinematics(robot)
    kin.update(q)
    WJ, Wr = np.zeros((6, robot.nv)), np.zeros(6)
    data.compute(kin, DT, WJ, Wr)
    return data.error.copy(), data.jacobian.copy(), WJ, Wr


@pytest.mark.parametrize("frame, root", PAIRS)
def test_the_jacobian_is_the_finite_difference_of_the_relative_pose(youbot, rng, frame, root):
    """J v = (dp/dt; w) of the relative pose, by central differences along random v:
    ``p`` in the root's axes, ``w`` from ``log3(R(q + h v) R(q - h v)^T) / 2h``."""
    task = wbc.RelativeFrameTask(frame, root)
    task.set_target(np.eye(4))
    h = 1e-6
    for q in random_youbot_configurations(rng, 10):
        _, J, _, _ = rows(youbot, q, task)
        v = rng.standard_normal(youbot.nv)
        plus = relative_pose(youbot, pin.integrate(youbot.model, q, h * v), frame, root)
        minus = relative_pose(youbot, pin.integrate(youbot.model, q, -h * v), frame, root)
        twist = np.r_[(plus[:3, 3] - minus[:3, 3]) / (2 * h), pin.log3(plus[:3, :3] @ minus[:3, :3].T) / (2 * h)]
        np.testing.assert_allclose(J @ v, twist, rtol=0, atol=1e-6 * (1 + np.abs(twist).max()))


@pytest.mark.parametrize("frame, root", PAIRS)
def test_the_jacobian_is_pinocchios_relative_twist(youbot, rng, frame, root):
    """Pinocchio: the frame's local twist minus the root's moved into the frame
    (``J_f^local - Ad(T_f^-1 T_r) J_r^local``), then rotated into the root's axes by ``R_r^T R_f``."""
    task = wbc.RelativeFrameTask(frame, root)
    task.set_target(np.eye(4))
    model, data = youbot.model, youbot.model.createData()
    frame_id, root_id = youbot.frame_id(frame), youbot.frame_id(root)
    for q in random_youbot_configurations(rng, 10):
        _, J, _, _ = rows(youbot, q, task)
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        Tf, Tr = data.oMf[frame_id], data.oMf[root_id]
        local = (pin.getFrameJacobian(model, data, frame_id, pin.LOCAL)
                 - (Tf.actInv(Tr)).toActionMatrix() @ pin.getFrameJacobian(model, data, root_id, pin.LOCAL))
        rotation = (Tr.actInv(Tf)).rotation
        expected = np.vstack([rotation @ local[:3], rotation @ local[3:]])
        np.testing.assert_allclose(J, expected, rtol=0, atol=1e-10)


def test_rows_are_the_written_out_objective_with_the_costs_of_the_tick(youbot, rng):
    """``W (J v - gain/dt e - xi)`` with e = (p* - p, log3(R* R^T)) in the root, costs changed after
    set_target (the feed-forward weighted with the new ones)."""
    q = random_youbot_configurations(rng, 1)[0]
    task = wbc.RelativeFrameTask("ee", "base_link", position_cost=1.0, orientation_cost=1.0, gain=0.4)
    target = relative_pose(youbot, q, "ee", "base_link")
    target[:3, 3] += [0.03, -0.02, 0.01]
    target[:3, :3] = pin.exp3(np.array([0.1, -0.2, 0.05])) @ target[:3, :3]
    twist = np.array([0.01, 0.02, -0.03, 0.1, 0.0, -0.2])
    task.set_target(target, twist)
    task.position_cost, task.orientation_cost = [4.0, 1.0, 9.0], 0.25
    error, J, WJ, Wr = rows(youbot, q, task)
    pose = relative_pose(youbot, q, "ee", "base_link")
    expected = np.r_[target[:3, 3] - pose[:3, 3], pin.log3(target[:3, :3] @ pose[:3, :3].T)]
    W = np.sqrt([4.0, 1.0, 9.0, 0.25, 0.25, 0.25])
    np.testing.assert_allclose(error, expected, rtol=0, atol=1e-12)
    np.testing.assert_allclose(WJ, W[:, None] * J, rtol=0, atol=1e-14)
    np.testing.assert_allclose(Wr, W * (0.4 / DT * expected + twist), rtol=1e-12, atol=1e-12)


def test_the_gripper_holds_its_pose_on_a_moving_platform(youbot):
    """Closed loop: the platform is driven at 0.2 m/s and 0.3 rad/s (BaseVelocityTask); the gripper,
    given a target in the platform's frame (its pose at other arm angles: the 5-joint arm reaches
    it), reaches it and holds it there while the base moves."""
    q = np.array([0.0, 0.0, 0.0, 0.2, 0.6, -0.8, 1.2, 0.3])
    target = relative_pose(youbot, q + [0.0, 0.0, 0.0, 0.3, -0.2, 0.25, 0.1, -0.3], "ee", "base_link")
    task = wbc.RelativeFrameTask("ee", "base_link", gain=0.3)
    task.set_target(target)
    base = wbc.BaseVelocityTask(1.0)
    base.set_target([0.2, 0.0, 0.3])
    controller = wbc.Controller(youbot, [task, base],
                                [wbc.JointPositionLimits(), wbc.JointVelocityLimits()], dt=DT)
    for _ in range(300):
        q = youbot.integrate(q, controller.step(q), DT)
    pose = relative_pose(youbot, q, "ee", "base_link")
    assert np.linalg.norm(pose[:3, 3] - target[:3, 3]) < 1e-5
    assert np.linalg.norm(pin.log3(target[:3, :3] @ pose[:3, :3].T)) < 1e-5
    assert np.hypot(q[0], q[1]) > 0.3  # the platform moved meanwhile
    assert controller.last.task_errors["RelativeFrameTask(ee in base_link).position"] < 1e-5


def test_bad_input_is_refused_by_name(youbot):
    with pytest.raises(wbc.InvalidInputError, match="frame and root"):
        wbc.RelativeFrameTask("ee", "ee")
    with pytest.raises(wbc.UnknownFrameError):
        wbc.Controller(youbot, [wbc.RelativeFrameTask("ee", "no_such_frame")])
    task = wbc.RelativeFrameTask("ee", "base_link")
    with pytest.raises(wbc.InvalidInputError, match="target pose"):
        task.set_target(np.full((4, 4), np.nan))
    controller = wbc.Controller(youbot, [task])
    with pytest.raises(wbc.InvalidInputError, match="no target set"):
        controller.step(youbot.neutral())
