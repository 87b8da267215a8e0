"""Regression: the PUMA 560 makes Lu et al.'s move T_a -> T_b (tool orientation held, 0.3 m
sideways) whose straight line passes the wrist singularity theta5 = 0
(tasks/puma_wrist_pass_naive.toml) and the same move planned around it
(tasks/puma_wrist_pass.toml): IK samples and closed loop."""

import json
import sys

import numpy as np
import pinocchio as pin
import pytest

from conftest import TASKS
from wbc.analysis.singularity import singularity_measure
from wbc.app.cli import main
from wbc.app.closed_loop import run
from wbc.app.scenario import load_scenario
from wbc.core.errors import InvalidInputError, PlanningError, ScenarioError
from wbc.trajectory import JointTrajectory, LinePath, branch_switches, plan

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

PLANNED, NAIVE = TASKS / "puma_wrist_pass.toml", TASKS / "puma_wrist_pass_naive.toml"
THRESHOLD = 1e-4
WRIST = ("joint_4", "joint_5", "joint_6")
TOOL_ROTATION = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])  # tool z = world x
T_A, T_B = np.eye(4), np.eye(4)
T_A[:3, :3] = T_B[:3, :3] = TOOL_ROTATION
T_A[:3, 3], T_B[:3, 3] = [0.737, -0.30, 0.29], [0.737, 0.0, 0.29]


def spec(path):
    with open(path, "rb") as stream:
        return tomllib.load(stream)


@pytest.fixture(scope="module")
def scenarios():
    return {"planned": load_scenario(PLANNED), "naive": load_scenario(NAIVE)}


@pytest.fixture(scope="module")
def plans(scenarios):
    robot, q0 = scenarios["planned"].robot, scenarios["planned"].q0
    return {name: plan(robot, LinePath(T_A, T_B), q0, 6.0, THRESHOLD, reroute=name == "planned", wrist=WRIST)
            for name in ("planned", "naive")}


@pytest.fixture(scope="module")
def runs(scenarios):
    return {name: run(scenario) for name, scenario in scenarios.items()}


def test_files_differ_only_by_rerouting():
    planned, naive = spec(PLANNED), spec(NAIVE)
    assert planned.pop("name") == "puma_wrist_pass" and naive.pop("name") == "puma_wrist_pass_naive"
    planned.pop("description"), naive.pop("description")
    assert planned["reference"].pop("reroute") is True and naive["reference"].pop("reroute") is False
    assert planned == naive


def test_the_move_is_the_papers_shift_with_the_tool_orientation_held(scenarios):
    scenario = scenarios["planned"]
    np.testing.assert_allclose(scenario.robot.frame_pose(scenario.q0, "ee"), T_A, atol=1e-9)
    start, end = scenario.reference(0.0)[0].copy(), scenario.reference(100.0)[0]
    np.testing.assert_allclose(start, T_A, atol=1e-9)
    np.testing.assert_allclose(end, T_B, atol=1e-9)
    np.testing.assert_allclose(end[:3, :3], start[:3, :3], atol=1e-14)
    for t in np.linspace(0.0, 6.0, 25):  # the naive reference holds it all the way, on the straight line
        pose, twist = scenarios["naive"].reference(t)
        np.testing.assert_allclose(pose[:3, :3], start[:3, :3], atol=1e-14)
        np.testing.assert_allclose(pose[[0, 2], 3], T_A[[0, 2], 3], atol=1e-9)
        np.testing.assert_allclose(twist[[0, 2, 3, 4, 5]], 0.0, atol=1e-9)  # q0 gives T_a to 1e-10


def test_the_straight_line_passes_the_wrist_singularity(plans, scenarios):
    """Along the IK of the straight line the joint-4 axis (the forearm) swings through the
    tool axis: their angle, measured on the geometry (not read from theta5), drops below
    1 deg at mid-path, where the measure falls 100 times below the threshold."""
    robot, straight = scenarios["naive"].robot, plans["naive"].straight
    data = robot.model.createData()
    angles = []
    for q in straight.q:
        pin.forwardKinematics(robot.model, data, q)
        forearm = data.oMi[robot.model.getJointId("joint_4")].rotation[:, 2]
        angles.append(np.arccos(np.clip(forearm @ TOOL_ROTATION[:, 2], -1.0, 1.0)))
    angles = np.degrees(angles)
    closest = int(np.argmin(angles))
    assert angles[0] > 10.0 and angles[-1] > 10.0 and angles[closest] < 1.0
    assert 0.4 < closest / straight.time.size < 0.6
    np.testing.assert_allclose(angles, np.degrees(np.abs(straight.q[:, 4])), atol=1e-6)  # = |theta5|
    assert straight.min_measure < THRESHOLD / 10
    assert straight.measure[0] > 5 * THRESHOLD and straight.measure[-1] > 5 * THRESHOLD


def test_planned_path_avoids_the_singular_region(plans):
    planned = plans["planned"]
    assert planned.rerouted and len(planned.detours) == 1
    assert planned.min_measure > THRESHOLD
    assert np.abs(planned.joints.q[:, 4]).min() > np.radians(4.0)
    assert plans["naive"].min_measure < THRESHOLD / 10 and not plans["naive"].rerouted


def test_ik_samples_naive_flips_planned_does_not(plans, scenarios):
    robot = scenarios["planned"].robot
    naive, planned = plans["naive"], plans["planned"]
    assert len(naive.flips) == 1
    flip = naive.flips[0]
    assert flip.end - flip.start < 0.5 and abs(flip.change_a) >= np.pi / 2 and abs(flip.change_b) >= np.pi / 2
    assert naive.joints.max_speed_ratio(robot) > 5.0
    assert planned.flips == []
    assert planned.joints.max_speed_ratio(robot) <= 0.8 + 1e-9
    for trajectory in (naive.joints, planned.joints):  # both stay on the start's IK branch
        assert trajectory.jumps.size == 0 and np.all(trajectory.q[:, 4] < 0.0)
    np.testing.assert_allclose(planned.joints.q[-1], naive.joints.q[-1], atol=1e-9)  # same end configuration


def test_planned_reference_is_continuous_and_consistent(plans, scenarios):
    robot = scenarios["planned"].robot
    reference = plans["planned"].reference
    assert [type(s).__name__ for s in reference.segments] == ["TimedPath", "JointSegment", "TimedPath"]
    h = 1e-6
    for boundary in reference.starts[1:]:  # pose continuous, at rest, across each cut
        (before, twist_before), (after, twist_after) = reference(boundary - h), reference(boundary + h)
        assert np.abs(after - before).max() < 1e-9
        assert np.abs(twist_before).max() < 1e-6 and np.abs(twist_after).max() < 1e-6
    for t in np.linspace(0.1, reference.duration - 0.1, 40):  # twist = d(pose)/dt on every segment
        (before, _), (_, twist), (after, _) = reference(t - h), reference(t), reference(t + h)
        numeric = np.r_[(after[:3, 3] - before[:3, 3]) / (2 * h), pin.log3(after[:3, :3] @ before[:3, :3].T) / (2 * h)]
        np.testing.assert_allclose(numeric, twist, atol=1e-6)
    q = plans["planned"].joints.q
    assert np.abs(np.diff(q, axis=0)).max() < 0.03  # sampled joint trajectory without jumps
    for q_sample in q[::50]:
        assert robot.within_limits(q_sample)


def test_closed_loop_naive_switches_wrist_branch_planned_does_not(runs, scenarios):
    """In closed loop the speed limits hold joints 4 and 6 back during the naive flip; the
    tracking error then carries the wrist through theta5 = 0 onto the other IK branch. The
    planned reference keeps the wrist on its branch, off the region, below the limits."""
    robot = scenarios["planned"].robot
    naive, planned = runs["naive"], runs["planned"]

    def closed_loop(result) -> JointTrajectory:
        measure = np.array([singularity_measure(robot, q) for q in result.q[:-1]])
        return JointTrajectory(result.time, result.q[:-1], result.v, measure, np.zeros(0))

    naive_loop, planned_loop = closed_loop(naive), closed_loop(planned)
    assert branch_switches(robot, naive_loop, "joint_5").size == 1
    assert naive_loop.min_measure < THRESHOLD / 100
    # joints 4 and 6 run at their limits (99.6 % with the default error-scaled damping, which
    # takes the edge off the demand near theta5 = 0; 100 % without it)
    assert naive.velocity_ratio[:, [3, 5]].max() > 0.99
    assert branch_switches(robot, planned_loop, "joint_5").size == 0
    assert planned_loop.min_measure > THRESHOLD
    assert planned.velocity_ratio.max() < 0.9
    assert planned.position_error.max() < 2e-3 and planned.orientation_error.max() < 2e-3
    assert planned.position_error[-1] < 1e-9 and naive.position_error[-1] < 1e-9


def test_cli_overlays_naive_and_planned(tmp_path, capsys):
    plot = tmp_path / "wrist_pass.png"
    assert main(["run", str(NAIVE), str(PLANNED), "--duration", "1.0", "--no-progress", "--json",
                 "--plot", str(plot)]) == 0
    assert plot.stat().st_size > 10_000
    summaries = json.loads(capsys.readouterr().out)
    assert [s["scenario"] for s in summaries] == ["puma_wrist_pass_naive", "puma_wrist_pass"]


def test_bad_planned_references_raise_scenario_errors(tmp_path):
    base = PLANNED.read_text()
    cases = {
        "path": base.replace('path = "line"', 'path = "spiral"'),
        "duration": base.replace("duration = 6.0 ", "# no duration "),
        "keys": base.replace("reroute = true", "reroute = true\nspeed = 3.0"),
        "joint": base.replace('"joint_5", "joint_6"]', '"joint_5", "joint_60"]'),
    }
    for name, text in cases.items():
        path = tmp_path / f"{name}.toml"
        path.write_text(text)
        with pytest.raises(ScenarioError):
            load_scenario(path)


def test_planner_refuses_a_goal_inside_the_region(scenarios):
    robot, q0 = scenarios["planned"].robot, scenarios["planned"].q0
    goal = T_A.copy()
    goal[1, 3] = -0.15  # about where the line meets theta5 = 0
    with pytest.raises(PlanningError, match="start or goal"):
        plan(robot, LinePath(T_A, goal), q0, 3.0, THRESHOLD)


@pytest.mark.parametrize("wrist", [("joint_4",), ("joint_4", "joint_5", "joint_6", "joint_1"), "joint_4"])
def test_the_planner_takes_three_wrist_joints(scenarios, wrist):
    """``plan(wrist=...)`` names three joints; another count is refused before planning (was a raw
    IndexError for fewer, the extra ones silently ignored for more)."""
    robot, q0 = scenarios["planned"].robot, scenarios["planned"].q0
    with pytest.raises(InvalidInputError, match="wrist names three joints"):
        plan(robot, LinePath(T_A, T_B), q0, 6.0, THRESHOLD, wrist=wrist)
