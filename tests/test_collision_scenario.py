"""tasks/youbot_obstacle.toml and CollisionAvoidance in scenario files: the run keeps the margin
(coal on the URDF's raw shapes as the oracle, every tick), obstacle tables are checked."""

import numpy as np
import pytest

import wbc
from conftest import TASKS
from test_collision_avoidance import MIN_DISTANCE, TOLERANCE, _excluded
from test_collision_distances import Oracle
from wbc.app import closed_loop
from wbc.app.scenario import load_scenario

SCENARIO = TASKS / "youbot_obstacle.toml"


def _closest_per_tick(scenario, obstacles, qs):
    oracle, excluded = Oracle(scenario.robot, obstacles), _excluded(scenario.robot)
    return np.array([min(d for key, d in oracle.distances(q).items() if key not in excluded) for q in qs])


def test_youbot_obstacle_goes_around_the_ball():
    scenario = load_scenario(SCENARIO)
    avoidance = scenario.constraints[-1]
    assert isinstance(avoidance, wbc.CollisionAvoidance)
    assert [type(o).__name__ for o in avoidance.obstacles] == ["Sphere", "Box", "Plane"]
    assert avoidance.obstacles[0].name == "ball" and avoidance.obstacles[0].radius == 0.05
    result = closed_loop.run(scenario)
    closest = _closest_per_tick(scenario, avoidance.obstacles, result.q)
    assert closest.min() >= MIN_DISTANCE - TOLERANCE
    assert result.fallback_ticks == 0
    end = scenario.robot.frame_pose(result.q[-1], "ee")[:3, 3]
    np.testing.assert_allclose(end, (0.9, 0.0, 0.1), atol=0.01)  # the goal behind the ball


def test_without_the_constraint_the_gripper_goes_through_the_ball():
    scenario = load_scenario(SCENARIO)
    obstacles = scenario.constraints.pop().obstacles
    result = closed_loop.run(scenario)
    assert _closest_per_tick(scenario, obstacles, result.q).min() < 0.0


@pytest.mark.parametrize(("obstacle", "message"), [
    ('{ type = "Cube", center = [0, 0, 0] }', "type 'Cube' unknown"),
    ('{ type = "Sphere", center = [0.7, 0, 0.1] }', "required key 'radius' missing"),
    ('{ type = "Sphere", center = [0.7, 0, 0.1], radius = 0.05, colour = 1 }', "unknown key 'colour'"),
    ('{ type = "Sphere", center = [nan, 0, 0.1], radius = 0.05 }', "Sphere center"),
    ('{ type = "Box", center = [0.7, 0, 0.1], size = [0.1, -0.1, 0.1] }', "Box size"),
    ('{ type = "Plane", normal = [0, 0, 0], offset = 0.0 }', "Plane normal"),
    ('"ball"', "expected a table"),
])
def test_bad_obstacle_tables_name_the_entry(tmp_path, obstacle, message):
    text = SCENARIO.read_text()
    start = text.index("obstacles = [")
    end = text.index("]\n\n[reference]")
    path = tmp_path / "bad.toml"
    path.write_text(text[:start] + f"obstacles = [{obstacle}" + text[end:])
    with pytest.raises(wbc.ScenarioError, match=r"\[\[constraints\]\] #5 \(CollisionAvoidance\).*obstacles\[0\]"):
        load_scenario(path)
    with pytest.raises(wbc.ScenarioError, match=message):
        load_scenario(path)


def test_bad_collision_settings_are_scenario_errors(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text(SCENARIO.read_text().replace("min_distance = 0.02 ", "min_distance = 0.5 "))
    with pytest.raises(wbc.ScenarioError, match="below detection_distance"):
        load_scenario(path)


def test_the_run_reports_and_plots_the_smallest_distance_against_the_margin(tmp_path):
    """collision_traces measures each recorded configuration of the runs with and without the
    constraint (coal on the raw shapes as the oracle); wbc run's summary and figure show it."""
    from wbc.app.cli import format_summary
    from wbc.app.plotting import figure

    guarded, free = load_scenario(SCENARIO), load_scenario(SCENARIO)
    obstacles = free.constraints.pop().obstacles
    runs = [(s, closed_loop.run(s, duration=3.0)) for s in (guarded, free)]
    trace = closed_loop.collision_traces(runs)
    assert trace is not None and trace.margin == MIN_DISTANCE and trace.detection_distance == 0.3
    for (scenario, result), series in zip(runs, trace.series, strict=True):
        closest = _closest_per_tick(scenario, obstacles, result.q)
        np.testing.assert_allclose(series, np.where(closest < 0.3, closest, np.inf), atol=1e-6)
    with_it, without = trace.summary(0), trace.summary(1)
    assert with_it["collision_distance_min_m"] >= MIN_DISTANCE - TOLERANCE
    assert without["collision_distance_min_m"] < 0.0  # through the ball
    text = format_summary("youbot_obstacle", "daqp", runs[0][1].summary() | with_it | {"loop": "kinematic"})
    smallest = with_it["collision_distance_min_m"] * 1e3
    assert f"collision distance min     {smallest:.2f} mm  (min_distance 20 mm)" in text
    axes = {ax.get_label(): ax for ax in figure(runs).axes}
    floor = [line for line in axes["distance"].lines if line.get_linestyle() == "--"]
    assert len(floor) == 1 and floor[0].get_ydata()[0] == pytest.approx(20.0)


def test_youbot_obstacle_with_acceleration_limits_brakes_in_time():
    """The dampers alone asked for decelerations the hard acceleration box forbids (104 of 600
    ticks from the fallback, -2.8 mm; with the collision rows braking, the footprint's rows still
    6 ticks); their braking bounds cap the approach speeds where the box can still stop them. Both
    detection distances (0.3, 0.5 m) are shorter than the platform's stop from its top speed (0.64
    m): the build warns, and this path, slower near the obstacles, still brakes in time."""
    scenario = load_scenario(SCENARIO)
    obstacles = scenario.constraints[-1].obstacles
    scenario.constraints.append(wbc.AccelerationLimits())
    with pytest.warns(wbc.ConfigurationWarning, match="need 0.64 m to stop"):
        result = closed_loop.run(scenario)
    assert _closest_per_tick(scenario, obstacles, result.q).min() >= MIN_DISTANCE - TOLERANCE
    assert result.fallback_ticks <= 2  # measured: 0 (daqp)
    step = np.abs(np.diff(np.vstack([np.zeros(scenario.robot.nv), result.v]), axis=0))
    assert np.all(step[:, 3:] <= np.pi * scenario.dt + 1e-6)  # the arm's sidecar limit: pi rad/s^2
    end = scenario.robot.frame_pose(result.q[-1], "ee")[:3, 3]
    np.testing.assert_allclose(end, (0.9, 0.0, 0.1), atol=0.01)
