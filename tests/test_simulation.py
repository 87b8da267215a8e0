"""MuJoCo in the loop: velocity servos, measurement noise and a one-tick delay."""

from dataclasses import replace

import numpy as np
import pytest

import wbc
from conftest import TASKS
from wbc.app.closed_loop import run
from wbc.app.scenario import load_scenario
from wbc.app.simulation import MujocoSimulation


def test_circle_is_tracked_through_the_servos_with_noise_and_delay():
    scenario = load_scenario(TASKS / "youbot_circle.toml")
    simulation = MujocoSimulation(scenario.robot, scenario.dt, noise=1e-4, delay=1, seed=7)
    result = run(scenario, duration=3.0, simulation=simulation)
    assert np.all(np.isfinite(result.v))
    assert result.position_error.max() < 1e-3  # documented bound: 1 mm
    assert result.orientation_error.max() < 2e-3
    assert result.velocity_violation.max() <= 1e-9  # commands respect the limits
    # the true state really moved: the simulated base followed the circle sideways
    assert np.ptp(result.q[:, 1]) > 0.1


def test_simulated_servos_follow_the_command():
    robot = wbc.load_robot("youbot")
    simulation = MujocoSimulation(robot, 0.01)
    q0 = np.array([0, 0, 0, 0, 0.5, 1.0, 1.2, 0.0])
    simulation.reset(q0)
    v = np.array([0.2, -0.1, 0.3, 0.2, -0.2, 0.2, -0.2, 0.3])
    for _ in range(50):
        simulation.apply(v)
        simulation.advance()
    np.testing.assert_allclose(simulation.data.qvel, v, atol=5e-3)
    np.testing.assert_allclose(simulation.q, q0 + 0.5 * v, atol=1e-2)


def test_simulation_input_checks():
    robot = wbc.load_robot("youbot")
    with pytest.raises(wbc.ModelError):
        MujocoSimulation(robot, 0.003)  # not a multiple of the 2 ms timestep
    with pytest.raises(wbc.ModelError):
        MujocoSimulation(wbc.load_robot("deluca_mm"), 0.01)  # no MJCF shipped
    with pytest.raises(ValueError):
        MujocoSimulation(robot, 0.01, delay=2)


def test_reach_converges_through_the_servos():
    scenario = load_scenario(TASKS / "youbot_reach.toml")
    simulation = MujocoSimulation(scenario.robot, scenario.dt, noise=1e-4, delay=1, seed=3)
    result = run(scenario, simulation=simulation)
    assert result.position_error[-1] < 1e-3  # documented bound: 1 mm
    assert result.orientation_error[-1] < 2e-3
    assert result.velocity_violation.max() <= 1e-9
    # servo lag may overshoot a position limit: with one tick of delay a joint runs on for at
    # most one tick at its recent speed (the damper stops it by the next), so a joint j outside
    # its range at tick t is out by at most dt max |v_j| over the three commands before t
    # (measured: 0.84 of that bound; 0.93 without the error-scaled damping, on a slower approach)
    robot = scenario.robot
    outside = np.maximum(robot.lower - result.q, result.q - robot.upper)  # youbot: q and v coordinates agree
    for t, j in zip(*np.nonzero(outside > 0), strict=True):
        assert outside[t, j] <= scenario.dt * np.abs(result.v[max(t - 3, 0):t, j]).max(), (t, j)
    assert result.position_violation.max() < 1e-2


def test_a_reference_task_without_a_reference_records_its_true_error_in_mujoco():
    """A scenario whose reference task holds a fixed target (no reference motion): the MuJoCo
    loop records the error of the true state to that target, as the kinematic loop records
    the task's (it failed calling the missing reference)."""
    scenario = load_scenario(TASKS / "youbot_reach.toml")
    goal = scenario.reference(0.0)[0]
    scenario.reference_task.set_target(goal)
    scenario = replace(scenario, reference=None)
    result = run(scenario, duration=0.3, simulation=MujocoSimulation(scenario.robot, scenario.dt))
    tool = np.array([scenario.robot.frame_pose(q, "ee")[:3, 3] for q in result.q[:-1]])
    np.testing.assert_allclose(result.position_error, np.linalg.norm(goal[:3, 3] - tool, axis=1), rtol=1e-12)
    assert result.position_error[-1] < result.position_error[0] - 0.05  # and the loop drives towards it


def test_contacts_are_off_whatever_the_mjcf_says(tmp_path, monkeypatch):
    """The loop checks the controller: an MJCF whose geoms all collide (the youBot's with
    contype/conaffinity 1 and a ball in the world overlapping its arm) produces no contact."""
    import mujoco

    from wbc.model.robot import model_path

    text = model_path("youbot", "mjcf").read_text()
    text = text.replace('contype="0" conaffinity="0"', 'contype="1" conaffinity="1"')
    ball = '<geom name="ball" type="sphere" pos="0.15 0 0.2" size="0.1"/>'
    text = text.replace('<geom name="floor"', ball + '<geom name="floor"')
    colliding = tmp_path / "youbot.xml"
    colliding.write_text(text)
    model = mujoco.MjModel.from_xml_path(str(colliding))
    data = mujoco.MjData(model)
    mujoco.mj_step(model, data, nstep=5)
    assert data.ncon > 0  # the MJCF as written has contacts
    monkeypatch.setattr("wbc.app.simulation.model_path", lambda name, kind: colliding)
    simulation = MujocoSimulation(wbc.load_robot("youbot"), 0.01)
    simulation.reset(np.zeros(8))
    simulation.advance()
    assert simulation.data.ncon == 0


def test_youbot_obstacle_keeps_its_margin_through_the_servos():
    """Collision avoidance in the MuJoCo loop: the true configuration of every tick (coal on the
    URDF's shapes as the oracle) keeps min_distance up to the servos' tracking lag."""
    from test_collision_scenario import _closest_per_tick

    scenario = load_scenario(TASKS / "youbot_obstacle.toml")
    avoidance = scenario.constraints[-1]
    simulation = MujocoSimulation(scenario.robot, scenario.dt)
    result = run(scenario, simulation=simulation)
    closest = _closest_per_tick(scenario, avoidance.obstacles, result.q)
    assert closest.min() >= avoidance.min_distance - 2e-3
    assert result.fallback_ticks == 0
