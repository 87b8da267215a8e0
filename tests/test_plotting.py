"""The figure of ``wbc run --plot``: what each panel shows, read back from the matplotlib axes."""

import numpy as np
import pytest

from conftest import TASKS
from wbc.closed_loop import run
from wbc.plotting import figure, log_floor
from wbc.scenario import load_scenario

plt = pytest.importorskip("matplotlib.pyplot")

YOUBOT_ARM = ["arm_joint_1", "arm_joint_2", "arm_joint_3", "arm_joint_4", "arm_joint_5"]
MECANUM_ORDER = ["FL", "FR", "RL", "RR"]  # wbc.base.MecanumWheels
YOUBOT_LINEAR_LIMIT, YOUBOT_WHEEL_LIMIT = 0.8, 16.842105263157894  # models/youbot/youbot.toml [m/s], [rad/s]


def _run(name: str, duration: float):
    scenario = load_scenario(TASKS / f"{name}.toml")
    return scenario, run(scenario, duration=duration)


@pytest.fixture(scope="module")
def circle():
    return _run("youbot_circle", 4.0)


@pytest.fixture(scope="module")
def parking():
    return _run("deluca_parking", 2.0)


@pytest.fixture(scope="module")
def puma():
    return _run("puma_wrist_pass", 2.0)


@pytest.fixture
def panels():
    """``panels(runs)``: the figure's axes by panel name; every figure is closed afterwards."""
    figures = []

    def make(runs):
        figures.append(figure(runs))
        return {ax.get_label(): ax for ax in figures[-1].axes}

    yield make
    for fig in figures:
        plt.close(fig)


def data_lines(ax):
    """Lines of ``ax`` that hold data (not the limit line, not legend proxies)."""
    return [line for line in ax.get_lines() if line.get_label() != "limit" and len(line.get_xdata()) > 1]


# ------------------------------------------------------------------ tracking error
def test_log_floor_is_three_decades_below_the_median_or_the_smallest_value():
    assert log_floor([np.array([0.0, 1e-12, 1.0, 1.0, 2.0])]) == pytest.approx(1e-3)
    assert log_floor([np.array([0.0, 0.012, 0.02]), np.array([0.015])]) == pytest.approx(1e-2)
    assert log_floor([np.zeros(5)]) is None
    assert log_floor([]) is None


def test_position_and_orientation_errors_have_their_own_labelled_axes(circle, panels):
    scenario, result = circle
    axes = panels([circle])
    for name, unit, error in (("position", "[mm]", result.position_error), ("orientation", "[mrad]",
                                                                              result.orientation_error)):
        ax = axes[name]
        assert unit in ax.get_ylabel() and ax.get_xlabel() == "time [s]"
        assert ax.get_yscale() == "log"
        (line,) = data_lines(ax)
        plotted = np.asarray(line.get_ydata())
        scaled = error * 1e3
        bottom, top = ax.get_ylim()
        positive = scaled[scaled > 0]
        # the axis starts near the data: at most four decades below the median, never six
        assert np.median(positive) * 1e-4 <= bottom <= np.percentile(positive, 5)
        assert top >= scaled.max()
        # above the floor the line is the error in mm / mrad; below it, on the floor
        above = scaled >= bottom
        np.testing.assert_allclose(plotted[above], scaled[above])
        np.testing.assert_allclose(plotted[~above], bottom)
    # the first tick has no error yet: an exact 0 does not drag the axis to 1e-9
    assert result.position_error[0] == 0.0 and axes["position"].get_ylim()[0] >= 1e-4


def test_position_only_scenario_draws_no_orientation(parking, panels):
    _, result = parking
    assert not result.orientation_tracked
    assert "orientation" not in panels([parking])
    summary = result.summary()
    assert not any(key.startswith(("orientation", "final_orientation")) for key in summary)
    assert "position_error_max_m" in summary


def test_frame_task_without_orientation_cost_draws_no_orientation(tmp_path, panels):
    text = (TASKS / "youbot_circle.toml").read_text().replace("orientation_cost = 0.5", "orientation_cost = 0.0")
    path = tmp_path / "circle_position_only.toml"
    path.write_text(text)
    scenario = load_scenario(path)
    result = run(scenario, duration=0.3)
    assert not result.orientation_tracked
    assert "orientation" not in panels([(scenario, result)])


def test_scenario_without_reference_says_so(tmp_path, panels):
    path = tmp_path / "posture_only.toml"
    path.write_text('[robot]\nname = "youbot"\ninitial_configuration = [0, 0, 0, 0, 0.5, 1.0, 1.2, 0]\n'
                    '[[tasks]]\ntype = "PostureTask"\ncost = 1.0\ngain = 0.1\n'
                    '[[constraints]]\ntype = "JointVelocityLimits"\n')
    scenario = load_scenario(path)
    assert scenario.reference_task is None
    axes = panels([(scenario, run(scenario, duration=0.2))])
    assert data_lines(axes["position"]) == []
    assert [t.get_text() for t in axes["position"].texts] == ["no tracking error recorded"]


def test_overlay_draws_orientation_only_for_runs_that_track_it(circle, parking, panels):
    axes = panels([circle, parking])
    assert [line.get_label() for line in data_lines(axes["orientation"])] == ["youbot_circle"]
    assert [line.get_label() for line in data_lines(axes["position"])] == ["youbot_circle", "deluca_parking"]


# ------------------------------------------------------------------------- speeds
def test_youbot_speeds_are_split_into_base_wheels_and_arm(circle, panels):
    scenario, result = circle
    axes = panels([circle])
    assert {"base", "wheels", "arm"} <= set(axes)
    for name in ("base", "wheels", "arm"):
        ax = axes[name]
        assert ax.get_ylabel() and ax.get_title()
        assert len(data_lines(ax)) <= 5, "a panel of at most five lines"
        assert any(line.get_label() == "limit" for line in ax.get_lines())
        assert ax.get_ylim()[1] > 1.0, "the limit is inside the panel"
    assert [line.get_label() for line in data_lines(axes["arm"])] == YOUBOT_ARM
    assert [line.get_label() for line in data_lines(axes["wheels"])] == MECANUM_ORDER

    # the base panel shows base-frame speeds, the wheel panel the wheel rates, against their limits
    q, v = result.q[:-1], result.v
    heading = q[:, 2]
    forward = np.cos(heading) * v[:, 0] + np.sin(heading) * v[:, 1]
    base_lines = data_lines(axes["base"])
    np.testing.assert_allclose(base_lines[0].get_ydata(), np.abs(forward) / YOUBOT_LINEAR_LIMIT, atol=1e-12)
    wheels = np.array([scenario.robot.wheel_speeds(qk, vk) for qk, vk in zip(q, v, strict=True)])
    for k, line in enumerate(data_lines(axes["wheels"])):
        np.testing.assert_allclose(line.get_ydata(), np.abs(wheels[:, k]) / YOUBOT_WHEEL_LIMIT, atol=1e-12)
    assert max(np.max(line.get_ydata()) for line in base_lines) > 0.1, "the base carries the circle"


def test_fixed_base_has_one_joint_panel(puma, panels):
    axes = panels([puma])
    assert "base" not in axes and "wheels" not in axes
    assert [line.get_label() for line in data_lines(axes["arm"])] == [f"joint_{i}" for i in range(1, 7)]


def test_several_runs_show_the_largest_ratio_of_each_group(circle, parking, panels):
    axes = panels([circle, parking])
    assert [line.get_label() for line in data_lines(axes["base"])] == ["youbot_circle: max", "deluca_parking: max"]
    assert [line.get_label() for line in data_lines(axes["wheels"])] == ["youbot_circle: max"]
    (_, result), (_, other) = circle, parking
    np.testing.assert_allclose(data_lines(axes["arm"])[0].get_ydata(), result.velocity_ratio[:, 3:].max(axis=1))
    np.testing.assert_allclose(data_lines(axes["arm"])[1].get_ydata(), other.velocity_ratio[:, 3:].max(axis=1))


# -------------------------------------------------------------------------- paths
def marker_points(ax, marker: str) -> np.ndarray:
    """(x, y) of every single-point line drawn with ``marker``."""
    return np.array([(line.get_xdata()[0], line.get_ydata()[0]) for line in ax.get_lines()
                     if line.get_marker() == marker and len(line.get_xdata()) == 1])


def test_paths_mark_start_and_end(circle, panels):
    scenario, result = circle
    ax = panels([circle])["paths"]
    robot, q0, q_end = scenario.robot, scenario.q0, result.q[-1]
    starts = [q0[:2], robot.frame_pose(q0, "ee")[:2, 3]]
    ends = [q_end[:2], robot.frame_pose(q_end, "ee")[:2, 3]]
    np.testing.assert_allclose(marker_points(ax, "o"), starts, atol=1e-12)
    np.testing.assert_allclose(marker_points(ax, "s"), ends, atol=1e-12)
    assert {"start", "end", "base", "tool"} <= set(ax.get_legend_handles_labels()[1])
    assert np.linalg.norm(ends[0] - starts[0]) > 0.05, "start and end are apart: the markers say something"


def test_every_panel_has_axis_labels(circle, panels):
    for name, ax in panels([circle]).items():
        assert ax.get_xlabel() and ax.get_ylabel(), name


def test_figure_needs_a_run():
    with pytest.raises(ValueError, match="at least one"):
        figure([])


def test_shipped_scenarios_all_plot(tmp_path):
    from wbc.plotting import plot_runs

    runs = [_run(path.stem, 0.2) for path in sorted(TASKS.glob("*.toml"))]
    path = plot_runs(runs, tmp_path / "all.png")
    assert path.stat().st_size > 10_000
