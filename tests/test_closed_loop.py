"""Closed-loop behaviour on the shipped scenarios and on focused set-ups."""

from dataclasses import replace

import numpy as np
import pytest

import wbc
from conftest import TASKS
from wbc.app.closed_loop import position_violation, run, velocity_ratio
from wbc.app.scenario import load_scenario

VELOCITY_TOLERANCE = 1e-9  # solver tolerance on |v| <= limit


@pytest.fixture(scope="module")
def reach_run():
    scenario = load_scenario(TASKS / "youbot_reach.toml")
    return scenario, run(scenario)


@pytest.fixture(scope="module")
def circle_run():
    scenario = load_scenario(TASKS / "youbot_circle.toml")
    return scenario, run(scenario)


def test_reach_converges_to_the_pose(reach_run):
    scenario, result = reach_run
    assert result.position_error[-1] < 1e-4
    assert result.orientation_error[-1] < 1e-3
    # independent check of the final pose, not through the task's own error
    final = scenario.robot.frame_pose(result.q[-1], "ee")
    target = scenario.reference(0.0)[0]
    assert np.linalg.norm(final[:3, 3] - target[:3, 3]) < 1e-4
    assert np.arccos(np.clip((np.trace(final[:3, :3].T @ target[:3, :3]) - 1) / 2, -1, 1)) < 1e-3
    assert np.linalg.norm(result.q[-1][:2]) > 1.5, "the target is out of the arm's reach: the base must drive"


@pytest.mark.parametrize("name", sorted(p.stem for p in TASKS.glob("*.toml")))
def test_every_shipped_scenario_is_solved_without_fallback(name):
    scenario = load_scenario(TASKS / f"{name}.toml")
    result = run(scenario, duration=min(scenario.duration, 3.0))
    assert result.fallback_ticks == 0
    assert np.all(np.isfinite(result.v))


def test_reach_never_violates_limits(reach_run):
    scenario, result = reach_run
    robot = scenario.robot
    assert np.all(position_violation(robot, result.q) == 0.0)
    assert np.all(velocity_ratio(robot, result.q[:-1], result.v) <= 1.0 + VELOCITY_TOLERANCE)


def test_circle_is_tracked_and_needs_the_base(circle_run):
    scenario, result = circle_run
    assert result.position_error.max() < 1e-3
    assert result.orientation_error.max() < 1e-3
    base_y = result.q[:, 1]
    assert base_y.max() - base_y.min() > 0.3, "with the gripper orientation held, the base carries the circle"
    assert np.all(position_violation(scenario.robot, result.q) == 0.0)
    assert np.all(velocity_ratio(scenario.robot, result.q[:-1], result.v) <= 1.0 + VELOCITY_TOLERANCE)


def test_position_limit_damper_holds_against_an_unreachable_target(youbot):
    """Pulling the arm far past theta2's upper limit: q stops at the limit, never beyond."""
    q = np.array([0, 0, 0, 0, 1.2, 0.3, 0.2, 0.0])
    posture = wbc.PostureTask(1.0, target=np.r_[q[:4], 3.0, q[5:]], gain=1.0)
    controller = wbc.Controller(youbot, [posture], [wbc.JointPositionLimits(gain=0.5), wbc.JointVelocityLimits()])
    for _ in range(300):
        q = youbot.integrate(q, controller.step(q), controller.dt)
        assert q[4] <= youbot.upper[4]
    assert youbot.upper[4] - q[4] < 1e-6


def test_a_reference_without_its_task_is_refused_before_the_run():
    """A Scenario built by hand with a reference but no reference_task: a clear wbc error naming
    the missing field (it was an AttributeError on None in the first tick)."""
    scenario = replace(load_scenario(TASKS / "youbot_reach.toml"), reference_task=None)
    with pytest.raises(wbc.InvalidInputError, match="reference_task"):
        run(scenario, duration=0.1)


def test_base_velocity_task_tracks_feasible_twists_in_the_base_frame(youbot):
    task = wbc.BaseVelocityTask(1.0)
    controller = wbc.Controller(youbot, [task, wbc.PostureTask(1e-3)], [wbc.JointVelocityLimits()], damping=1e-9)
    q = np.array([1.0, 2.0, 0.7, 0, 0.5, 1.0, 1.2, 0])
    task.set_target([0.3, -0.2, 0.5])
    v = controller.step(q)
    c, s = np.cos(0.7), np.sin(0.7)
    np.testing.assert_allclose([c * v[0] + s * v[1], -s * v[0] + c * v[1], v[2]], [0.3, -0.2, 0.5], atol=1e-6)


def test_base_speed_limit_holds_in_the_base_frame(youbot):
    task = wbc.BaseVelocityTask(1.0)
    controller = wbc.Controller(youbot, [task], [wbc.JointVelocityLimits()])
    for yaw in np.linspace(-np.pi, np.pi, 13):
        q = np.array([0, 0, yaw, 0, 0.5, 1.0, 1.2, 0])
        task.set_target([2.0, 2.0, 3.0])  # beyond every limit
        v = controller.step(q)
        c, s = np.cos(yaw), np.sin(yaw)
        np.testing.assert_allclose([c * v[0] + s * v[1], -s * v[0] + c * v[1], v[2]], [0.8, 0.8, 1.0], atol=1e-7)


def test_posture_task_converges(youbot):
    target = np.array([0, 0, 0, 0.3, 0.6, 0.9, -0.4, 1.0])
    controller = wbc.Controller(youbot, [wbc.PostureTask(1.0, target=target, gain=0.2)],
                                [wbc.JointPositionLimits(), wbc.JointVelocityLimits()])
    q = np.array([0, 0, 0, 0, 0.5, 1.0, 1.2, 0.0])
    for _ in range(400):
        q = youbot.integrate(q, controller.step(q), controller.dt)
    np.testing.assert_allclose(q[3:], target[3:], atol=1e-6)
    np.testing.assert_allclose(q[:3], 0.0, atol=1e-12)  # the base is not part of the posture
