"""The figure of ``wbc run --plot``: what each panel shows, read back from the matplotlib axes."""

from dataclasses import replace

import numpy as np
import pytest

from conftest import TASKS
from wbc.app.closed_loop import run
from wbc.app.plotting import figure, log_floor
from wbc.app.scenario import load_scenario

plt = pytest.importorskip("matplotlib.pyplot")

YOUBOT_ARM = ["arm_joint_1", "arm_joint_2", "arm_joint_3", "arm_joint_4", "arm_joint_5"]
MECANUM_ORDER = ["FL", "FR", "RL", "RR"]  # wbc.model.mobile_base.MecanumWheels
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
    return [line for line in ax.get_lines() if not line.get_label().startswith("limit") and len(line.get_xdata()) > 1]


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
    # the runs' colours are named once, in the figure's legend, not in every panel
    fig = axes["position"].get_figure()
    (legend,) = fig.legends
    assert [text.get_text() for text in legend.get_texts()] == ["youbot_circle", "deluca_parking"]
    colours = [line.get_color() for line in data_lines(axes["position"])]
    assert [handle.get_color() for handle in legend.legend_handles] == colours
    assert axes["position"].get_legend() is None


# ------------------------------------------------------------------------- speeds
def names(ax) -> list[str]:
    """The joint (or run) names of the data lines of a speed panel, without their "(peak ...)"."""
    return [line.get_label().split("  (peak")[0] for line in data_lines(ax)]


def legend_texts(ax) -> list[str]:
    return [text.get_text() for text in ax.get_legend().get_texts()]


def panel_text(ax) -> str:
    return "\n".join(text.get_text() for text in ax.texts)


def test_youbot_speeds_are_split_into_base_wheels_and_chain(circle, panels):
    scenario, result = circle
    axes = panels([circle])
    assert {"base", "wheels", "chain"} <= set(axes) and "other" not in axes
    for name in ("base", "wheels", "chain"):
        ax = axes[name]
        assert ax.get_ylabel() and ax.get_title()
        assert any(line.get_ydata()[0] == 1.0 for line in ax.get_lines()), "the limit is drawn"
        assert ax.get_ylim()[1] > 1.0, "the limit is inside the panel"
    assert axes["chain"].get_title() == "Chain to 'ee': |v| / limit"

    # the base panel shows base-frame speeds, the wheel panel the wheel rates, against their limits
    q, v = result.q[:-1], result.v
    heading = q[:, 2]
    forward = np.cos(heading) * v[:, 0] + np.sin(heading) * v[:, 1]
    (forward_line,) = [line for line in data_lines(axes["base"]) if line.get_label().startswith("v_x forward")]
    np.testing.assert_allclose(forward_line.get_ydata(), np.abs(forward) / YOUBOT_LINEAR_LIMIT, atol=1e-12)
    assert forward_line.get_label() == f"v_x forward  (peak {np.abs(forward).max() / YOUBOT_LINEAR_LIMIT:.2f})"
    assert max(np.max(line.get_ydata()) for line in data_lines(axes["base"])) > 0.1, "the base carries the circle"

    # wheels FL and RR (FR and RL) turn alike on a circle at a fixed heading: each pair is one
    # line, at the larger of the two, named after both
    wheels = np.abs(np.array([scenario.robot.wheel_speeds(qk, vk) for qk, vk in zip(q, v, strict=True)]))
    wheels /= YOUBOT_WHEEL_LIMIT
    lines = dict(zip(names(axes["wheels"]), data_lines(axes["wheels"]), strict=True))
    assert set(lines) == {"FL = RR", "FR = RL"}
    for label, (a, b) in (("FL = RR", (0, 3)), ("FR = RL", (1, 2))):
        assert np.max(np.abs(wheels[:, a] - wheels[:, b])) < 0.01 * 1.15  # COINCIDE of the panel's height
        np.testing.assert_allclose(lines[label].get_ydata(), np.maximum(wheels[:, a], wheels[:, b]), atol=1e-12)
    assert lines["FL = RR"].get_linestyle() != lines["FR = RL"].get_linestyle()


def test_a_panel_whose_joints_barely_move_says_so(circle, panels):
    _, result = circle
    ax = panels([circle])["chain"]
    arm = result.velocity_ratio[:, 3:]
    assert arm.max() < 0.01, "the premise: the arm moves at less than 1 % of its limits"
    assert data_lines(ax) == [], "no invisible lines"
    text = panel_text(ax)
    strongest = YOUBOT_ARM[int(np.argmax(arm.max(axis=0)))]
    assert "barely moves: 5 joints (arm_…)" in text and "below 1% of their speed limits" in text
    assert f"largest: {strongest}, {arm.max():.2%} of its limit" in text


def test_a_small_motion_gets_an_axis_of_its_own(circle, panels):
    scenario, result = circle
    ratio = result.velocity_ratio.copy()
    ratio[:, 3:] *= 0.05 / ratio[:, 3:].max()  # the arm at most at 5 % of its limits
    ax = panels([(scenario, replace(result, velocity_ratio=ratio))])["chain"]
    assert max(np.max(line.get_ydata()) for line in data_lines(ax)) == pytest.approx(0.05)
    assert 0.05 < ax.get_ylim()[1] < 0.1, "the axis ends near the peak, not at the limit"
    assert "limit 1.0: above the axis (below 10% of it throughout)" in legend_texts(ax)
    assert "barely moves" not in panel_text(ax)


def test_coinciding_lines_are_merged_only_when_they_coincide(panels):
    scenario, result = _run("youbot_reach", 3.0)
    ax = panels([(scenario, result)])["wheels"]
    wheels = result.wheel_ratio
    gap = np.max(np.abs(wheels[:, 0] - wheels[:, 3]))
    assert gap > 0.01 * 1.15, "the premise: FL and RR part by more than 1 % of the panel"
    assert sorted(names(ax)) == sorted(MECANUM_ORDER)
    assert len({line.get_linestyle() for line in data_lines(ax)}) == 4, "each its own dash pattern"


def test_fixed_base_has_one_chain_panel(puma, panels):
    axes = panels([puma])
    assert "base" not in axes and "wheels" not in axes and "other" not in axes
    drawn = [name for label in names(axes["chain"]) for name in label.split(" = ")]
    assert sorted(drawn) == [f"joint_{i}" for i in range(1, 7)]
    peaks = [float(line.get_label().split("(peak ")[1][:-1]) for line in data_lines(axes["chain"])]
    assert peaks == sorted(peaks, reverse=True), "closest to its limit first"


def test_several_runs_show_the_largest_ratio_of_each_group(circle, parking, panels):
    axes = panels([circle, parking])
    assert names(axes["base"]) == ["youbot_circle", "deluca_parking"]
    assert names(axes["wheels"]) == ["youbot_circle"]
    (_, result), (_, other) = circle, parking
    # two robots, two tracked frames
    assert axes["chain"].get_title() == "Chain: |v| / limit (largest of each run)"
    np.testing.assert_allclose(data_lines(axes["chain"])[0].get_ydata(), result.velocity_ratio[:, 3:].max(axis=1))
    np.testing.assert_allclose(data_lines(axes["chain"])[1].get_ydata(), other.velocity_ratio[:, 3:].max(axis=1))


# ------------------------------------------------- a robot of many joints (TIAGo-like)
ARM = ["torso_lift_joint"] + [f"arm_{i}_joint" for i in range(1, 8)]
HAND = [f"hand_{finger}_{part}_joint" for finger in ("thumb", "index", "middle", "ring", "little", "extra")
        for part in ("abd", "virtual_1", "flex_1", "virtual_2", "flex_2", "flex_3")]
HEAD, WHEELS = ["head_1_joint", "head_2_joint"], ["wheel_left_joint", "wheel_right_joint"]


def service_robot_urdf() -> str:
    """A fixed-base service robot shaped like PAL's TIAGo: torso lift, 7-joint arm to a
    'gripper' frame, a 36-joint hand on the last arm link, a 2-joint head, two wheels; 48 joints."""
    links, joints = ['<link name="base_link"/>'], []

    def joint(name, kind, parent, child, xyz, axis, lower=-2.5, upper=2.5, velocity=2.0):
        links.append(f'<link name="{child}"/>')
        bounds = f'lower="{lower}" upper="{upper}" ' if kind != "continuous" else ""
        limit = "" if kind == "fixed" else f'<limit {bounds}effort="10" velocity="{velocity}"/>'
        joints.append(f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
                      f'<origin xyz="{xyz}"/><axis xyz="{axis}"/>{limit}</joint>')

    joint("torso_lift_joint", "prismatic", "base_link", "torso", "0 0 0.8", "0 0 1", 0.0, 0.35, 0.07)
    parent = "torso"
    for i, axis in enumerate(("0 0 1", "0 1 0", "1 0 0", "0 1 0", "1 0 0", "0 1 0", "1 0 0"), start=1):
        joint(f"arm_{i}_joint", "revolute", parent, f"arm_{i}", "0.12 0 0" if i > 1 else "0.1 0 0.2", axis)
        parent = f"arm_{i}"
    joint("gripper_joint", "fixed", parent, "gripper", "0.1 0 0", "1 0 0")
    for name in HAND:
        joint(name, "revolute", "arm_7", name.replace("_joint", "_link"), "0.05 0 0", "0 0 1", 0.0, 0.8)
    joint("head_1_joint", "revolute", "torso", "head_1", "0 0 0.3", "0 0 1", -1.2, 1.2, 3.0)
    joint("head_2_joint", "revolute", "head_1", "head_2", "0 0 0.1", "0 1 0", -1.0, 0.8, 3.0)
    for side, y in (("left", 0.2), ("right", -0.2)):
        joint(f"wheel_{side}_joint", "continuous", "base_link", f"wheel_{side}", f"0 {y} 0.1", "0 1 0", velocity=10.0)
    return '<robot name="service">' + "".join(links) + "".join(joints) + "</robot>"


@pytest.fixture(scope="module")
def service(tmp_path_factory):
    """A run of the service robot: its gripper on a vertical circle, a posture task on the rest."""
    import wbc

    folder = tmp_path_factory.mktemp("service")
    (folder / "service.urdf").write_text(service_robot_urdf())
    robot = wbc.load_robot(folder / "service.urdf")
    q0 = robot.neutral()
    for name, value in zip(ARM, (0.15, 0.3, -0.6, 0.4, 1.2, 0.3, 0.8, 0.2), strict=True):
        q0[robot.model.joints[robot.model.getJointId(name)].idx_q] = value
    (folder / "service_circle.toml").write_text(  # (not service.toml: the URDF's sidecar)
        f'[robot]\nname = "service.urdf"\ninitial_configuration = [{", ".join(map(str, q0))}]\n'
        '[controller]\nduration = 1.5\n'
        '[[tasks]]\ntype = "FrameTask"\nframe = "gripper"\nposition_cost = 1.0\norientation_cost = 0.1\n'
        '[[tasks]]\ntype = "PostureTask"\ncost = 1e-3\ngain = 0.05\n'
        '[[constraints]]\ntype = "JointPositionLimits"\n[[constraints]]\ntype = "JointVelocityLimits"\n'
        '[reference]\ntype = "circle"\nradius = 0.1\nperiod = 2.0\nnormal = [1.0, 0.0, 0.0]\n'
        'start_axis = [0.0, 0.0, 1.0]\nramp_time = 0.3\n')
    scenario = load_scenario(folder / "service_circle.toml")
    assert scenario.robot.nv == 48
    return scenario, run(scenario)


def test_joint_roles_of_a_many_joint_robot(service):
    from wbc.app.plotting import joint_roles

    scenario, _ = service
    roles = joint_roles(scenario.robot, "gripper")
    named = {role: sorted(roles.labels[c] for c in getattr(roles, role))
             for role in ("base", "wheels", "chain", "other")}
    assert named == {"base": [], "wheels": sorted(WHEELS), "chain": sorted(ARM), "other": sorted(HAND + HEAD)}
    everything = joint_roles(scenario.robot, None)
    assert everything.chain == []
    assert sorted(everything.labels[c] for c in everything.other) == sorted(ARM + HAND + HEAD)


def test_many_joints_get_readable_panels_named_by_role(service, panels):
    from wbc.app.plotting import MAX_LINES

    scenario, result = service
    axes = panels([service])
    assert {"wheels", "chain", "other"} <= set(axes) and "base" not in axes
    chain = axes["chain"]
    assert chain.get_title() == "Chain to 'gripper': |v| / limit"
    drawn = names(chain)
    named = [name for label in drawn if not label.endswith("others: max") for name in label.split(" = ")]
    assert set(named) <= set(ARM) and 0 < len(drawn) <= MAX_LINES + 1
    assert len(legend_texts(chain)) <= MAX_LINES + 2  # + the others' maximum and the limit
    # the joints drawn are those closest to their limits, the others' maximum is below each of them
    ratio = {name: result.velocity_ratio[:, scenario.robot.joint_names.index(name)] for name in ARM}
    peaks = sorted((ratio[name].max() for name in ARM), reverse=True)
    (others,) = [line for line in data_lines(chain) if line.get_label().startswith("2 others: max")]
    assert np.max(others.get_ydata()) == pytest.approx(peaks[MAX_LINES], rel=1e-12)
    assert min(float(np.max(line.get_ydata())) for line in data_lines(chain) if line is not others) >= peaks[MAX_LINES]
    # hand and head: one panel, which says they do not move (the posture task holds them)
    other = axes["other"]
    assert data_lines(other) == [] and "38 joints (36 hand_…, 2 head_…)" in panel_text(other)
    assert "2 joints (wheel_left_joint, wheel_right_joint)" in panel_text(axes["wheels"])
    for ax in axes.values():
        legend = ax.get_legend()
        if legend is not None:
            assert len(legend.get_texts()) <= MAX_LINES + 2, ax.get_label()


def test_a_fixed_base_tool_path_is_drawn_in_the_plane_it_moves_in(service, panels):
    scenario, result = service
    ax = panels([service])["paths"]
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("y [m]", "z [m]")  # the circle's plane, normal x
    (tool,) = [line for line in ax.get_lines() if line.get_label() == "tool"]
    gripper = np.array([scenario.robot.frame_pose(q, "gripper")[:3, 3] for q in result.q])
    np.testing.assert_allclose(np.column_stack([tool.get_xdata(), tool.get_ydata()]), gripper[:, 1:], atol=1e-12)


# ------------------------------------------------------------------------ latency
def test_latency_spikes_above_the_axis_are_marked_with_their_true_value(circle, panels):
    scenario, result = circle
    tick_time = result.tick_time.copy()
    tick_time[123] = 0.0123456  # 12 346 µs: a spike of the machine
    spiked = replace(result, tick_time=tick_time)
    ax = panels([(scenario, spiked)])["latency"]
    top = ax.get_ylim()[1]
    assert top == pytest.approx(2 * result.statistics.tick_latency_p99 * 1e6) and top < 12345.6
    marks = [line for line in ax.get_lines() if line.get_marker() == "^" and len(line.get_xdata())]
    above = np.flatnonzero(tick_time * 1e6 > top)
    np.testing.assert_allclose(np.concatenate([line.get_xdata() for line in marks if line.get_color() == marks[0]
                                               .get_color()]), result.time[above])
    assert all(np.all(line.get_ydata() == top) and not line.get_clip_on() for line in marks), "on the top edge"
    (note,) = [text for text in legend_texts(ax) if text.startswith("above the axis")]
    assert note == f"above the axis: largest 12,346 µs (tick, t = {result.time[123]:.2f} s)"


def test_latency_without_spikes_has_no_mark(circle, panels):
    scenario, result = circle
    calm = replace(result, tick_time=np.full_like(result.tick_time, 4e-6), solve_time=np.full_like(result.time, 1e-6),
                   statistics=replace(result.statistics, tick_latency_p99=4e-6))
    ax = panels([(scenario, calm)])["latency"]
    assert not [line for line in ax.get_lines() if line.get_marker() == "^"]
    assert not any(text.startswith("above the axis") for text in legend_texts(ax))


def test_the_latency_of_a_long_record_shows_every_row_peak_and_the_exact_median(circle, panels):
    scenario, _ = circle
    kept = run(scenario, duration=0.5, max_rows=7)  # rows of 8 ticks
    ax = panels([(scenario, kept)])["latency"]
    assert ax.get_yscale() == "log"
    (peaks,) = [line for line in ax.get_lines() if line.get_label() == "largest tick time of each 8"]
    np.testing.assert_allclose(peaks.get_ydata(), kept.tick_time * 1e6)
    low, high = ax.get_ylim()
    assert low < kept.statistics.tick_latency_median * 1e6 and high > kept.tick_time.max() * 1e6, "nothing clipped"
    (median,) = [line for line in ax.get_lines() if str(line.get_label()).startswith("median")]
    assert median.get_ydata()[0] == pytest.approx(kept.statistics.tick_latency_median * 1e6)


# ------------------------------------------------------------------------ the title
def test_title_names_the_loop_and_what_a_long_run_kept(circle, panels):
    scenario, result = circle
    fig = figure([(scenario, result)])
    assert fig.get_suptitle() == "youbot_circle — daqp, dt = 10 ms, kinematic loop"
    plt.close(fig)
    kept = run(scenario, duration=0.5, max_rows=7)
    fig = figure([(scenario, kept), (scenario, replace(result, loop="mujoco", loop_details="velocity servos"))])
    title = fig.get_suptitle()
    plt.close(fig)
    assert "kinematic loop / MuJoCo loop (velocity servos)" in title
    assert ("youbot_circle: every 8th of 50 ticks drawn, each point the largest value of its 8 ticks; "
            "the summary's numbers are over every tick") in title


def test_a_long_record_is_drawn_coarsened_and_says_so(circle, panels, monkeypatch):
    import wbc.app.plotting

    scenario, result = circle  # 400 ticks
    monkeypatch.setattr(wbc.app.plotting, "PLOT_ROWS", 100)
    axes = panels([circle])
    (line,) = data_lines(axes["position"])
    np.testing.assert_allclose(line.get_ydata(), result.position_error.reshape(100, 4).max(axis=1) * 1e3)
    assert ("youbot_circle: every 4th of 400 ticks drawn, each point the largest value of its 4 ticks"
            in axes["position"].get_figure().get_suptitle())


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
    from wbc.app.plotting import plot_runs

    runs = [_run(path.stem, 0.2) for path in sorted(TASKS.glob("*.toml"))]
    path = plot_runs(runs, tmp_path / "all.png")
    assert path.stat().st_size > 10_000
