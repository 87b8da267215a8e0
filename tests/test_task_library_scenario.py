"""Scenario files name the task library's items (tasks/youbot_look_at.toml) and get clear errors for bad ones."""

from __future__ import annotations

import numpy as np
import pytest

import wbc
from conftest import ROOT
from wbc.app.closed_loop import run
from wbc.app.scenario import load_scenario
from wbc.core.errors import ScenarioError

SCENARIO = ROOT / "tasks" / "youbot_look_at.toml"


def test_the_look_at_scenario_reaches_the_point_with_the_marker_in_view():
    """The gripper reaches the reference point and its z axis points at the marker (written out)."""
    scenario = load_scenario(SCENARIO)
    kinds = {type(task) for task in scenario.tasks}
    assert {wbc.LookAtTask, wbc.DampingTask, wbc.KineticEnergyRegularization} <= kinds
    result = run(scenario)
    pose = scenario.robot.frame_pose(result.q[-1], "ee")
    marker = np.array([3.0, 0.3, 0.5])
    sight = (marker - pose[:3, 3]) / np.linalg.norm(marker - pose[:3, 3])
    assert result.fallback_ticks == 0
    assert np.linalg.norm(pose[:3, 3] - [1.5, 0.3, 0.35]) < 1e-4
    assert np.arccos(np.clip(pose[:3, 2] @ sight, -1.0, 1.0)) < 1e-4
    assert np.hypot(*result.q[-1][:2]) > 0.5  # out of the arm's reach: the platform drove


@pytest.mark.parametrize("entry, message", [
    ('type = "LookAtTask"\nframe = "ee"\naxis = [0.0, 0.0, 0.0]', "axis must be a non-zero direction"),
    ('type = "LookAtTask"\nframe = "camera"', "camera"),
    ('type = "AxisAlignTask"\nframe = "ee"\ntarget_axis = [0.0, 1.0]', "target_axis must have shape"),
    ('type = "DampingTask"\ncost = [1.0, 2.0]', "2 costs, but robot 'youbot' has 8"),
    ('type = "DampingTask"\ncost = 1.0\njoints = ["arm_joint_7"]', "'arm_joint_7' is not a joint"),
    ('type = "KineticEnergyRegularization"\ncost = -1.0', "cost must be finite and >= 0"),
    ('type = "LinearTask"\nA = [[0, 0, 0, 1, -1, 0, 0]]', "A has 7 columns, robot 'youbot' has nv = 8"),
    ('type = "LinearTask"\nA = [[0, 0, 0, 1, -1, 0, 0, "x"]]', "A = .*expected"),
])
def test_bad_entries_are_scenario_errors_naming_the_entry(tmp_path, entry, message):
    text = SCENARIO.read_text().replace('type = "KineticEnergyRegularization"\ncost = 1e-4', entry)
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(ScenarioError, match=message):
        load_scenario(path)


def test_a_linear_task_reads_its_matrix_from_the_file(tmp_path):
    entry = ('type = "LinearTask"\nA = [[0, 0, 0, 1, -1, 0, 0, 0], [1, 0, 0, 0, 0, 0, 0, 0]]\n'
             'b = [0.0, 0.1]\ncost = 1e-3')
    path = tmp_path / "linear.toml"
    path.write_text(SCENARIO.read_text().replace('type = "KineticEnergyRegularization"\ncost = 1e-4', entry))
    task = load_scenario(path).tasks[-1]
    assert isinstance(task, wbc.LinearTask)
    np.testing.assert_array_equal(task.matrix, [[0, 0, 0, 1, -1, 0, 0, 0], [1, 0, 0, 0, 0, 0, 0, 0]])
    np.testing.assert_array_equal(task.target, [0.0, 0.1])
