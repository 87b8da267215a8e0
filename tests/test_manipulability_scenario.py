"""Regression: tasks/youbot_stretch*.toml, the gripper driven into Kapustina's singular set
theta2 = theta3 = 0, without and with the manipulability barrier; the line reference; the
side-by-side CLI plot; the docs figure."""

import importlib.util
import json

import numpy as np
import pinocchio as pin
import pytest

from conftest import ROOT, TASKS, tomllib
from wbc.app.cli import main
from wbc.app.closed_loop import run, velocity_ratio
from wbc.app.plotting import manipulability_traces
from wbc.app.references import Line
from wbc.app.scenario import load_scenario
from wbc.model.manipulability import manipulability

GUARDED, UNGUARDED = TASKS / "youbot_stretch.toml", TASKS / "youbot_stretch_no_barrier.toml"
M_MIN = 0.04
RANK_TOL = 1e-3  # singular values below this count as zero (sigma_1 is about 1.9 here)


@pytest.fixture(scope="module")
def runs():
    return {path.stem: (scenario, run(scenario)) for path in (UNGUARDED, GUARDED)
            for scenario in [load_scenario(path)]}


def distance_to_singular_set(q: np.ndarray) -> np.ndarray:
    """Kapustina's set theta2 = theta3 = 0: Euclidean distance in (theta2, theta3) [rad]."""
    return np.hypot(q[:, 4], q[:, 5])


def ranks(robot, qs):
    return np.array([np.linalg.matrix_rank(robot.frame_jacobian(q, "ee"), tol=RANK_TOL) for q in qs])


def test_files_differ_only_by_the_barrier():
    def spec(path):
        with open(path, "rb") as stream:
            data = tomllib.load(stream)
        data.pop("name"), data.pop("description")
        data["constraints"] = [c for c in data["constraints"] if c["type"] != "ManipulabilityBarrier"]
        return data

    assert spec(GUARDED) == spec(UNGUARDED)
    barriers = [c for c in load_scenario(GUARDED).constraints if type(c).__name__ == "ManipulabilityBarrier"]
    assert len(barriers) == 1 and barriers[0].min_value == M_MIN


def test_target_rises_straight_up_into_the_stretched_pose():
    scenario = load_scenario(GUARDED)
    start, _ = scenario.reference(0.0)
    start = start.copy()
    end, twist_at_end = scenario.reference(100.0)
    stretched = scenario.robot.frame_pose([0, 0, 0, 0, 0, 0, 0.5, 0], "ee")
    np.testing.assert_allclose(end, stretched, atol=1e-12)
    np.testing.assert_allclose(end[:2, 3], start[:2, 3], atol=1e-5)  # vertical line
    np.testing.assert_allclose(end[:3, :3], start[:3, :3], atol=1e-9)  # same orientation
    assert end[2, 3] - start[2, 3] == pytest.approx(0.29 * (1 - np.cos(0.9)), rel=1e-4)  # (a2 + a3)(1 - cos 0.9)
    np.testing.assert_array_equal(twist_at_end, 0.0)
    assert np.linalg.matrix_rank(scenario.robot.frame_jacobian([0, 0, 0, 0, 0, 0, 0.5, 0], "ee"), tol=1e-9) == 5


def test_without_the_barrier_the_arm_enters_the_singular_set(runs):
    scenario, result = runs["youbot_stretch_no_barrier"]
    robot = scenario.robot
    distance = distance_to_singular_set(result.q)
    assert distance[0] > 0.8 and distance[-1] < 0.02
    assert ranks(robot, result.q[-50:]).max() == 5, "the Jacobian is numerically rank 5 at the end"
    assert manipulability(robot, result.q[-1], "ee") < 0.05 * M_MIN
    ratio = velocity_ratio(robot, result.q[:-1], result.v)
    assert ratio.max() > 1 - 1e-6, "an arm joint saturates its speed limit on the way in"
    assert result.position_error[-1] < 1e-4  # it does reach the (singular) target


def test_with_the_barrier_m_distance_rank_and_rates_stay_bounded(runs):
    scenario, result = runs["youbot_stretch"]
    robot = scenario.robot
    m = np.array([manipulability(robot, q, "ee") for q in result.q])  # every tick: the QP never failed
    assert m.min() >= M_MIN * (1 - 1e-9)
    assert m[-1] < 1.01 * M_MIN, "the barrier is what stops the arm"
    assert distance_to_singular_set(result.q).min() > 0.15
    assert ranks(robot, result.q).min() == 6
    assert velocity_ratio(robot, result.q[:-1], result.v).max() < 0.7
    assert result.position_error.max() < 5e-3 and result.orientation_error.max() < 1e-3
    assert result.position_violation.max() == 0.0


def test_line_reference_twist_is_the_derivative_of_its_pose():
    start = pin.SE3(pin.rpy.rpyToMatrix(0.1, -0.3, 0.5), np.array([0.2, -0.1, 0.4])).homogeneous
    end = pin.SE3(pin.rpy.rpyToMatrix(0.4, 0.2, -0.2), np.array([0.5, 0.3, 0.1])).homogeneous
    line = Line(start, end, speed=0.2, ramp_time=0.4)
    h = 1e-6
    for t in (0.1, 0.3, 0.9, 2.0):
        plus, _ = line(t + h)
        plus = plus.copy()
        minus, _ = line(t - h)
        minus = minus.copy()
        _, twist = line(t)
        np.testing.assert_allclose(twist[:3], (plus[:3, 3] - minus[:3, 3]) / (2 * h), atol=1e-7)
        np.testing.assert_allclose(twist[3:], pin.log3(plus[:3, :3] @ minus[:3, :3].T) / (2 * h), atol=1e-7)
    distance, speed = line.distance(1.0)
    assert speed == pytest.approx(0.2) and distance == pytest.approx(0.2 * (1.0 - 0.2))
    final, twist = line(10.0)
    np.testing.assert_allclose(final, end, atol=1e-12)
    np.testing.assert_array_equal(twist, 0.0)
    with pytest.raises(ValueError):
        Line(start, start, speed=0.1)


def test_cli_runs_both_files_side_by_side(tmp_path, capsys):
    plot = tmp_path / "stretch.png"
    assert main(["run", str(UNGUARDED), str(GUARDED), "--duration", "3.0", "--no-progress", "--json",
                 "--plot", str(plot)]) == 0
    captured = capsys.readouterr()
    summaries = json.loads(captured.out)  # stdout holds the JSON alone
    assert "plot written" in captured.err
    assert [s["scenario"] for s in summaries] == ["youbot_stretch_no_barrier", "youbot_stretch"]
    assert summaries[1]["position_error_max_m"] > summaries[0]["final_position_error_m"]
    # the point of the scenario, in both summaries: the barrier holds m >= m_min, without it m drops below
    unguarded, guarded = summaries
    assert guarded["manipulability_floor"] == M_MIN and "manipulability_floor" not in unguarded
    assert guarded["manipulability_min"] >= M_MIN * (1 - 1e-9) > unguarded["manipulability_min"]
    assert plot.stat().st_size > 10_000


def test_cli_prints_the_minimum_manipulability(capsys):
    assert main(["run", str(GUARDED), "--duration", "3.0", "--no-progress"]) == 0
    line = next(line for line in capsys.readouterr().out.splitlines() if "manipulability" in line)
    assert float(line.split()[2]) == pytest.approx(M_MIN, rel=1e-3) and "m_min 0.04" in line


def test_manipulability_trace_uses_the_barrier_of_either_run(runs):
    trace = manipulability_traces(list(runs.values()))
    assert (trace.frame, trace.rows, trace.min_value) == ("ee", "all", M_MIN)
    assert trace.guarded == [False, True]
    unguarded, guarded = trace.series
    assert unguarded.min() < M_MIN <= guarded.min() + 1e-12
    assert manipulability_traces([runs["youbot_stretch_no_barrier"]]) is None


def test_summary_minimum_is_the_product_of_the_singular_values(runs):
    trace = manipulability_traces(list(runs.values()))
    for k, (scenario, result) in enumerate(runs.values()):
        m = [np.prod(np.linalg.svd(scenario.robot.frame_jacobian(q, "ee"), compute_uv=False)) for q in result.q]
        assert trace.summary(k)["manipulability_min"] == pytest.approx(min(m), rel=1e-9)


def test_docs_figure_is_small(runs, tmp_path):
    spec = importlib.util.spec_from_file_location("manipulability_figure", ROOT / "docs" / "manipulability_figure.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    path = module.figure(list(runs.values()), tmp_path / "figure.png")
    assert 10_000 < path.stat().st_size < 150_000
