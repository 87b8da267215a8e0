"""AccelerationLimits (issue 24 §6-§8): the change of every joint's speed, of the platform's
base-frame velocity and of each wheel speed per tick, checked on closed-loop runs against the
limits read here from the model's sidecar and the formulas written out here; the braking bound
toward position limits against a simulated braking sequence."""

from __future__ import annotations

import copy
import dataclasses
import pickle

import numpy as np
import pytest

import wbc
from test_mobile_bases import UNICYCLE_TOML, UNICYCLE_URDF
from wbc.app.closed_loop import run
from wbc.app.scenario import load_scenario
from wbc.constraints.acceleration_limits import braking_speed
from wbc.core.schema import read_toml
from wbc.model.robot import model_path

TABLE = read_toml(model_path("youbot", "toml"), wbc.ModelError)["acceleration"]  # the sidecar's text
TOLERANCE = 1e-7  # [unit/s] solver tolerance on a bound


def youbot_limits(robot: wbc.Robot) -> tuple[np.ndarray, float]:
    """Per velocity coordinate (x, y: base frame) and the wheels', from the sidecar text."""
    a = np.array([TABLE["base_linear"], TABLE["base_linear"], TABLE["base_yaw"]]
                 + [TABLE["joints"][name] for name in robot.joint_names[3:]])
    return a, TABLE["wheels"]


def base_frame(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """(v_x, v_y) of the platform in its own frame, heading q[2]."""
    c, s = np.cos(q[2]), np.sin(q[2])
    return np.array([c * v[0] + s * v[1], -s * v[0] + c * v[1]])


def worst_excess(robot: wbc.Robot, qs: np.ndarray, vs: np.ndarray, dt: float, a: np.ndarray,
                 wheel_a: float | None) -> float:
    """Largest ``|w_k - w_{k-1}| - a dt`` over the ticks (from rest), for every joint but the base
    x, y, the base-frame (v_x, v_y) and the wheel speeds; <= 0 when every bound held."""
    worst, previous_v, previous_q = -np.inf, np.zeros(robot.nv), qs[0]
    for q, v in zip(qs, vs, strict=False):
        worst = max(worst, np.max(np.abs(v[2:] - previous_v[2:]) - a[2:] * dt))
        change = base_frame(q, v) - base_frame(previous_q, previous_v)
        worst = max(worst, np.max(np.abs(change) - a[:2] * dt))
        if wheel_a is not None:
            wheel_change = robot.wheel_speeds(q, v) - robot.wheel_speeds(previous_q, previous_v)
            worst = max(worst, np.max(np.abs(wheel_change)) - wheel_a * dt)
        previous_v, previous_q = v, q
    return worst


def overshoot(robot: wbc.Robot, qs: np.ndarray) -> float:
    """Largest distance of any joint beyond its position limits over the run."""
    return float(np.max(np.maximum(qs - robot.upper, robot.lower - qs)))


# ------------------------------------------------------------------ the scenario (§8)
@pytest.fixture(scope="module")
def reach_accel():
    return load_scenario("youbot_reach_accel")


@pytest.mark.parametrize("solver", ["daqp", "quadprog", "clarabel"])
def test_youbot_reach_accel_ramps_every_speed_and_converges(reach_accel, solver):
    scenario = reach_accel
    robot = scenario.robot
    result = run(scenario, solver=solver)
    a, wheel_a = youbot_limits(robot)
    qs, vs = result.q[:-1], result.v
    assert result.fallback_ticks == 0
    assert worst_excess(robot, qs, vs, scenario.dt, a, wheel_a) <= TOLERANCE
    assert overshoot(robot, result.q) <= 1e-12  # rounding of q + v dt
    assert result.statistics.final_position_error < 1e-3  # [m]
    assert result.statistics.final_orientation_error < 1e-2  # [rad]
    # the wheels ramp: the first tick's wheel speeds are one tick of acceleration, and the run reaches the limit
    first = np.abs(robot.wheel_speeds(qs[0], vs[0]))
    assert first.max() <= wheel_a * scenario.dt + TOLERANCE
    assert result.wheel_ratio.max() > 0.99


def test_the_limits_add_no_oscillation(reach_accel):
    """Sign changes of each joint's acceleration (steps above 1e-6, from rest) with the limits stay
    within 1.5x of the same scenario without them; with youbot_reach's gain (0.2, far above
    a_max dt / v_max) the limited loop overshoots back and forth: more than 3x."""
    def sign_changes(vs: np.ndarray) -> int:
        steps = np.diff(np.vstack([np.zeros(vs.shape[1]), vs]), axis=0)
        total = 0
        for column in steps.T:
            signs = np.sign(column[np.abs(column) > 1e-6])
            total += int(np.count_nonzero(signs[1:] != signs[:-1]))
        return total

    counts = {}
    for gain in (0.0125, 0.2):
        for limited in (False, True):
            scenario = load_scenario("youbot_reach_accel")
            scenario.tasks[0].gain = gain
            constraints = scenario.constraints if limited else scenario.constraints[:-1]
            assert isinstance(scenario.constraints[-1], wbc.AccelerationLimits)
            counts[gain, limited] = sign_changes(run(dataclasses.replace(scenario, constraints=constraints)).v)
    assert counts[0.0125, True] <= 1.5 * counts[0.0125, False]
    assert counts[0.2, True] > 3 * counts[0.2, False]  # the check can fail


def test_without_the_limits_the_wheels_jump(reach_accel):
    """The scenario without AccelerationLimits: the first tick already asks > 50 % of the wheel
    limit, a jump of more than 30 ticks of acceleration (what the constraint removes)."""
    scenario = load_scenario("youbot_reach")
    robot = scenario.robot
    result = run(scenario, duration=0.05)
    _, wheel_a = youbot_limits(robot)
    first = np.abs(robot.wheel_speeds(result.q[0], result.v[0]))
    assert first.max() > 0.5 * robot.base.wheels.max_speed > 30 * wheel_a * scenario.dt


# ------------------------------------------------------------------ hierarchy, reduced form, measured
def reach_tasks(robot: wbc.Robot, offset=(1.2, -0.6, 0.0)) -> tuple[wbc.FrameTask, wbc.PostureTask]:
    ee = wbc.FrameTask("ee", position_cost=1.0, orientation_cost=0.2, gain=0.3)
    q0 = np.array([0.0, 0.0, 0.0, 0.0, 0.5, 1.0, 1.2, 0.0])
    pose = robot.frame_pose(q0, "ee").copy()
    pose[:3, 3] += offset
    ee.set_target(pose)
    return ee, wbc.PostureTask(1e-3, target=q0, gain=0.1)


def closed_loop(controller: wbc.Controller, q: np.ndarray, ticks: int, measured=None):
    robot, qs, vs = controller.robot, [], []
    for _ in range(ticks):
        v = controller.step(q) if measured is None else controller.step(q, measured(vs))
        assert controller.last.success, controller.last.status
        qs.append(q)
        vs.append(v.copy())
        q = robot.integrate(q, v, controller.dt)
    return np.array(qs + [q]), np.array(vs)


@pytest.mark.parametrize("solver", ["daqp", "quadprog"])
def test_a_two_level_hierarchy_keeps_the_bounds(youbot, solver):
    ee, posture = reach_tasks(youbot)
    constraints = [wbc.JointPositionLimits(), wbc.JointVelocityLimits(), wbc.MecanumWheelLimits(),
                   wbc.AccelerationLimits()]
    controller = wbc.Controller(youbot, [[ee], [posture]], constraints, solver=solver)
    qs, vs = closed_loop(controller, np.array([0.0, 0.0, 0.0, 0.0, 0.5, 1.0, 1.2, 0.0]), 1300)
    a, wheel_a = youbot_limits(youbot)
    assert worst_excess(youbot, qs[:-1], vs, controller.dt, a, wheel_a) <= 1e-6  # through two solves
    assert overshoot(youbot, qs) <= 1e-12
    assert np.linalg.norm(youbot.frame_pose(qs[-1], "ee")[:3, 3] - ee.target[:3, 3]) < 1e-3


@pytest.fixture(scope="module")
def unicycle(tmp_path_factory):
    folder = tmp_path_factory.mktemp("unicycle_accel")
    (folder / "diffdrive_arm.urdf").write_text(UNICYCLE_URDF)
    (folder / "diffdrive_arm.toml").write_text(UNICYCLE_TOML)
    return wbc.load_robot(folder / "diffdrive_arm.urdf")


@pytest.mark.parametrize("solver", ["daqp", "quadprog"])
def test_the_reduced_nonholonomic_form_ramps_the_wheels(unicycle, solver):
    """A differential drive in the reduced form (QP over its real inputs): the same bounds, and the
    reduced and equality forms give the same commands."""
    a = np.array([0.5, 0.5, 1.5, 2.0, 2.0])  # [m/s^2, m/s^2, rad/s^2, rad/s^2, rad/s^2]
    wheel_a = 6.0  # [rad/s^2]
    reach = wbc.PositionTask("tool", cost=1.0, gain=0.1, max_speed=0.4)
    reach.set_target([0.0, 2.0, 0.6])
    tasks = [reach, wbc.PostureTask(1e-4, target=[0, 0, 0, 0.3, 0.6])]
    constraints = [wbc.NonholonomicBase(), wbc.JointPositionLimits(), wbc.JointVelocityLimits(),
                   wbc.WheelSpeedLimits(), wbc.AccelerationLimits(a, max_wheel_acceleration=wheel_a)]
    reduced = wbc.Controller(unicycle, tasks, constraints, reduced=True, solver=solver)
    full = wbc.Controller(unicycle, tasks, constraints, solver="daqp")
    q0 = np.array([0.0, 0.0, 0.0, 0.3, 0.6])
    qs, vs = closed_loop(reduced, q0, 1500)
    assert worst_excess(unicycle, qs[:-1], vs, reduced.dt, a, wheel_a) <= TOLERANCE
    assert overshoot(unicycle, qs) <= 1e-12
    assert np.linalg.norm(unicycle.frame_pose(qs[-1], "tool")[:3, 3] - [0.0, 2.0, 0.6]) < 1e-3
    wheels = np.array([unicycle.wheel_speeds(q, v) for q, v in zip(qs, vs, strict=False)])
    assert np.abs(wheels[0]).max() <= wheel_a * reduced.dt + TOLERANCE  # from rest
    assert np.abs(wheels).max() > 0.5 * unicycle.base.wheels.max_speed  # ... ramped up over many ticks
    _, full_vs = closed_loop(full, q0, 200)
    np.testing.assert_allclose(vs[:200], full_vs, rtol=0, atol=1e-6)


def test_the_bounds_follow_the_measured_velocity(youbot, rng):
    """With ``v_measured`` the box is around the measurement (inside the speed limits), not the
    previous command."""
    ee, posture = reach_tasks(youbot)
    a, _ = youbot_limits(youbot)
    controller = wbc.Controller(youbot, [ee, posture], [wbc.JointVelocityLimits(), wbc.AccelerationLimits()])
    q = np.array([0.0, 0.0, 0.0, 0.0, 0.5, 1.0, 1.2, 0.0])
    for _ in range(50):
        measured = rng.uniform(-0.5, 0.5, youbot.nv)
        measured[:3] *= 0.4  # a platform velocity inside the wheel speed limits
        v = controller.step(q, v_measured=measured)
        assert controller.last.success
        assert np.all(np.abs(v[2:] - measured[2:]) <= a[2:] * controller.dt + TOLERANCE)
        change = base_frame(q, v) - base_frame(q, measured)
        assert np.all(np.abs(change) <= a[:2] * controller.dt + TOLERANCE)
        q = youbot.integrate(q, v, controller.dt)


def test_a_measured_velocity_beyond_the_limits_brakes_without_infeasibility(youbot, rng):
    """A measurement beyond the speed and wheel limits (a push, an encoder glitch): the reference
    is taken into the limits first (the base twist scaled as a whole), so the QP stays feasible
    and the command keeps every speed limit."""
    ee, posture = reach_tasks(youbot)
    constraints = [wbc.JointVelocityLimits(), wbc.MecanumWheelLimits(), wbc.AccelerationLimits()]
    controller = wbc.Controller(youbot, [ee, posture], constraints)
    q = np.array([0.0, 0.0, 0.4, 0.0, 0.5, 1.0, 1.2, 0.0])
    for _ in range(30):
        measured = 3.0 * youbot.velocity_limit * rng.choice([-1.0, 1.0], youbot.nv)
        v = controller.step(q, v_measured=measured)
        assert controller.last.success, controller.last.status
        assert np.all(np.abs(v[2:]) <= youbot.velocity_limit[2:] + TOLERANCE)
        assert np.abs(youbot.wheel_speeds(q, v)).max() <= youbot.base.wheels.max_speed + TOLERANCE


def test_jerk_bounds_the_change_of_acceleration(youbot):
    """A posture move far from the position limits: ``|v_k - 2 v_{k-1} + v_{k-2}| <= j dt^2`` on
    every joint coordinate (from rest), and the move still converges."""
    jerk = 20.0
    q0 = np.array([0.0, 0.0, 0.0, 0.0, 0.5, 1.0, 1.2, 0.0])
    target = q0 + [0.0, 0.0, 0.0, 0.4, -0.3, 0.3, -0.3, 0.5]  # the arm (a posture of the arm)
    posture = wbc.PostureTask(1.0, target=target, gain=0.01)  # <= 0.5 rad/s: speed limits never bind
    controller = wbc.Controller(youbot, [posture], [wbc.JointVelocityLimits(), wbc.AccelerationLimits(max_jerk=jerk)])
    qs, vs = closed_loop(controller, q0, 1500)
    history = np.vstack([np.zeros((2, youbot.nv)), vs])
    second = history[2:] - 2 * history[1:-1] + history[:-2]
    assert np.abs(second[:, 2:]).max() <= jerk * controller.dt**2 + TOLERANCE
    assert np.abs(second[:, 2:]).max() >= 0.5 * jerk * controller.dt**2  # the bound acted
    np.testing.assert_allclose(qs[-1][3:], target[3:], atol=1e-3)


@pytest.mark.parametrize("duplicate", [copy.deepcopy, lambda c: pickle.loads(pickle.dumps(c))],
                         ids=["deepcopy", "pickle"])
def test_a_copy_continues_exactly(youbot, duplicate):
    """A copy of a running controller carries the previous command, the heading it was computed
    at and the channels' history: with and without jerk limits, on a turned base with wheel
    limits (the base-frame and wheel rows depend on the heading), it commands bit for bit what
    the original does -- and so its first step changes the base-frame speed by at most
    ``a_max dt`` (a copy that took the heading as 0 changed it by 8x that, marked optimal)."""
    a_max = 1.0  # [m/s^2] the youBot sidecar's base_linear
    for jerk in (None, 20.0):
        q0 = np.array([0.0, 0.0, 1.2, 0.0, 0.5, 1.0, 1.2, 0.0])  # base yaw 1.2 rad
        ee = wbc.FrameTask("ee", position_cost=1.0, orientation_cost=0.5, gain=0.5)
        pose = youbot.frame_pose(q0, "ee")
        pose[:3, 3] += [2.0, -1.5, 0.0]  # far: the base drives and turns
        ee.set_target(pose)
        controller = wbc.Controller(youbot, [ee, wbc.PostureTask(1e-3, gain=0.05)],
                                    [wbc.JointPositionLimits(), wbc.JointVelocityLimits(), wbc.MecanumWheelLimits(),
                                     wbc.AccelerationLimits(max_jerk=jerk)])
        qs, vs = closed_loop(controller, q0, 40)
        q = youbot.integrate(qs[-1], vs[-1], controller.dt)
        twin = duplicate(controller)
        for tick in range(3):
            v = controller.step(q)
            np.testing.assert_array_equal(twin.step(q), v)
            assert twin.last.success
            if tick == 0:  # world (x, y) -> base frame at each command's own heading
                def forward_left(w: np.ndarray, yaw: float) -> np.ndarray:
                    return np.array([np.cos(yaw) * w[0] + np.sin(yaw) * w[1], -np.sin(yaw) * w[0] + np.cos(yaw) * w[1]])
                change = forward_left(v, q[2]) - forward_left(vs[-1], qs[-1][2])
                assert np.abs(change).max() <= a_max * controller.dt + TOLERANCE
            q = youbot.integrate(q, v, controller.dt)


# ------------------------------------------------------------------ viability (§7)
@pytest.mark.parametrize("distance", [0.0, 1e-6, 3e-4, 0.01, 0.37, 2.0])
@pytest.mark.parametrize("a_max", [0.5, 3.0, 40.0])
def test_the_braking_speed_is_the_largest_that_stops_in_time(distance, a_max):
    """Against the braking sequence v, v - a dt, ... simulated here: from the returned speed the
    joint stops within ``distance``; from 1e-6 more it does not."""
    dt = 0.01

    def travelled(v: float) -> float:
        total = 0.0
        while v > 0.0:
            total += v * dt
            v -= a_max * dt
        return total

    v = braking_speed(np.array([distance]), np.array([a_max]), dt, np.empty(1))[0]
    assert travelled(v) <= distance + 1e-12
    assert travelled(v + 1e-6) > distance
    assert v == pytest.approx(np.sqrt(2 * a_max * distance), abs=a_max * dt)  # ~ sqrt(2 a d)


def test_the_braking_speed_beyond_a_limit_and_without_one():
    """Beyond the limit (d < 0) the speed that lands on it in one tick, d / dt; no limit on that
    side (d = inf, a one-sided position range): no bound (was an OverflowError of math.floor)."""
    out = braking_speed(np.array([-0.02, np.inf]), np.array([3.0, 3.0]), 0.01, np.empty(2))
    assert out[0] == pytest.approx(-2.0) and out[1] == np.inf


@pytest.mark.parametrize("solver", ["daqp", "osqp"])
@pytest.mark.parametrize("gain", [None, 0.5])
def test_a_joint_driven_at_its_limit_brakes_in_time_and_never_overshoots(youbot, solver, gain):
    """A posture target beyond arm_joint_2's upper limit, with and without the position damper:
    the joint stops on (or short of) the limit, the acceleration bounds hold on every tick, and
    no QP is infeasible."""
    q0 = np.array([0.0, 0.0, 0.0, 0.0, -0.8, 1.0, 1.2, 0.0])
    target = q0.copy()
    target[4] = youbot.upper[4] + 1.0
    posture = wbc.PostureTask(1.0, target=target, gain=1.0)
    constraints = [wbc.JointVelocityLimits(), wbc.AccelerationLimits()]
    if gain is not None:
        constraints.append(wbc.JointPositionLimits(gain=gain))
    controller = wbc.Controller(youbot, [posture], constraints, solver=solver)
    qs, vs = closed_loop(controller, q0, 400)
    a, _ = youbot_limits(youbot)
    assert overshoot(youbot, qs) <= 1e-9  # a solver's tolerance on the last, braking tick
    assert youbot.upper[4] - qs[-1][4] < 1e-3  # it got there
    assert worst_excess(youbot, qs[:-1], vs, controller.dt, a, None) <= 1e-6
    assert np.abs(vs[:, 4]).max() > 1.5  # at top speed before braking


def test_a_rate_limit_without_the_braking_bound_overshoots(youbot):
    """What the viability bound prevents: the same run with a plain box |v - v_prev| <= a dt (the
    acceleration limit without it, soft beside the position damper) overshoots the limit."""
    from test_tick_context import RateLimit  # a box around the previous command, nothing more

    q0 = np.array([0.0, 0.0, 0.0, 0.0, -0.8, 1.0, 1.2, 0.0])
    target = q0.copy()
    target[4] = youbot.upper[4] + 1.0
    controller = wbc.Controller(youbot, [wbc.PostureTask(1.0, target=target, gain=1.0)],
                                [wbc.JointVelocityLimits(), RateLimit(), wbc.JointPositionLimits(gain=0.5)])
    qs, _ = closed_loop(controller, q0, 400)
    assert overshoot(youbot, qs) > 1e-3


def test_starts_from_rest(youbot):
    ee, posture = reach_tasks(youbot)
    a, _ = youbot_limits(youbot)
    controller = wbc.Controller(youbot, [ee, posture], [wbc.AccelerationLimits()])
    v = controller.step(np.array([0.0, 0.0, 0.0, 0.0, 0.5, 1.0, 1.2, 0.0]))
    assert np.all(np.abs(v[2:]) <= a[2:] * controller.dt + TOLERANCE)
    assert np.all(np.abs(v[:2]) <= a[0] * controller.dt + TOLERANCE)
    assert np.abs(v).max() > 0.5 * a.min() * controller.dt  # and moves


# ------------------------------------------------------------------ misuse
@pytest.mark.parametrize(("arguments", "message"), [
    ({"max_acceleration": -1.0}, "max_acceleration must be > 0"),
    ({"max_acceleration": 0.0}, "max_acceleration must be > 0"),
    ({"max_acceleration": float("nan")}, "max_acceleration must be > 0"),
    ({"max_acceleration": [1.0, np.nan]}, "max_acceleration must be > 0"),
    ({"max_acceleration": "fast"}, "max_acceleration must be a number"),
    ({"max_acceleration": [[1.0]]}, "scalar or a vector"),
    ({"max_jerk": -2.0}, "max_jerk must be > 0"),
    ({"max_wheel_acceleration": [1.0, 2.0]}, "one number"),
    ({"max_wheel_acceleration": np.nan}, "max_wheel_acceleration must be > 0"),
])
def test_bad_limits_are_refused_by_name(arguments, message):
    with pytest.raises(wbc.InvalidInputError, match=message):
        wbc.AccelerationLimits(**arguments)


def test_a_wrong_size_is_refused_naming_the_coordinates(youbot):
    with pytest.raises(wbc.InvalidInputError, match="3 entries.*8 velocity coordinates.*arm_joint_1"):
        wbc.Controller(youbot, [wbc.PostureTask(1.0)], [wbc.AccelerationLimits([1.0, 2.0, 3.0])])
    with pytest.raises(wbc.InvalidInputError, match="max_jerk has 2 entries"):
        wbc.Controller(youbot, [wbc.PostureTask(1.0)], [wbc.AccelerationLimits(max_jerk=[1.0, 2.0])])


def test_a_model_without_declared_limits_asks_for_them():
    puma = wbc.load_robot("puma560")
    with pytest.raises(wbc.InvalidInputError, match="declares no acceleration limits.*max_acceleration="):
        wbc.Controller(puma, [wbc.PostureTask(1.0)], [wbc.AccelerationLimits()])
    wbc.Controller(puma, [wbc.PostureTask(1.0)], [wbc.AccelerationLimits(2.0)])  # given: fine
