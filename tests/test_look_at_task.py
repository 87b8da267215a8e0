"""LookAtTask: an axis of a frame pointed at a world point (error, exact Jacobian, closed loop, bad input)."""

from __future__ import annotations

import warnings

import numpy as np
import pinocchio as pin
import pytest

import wbc
from conftest import random_youbot_configurations
from wbc.model.kinematics import Kinematics

DT = 0.01


def rows(robot: wbc.Robot, q: np.ndarray, task: wbc.Task) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The task data's (error, J, W J, W r) after one compute at q."""
    data = task.bind(robot)
    kin = Kinematics(robot)
    kin.update(q)
    WJ, Wr = np.zeros((data.dim, robot.nv)), np.zeros(data.dim)
    data.compute(kin, DT, WJ, Wr)
    return data.error.copy(), data.jacobian.copy(), WJ, Wr


def look_error(robot: wbc.Robot, q: np.ndarray, axis: np.ndarray, point: np.ndarray) -> np.ndarray:
    """The angle-axis from the frame's axis to the line of sight, written out: arccos of the cosine,
    about the normalised cross product."""
    pose = robot.frame_pose(q, "ee")
    a = pose[:3, :3] @ axis / np.linalg.norm(axis)
    d = (point - pose[:3, 3]) / np.linalg.norm(point - pose[:3, 3])
    cross = np.cross(a, d)
    return np.arccos(np.clip(a @ d, -1.0, 1.0)) * cross / np.linalg.norm(cross)


def test_error_and_jacobian_are_the_written_out_angle_and_its_finite_difference(youbot, rng):
    """At random configurations and targets (errors up to ~pi): e is the arccos formula, and J v is
    minus its central difference along random v, the translation of the frame included."""
    axis = np.array([0.3, -0.2, 1.0])
    h = 1e-6
    for q in random_youbot_configurations(rng, 12):
        point = youbot.frame_pose(q, "ee")[:3, 3] + rng.uniform(-1.0, 1.0, 3)
        task = wbc.LookAtTask("ee", axis=axis, target=point)
        error, J, _, _ = rows(youbot, q, task)
        np.testing.assert_allclose(error, look_error(youbot, q, axis, point), rtol=0, atol=1e-9)
        v = rng.standard_normal(youbot.nv)
        plus = look_error(youbot, pin.integrate(youbot.model, q, h * v), axis, point)
        minus = look_error(youbot, pin.integrate(youbot.model, q, -h * v), axis, point)
        expected = -(plus - minus) / (2 * h)
        np.testing.assert_allclose(J @ v, expected, rtol=0, atol=1e-6 * (1 + np.abs(expected).max()))


def test_the_line_of_sight_turns_when_the_frame_only_translates(youbot):
    """Platform translation alone (v = e_x) leaves the gripper's axis as it is but turns the line of
    sight: the rows see it (a Jacobian of the rotation alone would be zero there)."""
    q = np.array([0.0, 0.0, 0.0, 0.2, 0.9, -0.8, 1.0, 0.4])
    pose = youbot.frame_pose(q, "ee")
    point = pose[:3, 3] + 0.5 * pose[:3, 2] + [0.0, 0.3, 0.0]
    task = wbc.LookAtTask("ee", axis=[0, 0, 1], target=point)
    _, J, _, _ = rows(youbot, q, task)
    v = np.eye(8)[0]
    h = 1e-6
    expected = -(look_error(youbot, q + h * v, np.array([0, 0, 1.0]), point)
                 - look_error(youbot, q - h * v, np.array([0, 0, 1.0]), point)) / (2 * h)
    assert np.abs(expected).max() > 0.1
    np.testing.assert_allclose(J @ v, expected, rtol=0, atol=1e-6)


def test_the_error_has_no_part_along_the_line_of_sight(youbot, rng):
    """The documented null direction: e is perpendicular to d (the turn about the line of sight is free)."""
    for q in random_youbot_configurations(rng, 5):
        pose = youbot.frame_pose(q, "ee")
        point = pose[:3, 3] + rng.uniform(-1.0, 1.0, 3)
        error, _, _, _ = rows(youbot, q, wbc.LookAtTask("ee", target=point))
        d = (point - pose[:3, 3]) / np.linalg.norm(point - pose[:3, 3])
        assert np.linalg.norm(error) > 1e-3
        assert abs(error @ d) < 1e-12


def test_rows_are_the_written_out_objective(youbot):
    q = np.array([0.1, -0.2, 0.3, 0.2, 0.9, -0.8, 1.0, 0.4])
    point = np.array([1.0, 0.5, 0.3])
    task = wbc.LookAtTask("ee", axis=[1, 0, 0], cost=1.0, gain=0.4, target=point)
    task.cost = [4.0, 1.0, 9.0]
    error, J, WJ, Wr = rows(youbot, q, task)
    W = np.array([2.0, 1.0, 3.0])
    np.testing.assert_allclose(WJ, W[:, None] * J, rtol=0, atol=1e-14)
    np.testing.assert_allclose(Wr, W * 0.4 / DT * look_error(youbot, q, np.array([1.0, 0, 0]), point), rtol=1e-9)


def test_the_gripper_axis_turns_onto_a_point_in_closed_loop(youbot):
    """From an axis ~1 rad off, the youBot's gripper z axis points at the target: the angle between
    it and the direction to the target (written out) falls below 1e-6 rad; the target stays put."""
    q = np.array([0.0, 0.0, 0.0, 0.2, 0.6, -0.8, 1.2, 0.3])
    point = np.array([0.9, 0.6, 0.2])
    task = wbc.LookAtTask("ee", axis=[0, 0, 1], cost=1.0, gain=0.3, target=point)
    controller = wbc.Controller(youbot, [task], [wbc.JointPositionLimits(), wbc.JointVelocityLimits()], dt=DT)
    start = np.linalg.norm(look_error(youbot, q, np.array([0, 0, 1.0]), point))
    for _ in range(400):
        q = youbot.integrate(q, controller.step(q), DT)
    assert start > 0.5
    assert np.linalg.norm(look_error(youbot, q, np.array([0, 0, 1.0]), point)) < 1e-6
    assert controller.last.task_errors[task.name] < 1e-6


def test_a_target_at_the_frame_origin_asks_nothing(youbot):
    """The documented fallback: closer than 1 mm to the frame origin the rows are zero, the command finite."""
    q = np.array([0.1, -0.2, 0.3, 0.2, 0.9, -0.8, 1.0, 0.4])
    origin = youbot.frame_pose(q, "ee")[:3, 3]
    for offset in (0.0, 5e-4):
        task = wbc.LookAtTask("ee", target=origin + offset)
        error, J, WJ, Wr = rows(youbot, q, task)
        assert not error.any() and not WJ.any() and not Wr.any()
        v = wbc.Controller(youbot, [task, wbc.PostureTask(1e-3)], [wbc.JointVelocityLimits()]).step(q)
        assert np.all(np.isfinite(v))
    error, _, _, _ = rows(youbot, q, wbc.LookAtTask("ee", target=origin + [0.0, 0.0, 2e-3]))
    assert np.linalg.norm(error) > 0  # past the threshold the task acts again


def test_an_axis_pointing_away_from_the_target_is_a_half_turn(youbot):
    """Opposed axis and line of sight: e = pi n, n perpendicular to the axis, finite rows that turn it."""
    q = np.array([0.1, -0.2, 0.3, 0.2, 0.9, -0.8, 1.0, 0.4])
    pose = youbot.frame_pose(q, "ee")
    task = wbc.LookAtTask("ee", axis=[0, 0, 1], target=pose[:3, 3] - 0.5 * pose[:3, 2])
    error, J, _, _ = rows(youbot, q, task)
    assert abs(np.linalg.norm(error) - np.pi) < 1e-9 and abs(error @ pose[:3, 2]) < 1e-9
    assert np.all(np.isfinite(J)) and np.abs(J).max() > 0.1


def test_bad_input_is_refused_by_name(youbot):
    with pytest.raises(wbc.InvalidInputError, match="axis must be a non-zero direction"):
        wbc.LookAtTask("ee", axis=[0, 0, 0])
    with pytest.raises(wbc.InvalidInputError, match="axis must have shape"):
        wbc.LookAtTask("ee", axis=[0, 1])
    with pytest.raises(wbc.InvalidInputError, match="axis contains NaN"):
        wbc.LookAtTask("ee", axis=[0, np.nan, 1])
    task = wbc.LookAtTask("ee", target=[1.0, 0.0, 0.5])
    with pytest.raises(wbc.InvalidInputError, match="target point contains NaN"):
        task.set_target([np.nan, 0.0, 0.0])
    with pytest.raises(wbc.InvalidInputError, match="target point must have shape"):
        task.set_target([1.0, 0.0])
    np.testing.assert_array_equal(task.target, [1.0, 0.0, 0.5])  # kept
    with pytest.raises(wbc.InvalidInputError, match="cost must be >= 0"):
        task.cost = -1.0
    with pytest.raises(wbc.UnknownFrameError):
        wbc.Controller(youbot, [wbc.LookAtTask("camera", target=[1.0, 0.0, 0.0])])
    controller = wbc.Controller(youbot, [wbc.LookAtTask("ee")])
    with pytest.raises(wbc.InvalidInputError, match="no target set"):
        controller.step(youbot.neutral())
    assert repr(task) == "LookAtTask(frame='ee', axis=[0.0, 0.0, 1.0], cost=[1.0, 1.0, 1.0], gain=1.0)"


def test_huge_finite_axes_and_targets_keep_their_direction(youbot):
    """Directions are normalised without overflow (``np.linalg.norm`` of entries near 1e308 is inf):
    an axis of 1e308s is the same unit axis as one of 1s, and a target at 1e308 (1, 1, 1) is looked
    at as one far along (1, 1, 1) -- no numpy warning in the tick, the rows those of a target at
    1e300 (1, 1, 1) (the line of sight's change with the frame's motion is 0 at that range)."""
    np.testing.assert_allclose(wbc.LookAtTask("ee", axis=[1e308, 1e308, 0.0]).axis, [2**-0.5, 2**-0.5, 0.0],
                               rtol=0, atol=1e-15)
    q = np.array([0.0, 0.0, 0.3, 0.2, 0.5, 1.0, 1.2, 0.0])
    commands = []
    for scale in (1e308, 1e300):
        task = wbc.LookAtTask("ee", axis=[0.0, 0.0, 1.0], target=[scale] * 3)
        controller = wbc.Controller(youbot, [task, wbc.PostureTask(1e-3)], [wbc.JointVelocityLimits()])
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            commands.append(controller.step(q))
        assert controller.last.success, controller.last.status
    assert np.abs(commands[1]).max() > 1e-3  # the task acts: not a zero row
    np.testing.assert_allclose(commands[0], commands[1], rtol=0, atol=1e-12)
