"""AxisAlignTask: an axis of a frame aligned with a world direction, the turn about it free."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

import wbc
from conftest import random_youbot_configurations
from test_look_at_task import rows

DT = 0.01
DOWN = np.array([0.0, 0.0, -1.0])


def rotation_error(robot: wbc.Robot, q: np.ndarray, axis: np.ndarray, target: np.ndarray) -> np.ndarray:
    """The angle-axis turning the frame's axis onto the target direction, written out (world axes)."""
    a = robot.frame_pose(q, "ee")[:3, :3] @ axis / np.linalg.norm(axis)
    t = target / np.linalg.norm(target)
    cross = np.cross(a, t)
    return np.arccos(np.clip(a @ t, -1.0, 1.0)) * cross / np.linalg.norm(cross)


def angle(robot: wbc.Robot, q: np.ndarray) -> float:
    """[rad] between the gripper's z axis and the world's -z."""
    return float(np.arccos(np.clip(robot.frame_pose(q, "ee")[:3, 2] @ DOWN, -1.0, 1.0)))


def test_two_rows_hold_the_whole_error_and_its_derivative(youbot, rng):
    """The 2 rows are the written-out angle-axis in an orthonormal basis perpendicular to the target
    (same norm: nothing lost), and J v is minus the central difference of those coordinates."""
    axis, target = np.array([0.2, 1.0, -0.3]), np.array([0.3, -0.4, 0.8])
    task = wbc.AxisAlignTask("ee", axis=axis, target_axis=target)
    basis = task._basis
    np.testing.assert_allclose(basis @ basis.T, np.eye(2), atol=1e-14)
    np.testing.assert_allclose(basis @ target, 0.0, atol=1e-14)
    h = 1e-6
    for q in random_youbot_configurations(rng, 12):
        error, J, _, _ = rows(youbot, q, task)
        written = rotation_error(youbot, q, axis, target)
        np.testing.assert_allclose(error, basis @ written, rtol=0, atol=1e-9)
        assert abs(np.linalg.norm(error) - np.linalg.norm(written)) < 1e-9
        v = rng.standard_normal(youbot.nv)
        plus = basis @ rotation_error(youbot, pin.integrate(youbot.model, q, h * v), axis, target)
        minus = basis @ rotation_error(youbot, pin.integrate(youbot.model, q, -h * v), axis, target)
        expected = -(plus - minus) / (2 * h)
        np.testing.assert_allclose(J @ v, expected, rtol=0, atol=1e-6 * (1 + np.abs(expected).max()))


def test_the_gripper_stays_vertical_while_the_position_task_moves_it(youbot):
    """The gripper first turns its z axis down (AxisAlign), then a PositionTask carries it 25 cm
    sideways and 10 cm up over 3 s: the z axis stays within 1e-4 rad of vertical at every tick
    and the gripper arrives."""
    q = np.array([0.0, 0.0, 0.0, 0.0, 1.0, 1.2, 0.4, 0.3])
    align = wbc.AxisAlignTask("ee", axis=[0, 0, 1], target_axis=DOWN, cost=10.0, gain=0.5)
    reach = wbc.PositionTask("ee", cost=1.0, gain=0.3)
    start = youbot.frame_pose(q, "ee")[:3, 3]
    reach.set_target(start)
    controller = wbc.Controller(youbot, [align, reach, wbc.PostureTask(1e-4, target=q, gain=0.05)],
                                [wbc.JointPositionLimits(), wbc.JointVelocityLimits()], dt=DT)
    initial = angle(youbot, q)
    for _ in range(200):
        q = youbot.integrate(q, controller.step(q), DT)
    assert initial > 0.3 and angle(youbot, q) < 1e-5
    goal = start + [0.0, 0.25, 0.1]
    worst = 0.0
    for tick in range(300):
        reach.set_target(start + (goal - start) * min(1.0, (tick + 1) / 200))
        q = youbot.integrate(q, controller.step(q), DT)
        worst = max(worst, angle(youbot, q))
    assert worst < 1e-4
    assert np.linalg.norm(youbot.frame_pose(q, "ee")[:3, 3] - goal) < 1e-3


def test_the_turn_about_the_target_axis_is_free(youbot):
    """Aligned, the rows do not see a turn about the target axis: J maps the arm's last joint (its
    axis along the gripper's z, here vertical) to zero, and the error is zero."""
    q = np.array([0.0, 0.0, 0.0, 0.0, 1.0, 1.2, 0.4, 0.3])
    align = wbc.AxisAlignTask("ee", axis=[0, 0, 1], target_axis=DOWN, gain=0.5)
    controller = wbc.Controller(youbot, [align], dt=DT)
    for _ in range(200):
        q = youbot.integrate(q, controller.step(q), DT)
    error, J, _, _ = rows(youbot, q, align)
    wrist = youbot.frame_jacobian(q, "ee")[3:, 7]
    assert abs(abs(wrist @ DOWN) - 1.0) < 1e-6  # the last joint turns about the vertical
    assert np.linalg.norm(error) < 1e-6 and np.abs(J[:, 7]).max() < 1e-6
    assert np.abs(J).max() > 0.1  # the other joints do tilt it


def test_bad_input_is_refused_by_name(youbot):
    with pytest.raises(wbc.InvalidInputError, match="target_axis must be a non-zero direction"):
        wbc.AxisAlignTask("ee", target_axis=[0.0, 0.0, 0.0])
    with pytest.raises(wbc.InvalidInputError, match="axis must have shape"):
        wbc.AxisAlignTask("ee", axis=[1.0, 0.0, 0.0, 0.0])
    task = wbc.AxisAlignTask("ee", cost=2.0)
    with pytest.raises(wbc.InvalidInputError, match="target_axis contains NaN"):
        task.set_target([np.nan, 0.0, 1.0])
    np.testing.assert_array_equal(task.target_axis, DOWN)  # kept
    with pytest.raises(wbc.InvalidInputError, match="cost must be finite and >= 0"):
        task.cost = -2.0
    with pytest.raises(wbc.UnknownFrameError):
        wbc.Controller(youbot, [wbc.AxisAlignTask("gripper")])
    assert repr(task) == ("AxisAlignTask(frame='ee', axis=[0.0, 0.0, 1.0], target_axis=[0.0, 0.0, -1.0], "
                          "cost=2.0, gain=1.0)")
