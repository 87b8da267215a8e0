"""Base kinds: mecanum wheel kinematics and limits, nonholonomic rows, input map, the De Luca
mobile manipulator (its J(q) from the document), steering, reduced vs equality form."""

import numpy as np
import pytest

import wbc
from conftest import TASKS, random_youbot_configurations
from wbc.app.closed_loop import lateral_slip, run, wheel_ratio
from wbc.app.scenario import load_scenario

R, L, W = 0.0475, 0.235, 0.15  # youBot wheels, from issue 2 (independent of the model files)
D0, L2, L3 = 0.6, 0.432, 0.432  # De Luca model dimensions, from issue 3


def mecanum_wheel_speeds(vx, vy, omega):
    """Textbook inverse kinematics of four 45-degree mecanum wheels, order FL, FR, RL, RR."""
    k = L + W
    return np.array([vx - vy - k * omega, vx + vy + k * omega, vx + vy - k * omega, vx - vy + k * omega]) / R


# ----------------------------------------------------------------------------- mecanum
def test_mecanum_forward_after_inverse_is_identity(youbot):
    wheels = youbot.base.wheels
    np.testing.assert_allclose(wheels.forward_matrix() @ wheels.inverse_matrix(), np.eye(3), atol=1e-14)


def test_wheel_speeds_rotate_world_rates_into_the_base_frame(youbot, rng):
    for q in random_youbot_configurations(rng, 200):
        v = rng.uniform(-1, 1, 8)
        c, s = np.cos(q[2]), np.sin(q[2])
        vx, vy = c * v[0] + s * v[1], -s * v[0] + c * v[1]
        np.testing.assert_allclose(youbot.wheel_speeds(q, v), mecanum_wheel_speeds(vx, vy, v[2]), atol=1e-12)


def test_wheel_speed_patterns(youbot):
    q = np.zeros(8)
    forward = youbot.wheel_speeds(q, [0.5, 0, 0, 0, 0, 0, 0, 0])
    np.testing.assert_allclose(forward, 0.5 / R)
    turn = youbot.wheel_speeds(q, [0, 0, 1.0, 0, 0, 0, 0, 0])  # counter-clockwise: right side forward
    assert turn[0] < 0 and turn[2] < 0 and turn[1] > 0 and turn[3] > 0
    heading_north = youbot.wheel_speeds([0, 0, np.pi / 2, 0, 0, 0, 0, 0], [0, 0.5, 0, 0, 0, 0, 0, 0])
    np.testing.assert_allclose(heading_north, 0.5 / R, atol=1e-12)  # world +y is the base's forward


def test_mecanum_limits_bound_every_wheel_when_driven_hard(youbot):
    task = wbc.BaseVelocityTask(1.0)
    controller = wbc.Controller(youbot, [task], [wbc.JointVelocityLimits(), wbc.MecanumWheelLimits()])
    u_max = youbot.base.wheels.max_speed
    rng = np.random.default_rng(3)
    hit = 0
    for _ in range(200):
        q = np.r_[rng.uniform(-1, 1, 2), rng.uniform(-np.pi, np.pi), 0, 0.5, 1.0, 1.2, 0]
        task.set_target(rng.uniform(-3, 3, 3))  # far beyond what the wheels allow
        u = youbot.wheel_speeds(q, controller.step(q))
        assert np.all(np.abs(u) <= u_max * (1 + 1e-9))
        hit += np.any(np.abs(u) > u_max * (1 - 1e-6))
    assert hit > 150, "the wheel limit, not the box limit, is what binds for most commands"


def test_youbot_reach_never_exceeds_wheel_limits_and_uses_them():
    scenario = load_scenario(TASKS / "youbot_reach.toml")
    result = run(scenario)
    ratio = wheel_ratio(scenario.robot, result.q[:-1], result.v)
    assert ratio.max() <= 1.0 + 1e-9
    assert ratio.max() > 1.0 - 1e-6  # the base is driven at its wheel limit
    assert result.position_error[-1] < 1e-4
    assert "worst_wheel_speed_ratio" in result.summary()


# ----------------------------------------------------------------------------- De Luca
@pytest.fixture(scope="module")
def deluca():
    return wbc.load_robot("deluca_mm")


def deluca_closed_form_jacobian(q):
    """The 3x5 J(q) of the document, p_dot = J(q) (v, omega, th1dot, th2dot, th3dot)."""
    _, _, th, t1, t2, t3 = q
    reach = L2 * np.cos(t2) + L3 * np.cos(t2 + t3)
    rise = L2 * np.sin(t2) + L3 * np.sin(t2 + t3)
    return np.array([
        [np.cos(th), 0, -reach * np.sin(t1), -rise * np.cos(t1), -L3 * np.sin(t2 + t3) * np.cos(t1)],
        [np.sin(th), 0, reach * np.cos(t1), -rise * np.sin(t1), -L3 * np.sin(t2 + t3) * np.sin(t1)],
        [0, 0, 0, reach, L3 * np.cos(t2 + t3)],
    ])


def random_deluca_configurations(robot, rng, count):
    return np.array([robot.random_configuration(rng, base_range=5.0) for _ in range(count)])


def test_deluca_coordinates_and_kind(deluca):
    assert deluca.joint_names == ["base_x", "base_y", "steering", "theta1", "theta2", "theta3"]
    assert deluca.base.kind is wbc.BaseKind.SYNCHRO and deluca.base.is_nonholonomic
    assert deluca.nq == deluca.nv == 6 and deluca.nu == 5


def test_deluca_wrist_centre_matches_the_document(deluca, rng):
    for q in random_deluca_configurations(deluca, rng, 300):
        x, y, _, t1, t2, t3 = q
        reach = L2 * np.cos(t2) + L3 * np.cos(t2 + t3)
        expected = [x + reach * np.cos(t1), y + reach * np.sin(t1), D0 + L2 * np.sin(t2) + L3 * np.sin(t2 + t3)]
        np.testing.assert_allclose(deluca.frame_pose(q, "wrist_center")[:3, 3], expected, atol=1e-12)


def test_deluca_jacobian_over_inputs_is_the_documents(deluca, rng):
    for q in random_deluca_configurations(deluca, rng, 300):
        J_u = deluca.frame_jacobian(q, "wrist_center")[:3] @ deluca.input_map(q)
        np.testing.assert_allclose(J_u, deluca_closed_form_jacobian(q), atol=1e-12)
        assert np.all(J_u[:, 1] == 0.0), "steering has no effect on the wrist centre"


def test_input_map_spans_exactly_the_no_slip_motions(deluca, youbot, rng):
    np.testing.assert_array_equal(youbot.input_map(youbot.neutral()), np.eye(8))
    for q in random_deluca_configurations(deluca, rng, 50):
        S = deluca.input_map(q)
        np.testing.assert_allclose(S.T @ S, np.eye(5), atol=1e-15)
        no_slip = np.array([-np.sin(q[2]), np.cos(q[2]), 0, 0, 0, 0])
        np.testing.assert_allclose(no_slip @ S, 0.0, atol=1e-15)


@pytest.fixture(scope="module")
def parking_run():
    scenario = load_scenario(TASKS / "deluca_parking.toml")
    return scenario, run(scenario)


def test_parking_reaches_the_target_without_lateral_slip(parking_run):
    scenario, result = parking_run
    assert result.lateral_slip.max() <= 1e-9
    target = scenario.reference(0.0)[0]
    assert np.linalg.norm(scenario.robot.frame_pose(result.q[-1], "wrist_center")[:3, 3] - target) < 1e-4
    heading = result.q[:, 2]
    assert np.ptp(heading) > 0.5, "the wheels had to turn toward the sideways target"
    assert np.all(result.velocity_ratio <= 1 + 1e-9)


def test_without_steering_the_greedy_qp_never_turns(parking_run):
    scenario = load_scenario(TASKS / "deluca_parking.toml")
    scenario.tasks = [t for t in scenario.tasks if not isinstance(t, wbc.SteeringTask)]
    result = run(scenario)
    assert np.ptp(result.q[:, 2]) < 1e-6
    assert result.position_error[-1] > 1.0


def test_reduced_and_equality_forms_agree_on_recorded_ticks(parking_run):
    scenario, result = parking_run
    target = scenario.reference(0.0)
    equality = scenario.make_controller()
    reduced = wbc.Controller(scenario.robot, scenario.tasks, scenario.constraints, dt=scenario.dt,
                             damping=scenario.damping, reduced=True)
    assert reduced.qp.n == 5 and reduced.qp.n_eq == 0
    scenario.reference_task.set_target(*target)
    for q in result.q[::25]:
        v_eq = equality.step(q)
        v_red = reduced.step(q)
        np.testing.assert_allclose(v_red, v_eq, rtol=0, atol=1e-8)
        np.testing.assert_allclose(reduced.last.u, equality.last.u, rtol=0, atol=1e-8)
        np.testing.assert_allclose(scenario.robot.input_map(q) @ reduced.last.u, v_red, atol=1e-15)


# ----------------------------------------------------------------------------- unicycle
UNICYCLE_URDF = """<robot name="diffdrive_arm">
  <link name="world"/><link name="bx"/><link name="by"/><link name="chassis"/><link name="l1"/>
  <link name="l2"/><link name="tool"/>
  <joint name="base_x" type="prismatic"><parent link="world"/><child link="bx"/><axis xyz="1 0 0"/>
    <limit lower="-1000" upper="1000" effort="1" velocity="1"/></joint>
  <joint name="base_y" type="prismatic"><parent link="bx"/><child link="by"/><axis xyz="0 1 0"/>
    <limit lower="-1000" upper="1000" effort="1" velocity="1"/></joint>
  <joint name="base_yaw" type="revolute"><parent link="by"/><child link="chassis"/><axis xyz="0 0 1"/>
    <limit lower="-1000" upper="1000" effort="1" velocity="1"/></joint>
  <joint name="shoulder" type="revolute"><parent link="chassis"/><child link="l1"/>
    <origin xyz="0.1 0 0.4"/><axis xyz="0 -1 0"/><limit lower="-1.5" upper="1.5" effort="1" velocity="1.5"/></joint>
  <joint name="elbow" type="revolute"><parent link="l1"/><child link="l2"/>
    <origin xyz="0.3 0 0"/><axis xyz="0 -1 0"/><limit lower="-2.5" upper="2.5" effort="1" velocity="1.5"/></joint>
  <joint name="tool_joint" type="fixed"><parent link="l2"/><child link="tool"/><origin xyz="0.3 0 0"/></joint>
</robot>"""

UNICYCLE_TOML = """name = "diffdrive_arm"
urdf = "diffdrive_arm.urdf"
[base]
kind = "unicycle"
joints = ["base_x", "base_y", "base_yaw"]
max_linear_speed = 0.6
max_yaw_rate = 1.2
[base.wheels]
radius = 0.1
half_track = 0.25
max_speed = 5.0
"""


@pytest.fixture(scope="module")
def unicycle(tmp_path_factory):
    folder = tmp_path_factory.mktemp("unicycle")
    (folder / "diffdrive_arm.urdf").write_text(UNICYCLE_URDF)
    (folder / "diffdrive_arm.toml").write_text(UNICYCLE_TOML)
    return wbc.load_robot(folder / "diffdrive_arm.urdf")


def test_unicycle_base_reaches_a_sideways_point(unicycle):
    """A differential drive carrying its arm ahead of the axle steers by itself: the heading
    rate swings the tool sideways, so the plain QP (no SteeringTask) finds the way."""
    assert unicycle.base.kind is wbc.BaseKind.UNICYCLE and unicycle.nu == 4
    reach = wbc.PositionTask("tool", cost=1.0, gain=0.1, max_speed=0.4)
    reach.set_target([0.0, 2.0, 0.6])
    tasks = [reach, wbc.PostureTask(1e-4, target=[0, 0, 0, 0.3, 0.6])]
    constraints = [wbc.NonholonomicBase(), wbc.JointPositionLimits(), wbc.JointVelocityLimits(),
                   wbc.WheelSpeedLimits()]
    controller = wbc.Controller(unicycle, tasks, constraints)
    reduced = wbc.Controller(unicycle, tasks, constraints, reduced=True)
    q = np.array([0, 0, 0, 0.3, 0.6])
    qs, vs = [], []
    for k in range(2000):
        v = controller.step(q)
        if k % 100 == 0:
            np.testing.assert_allclose(reduced.step(q), v, rtol=0, atol=1e-8)
        qs.append(q)
        vs.append(v)
        q = unicycle.integrate(q, v, controller.dt)
    qs, vs = np.array(qs), np.array(vs)
    assert lateral_slip(unicycle, qs, vs).max() <= 1e-9
    assert wheel_ratio(unicycle, qs, vs).max() <= 1 + 1e-9
    assert np.ptp(qs[:, 2]) > 0.5, "the chassis turned toward the target"
    assert np.linalg.norm(unicycle.frame_pose(q, "tool")[:3, 3] - [0.0, 2.0, 0.6]) < 1e-3


def test_differential_wheel_speeds(unicycle):
    u = unicycle.wheel_speeds([0, 0, 0.3, 0, 0], [0.5 * np.cos(0.3), 0.5 * np.sin(0.3), 1.0, 0, 0])
    np.testing.assert_allclose(u, [(0.5 - 0.25) / 0.1, (0.5 + 0.25) / 0.1], atol=1e-12)


# ----------------------------------------------------------------------------- misuse
def test_base_specific_pieces_refuse_the_wrong_base(youbot, deluca):
    with pytest.raises(wbc.InvalidInputError):
        wbc.Controller(youbot, [wbc.PostureTask(1.0)], [wbc.NonholonomicBase()])
    with pytest.raises(wbc.InvalidInputError):
        wbc.Controller(youbot, [wbc.SteeringTask()])
    with pytest.raises(wbc.InvalidInputError):
        wbc.Controller(deluca, [wbc.PostureTask(1.0)], [wbc.NonholonomicBase(), wbc.MecanumWheelLimits()])
    with pytest.raises(wbc.InvalidInputError, match="NonholonomicBase"):
        wbc.Controller(deluca, [wbc.PostureTask(1.0)])
    with pytest.raises(wbc.InvalidInputError):
        deluca.wheel_speeds(deluca.neutral(), np.zeros(6))
