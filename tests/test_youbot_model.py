"""The shipped youBot against Kapustina (2019): limits eq. (1), forward kinematics eq. (2),
her Jacobian entries j_13..j_37, finite differences, and URDF vs MJCF."""

import numpy as np
import pinocchio as pin
import pytest

import wbc
from conftest import random_youbot_configurations

# Dimensions from wbc issue 2 (public youBot data), written here independently of the model files.
H, A1, D1, A2, A3, C = 0.1662, 0.033, 0.147, 0.155, 0.135, 0.2176
DEG = np.pi / 180.0


def rot_z(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def rot_x(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def kapustina_eq2(q, sign=+1):
    """Eq. (2): position of E and Euler angles (psi, theta_E, phi); R = Rz(psi) Rx(theta_E) Rz(phi)."""
    x, y, th, t1, t2, t3, t4, t5 = q
    reach = A1 + A2 * np.sin(t2) + A3 * np.sin(t2 + t3) + C * np.sin(t2 + t3 + t4)
    position = np.array([
        x + H * np.cos(th) + np.cos(th + t1) * reach,
        y + H * np.sin(th) + np.sin(th + t1) * reach,
        D1 + A2 * np.cos(t2) + A3 * np.cos(t2 + t3) + C * np.cos(t2 + t3 + t4),
    ])
    psi, theta_e, phi = th + t1 + sign * np.pi / 2, sign * (t2 + t3 + t4), t5 + sign * np.pi / 2
    return position, rot_z(psi) @ rot_x(theta_e) @ rot_z(phi)


def kapustina_position_jacobian(q):
    """Rows 1-3 of her J = dX/dQ (entries j_13 ... j_37 of the paper)."""
    _, _, th, t1, t2, t3, t4, _ = q
    s234, c234 = np.sin(t2 + t3 + t4), np.cos(t2 + t3 + t4)
    ell = A1 + A2 * np.sin(t2) + A3 * np.sin(t2 + t3) + C * s234
    k5 = A2 * np.cos(t2) + A3 * np.cos(t2 + t3) + C * c234
    k6 = A3 * np.cos(t2 + t3) + C * c234
    k7 = C * c234
    c, s = np.cos(th + t1), np.sin(th + t1)
    J = np.zeros((3, 8))
    J[0] = [1, 0, -H * np.sin(th) - s * ell, -s * ell, c * k5, c * k6, c * k7, 0]
    J[1] = [0, 1, H * np.cos(th) + c * ell, c * ell, s * k5, s * k6, s * k7, 0]
    J[2] = [0, 0, 0, 0, -A2 * np.sin(t2) - A3 * np.sin(t2 + t3) - C * s234,
            -A3 * np.sin(t2 + t3) - C * s234, -C * s234, 0]
    return J


def test_coordinates_and_limits_are_kapustinas(youbot):
    assert youbot.nq == youbot.nv == 8
    assert youbot.joint_names == ["base_x", "base_y", "base_yaw"] + [f"arm_joint_{i}" for i in range(1, 6)]
    expected_lower = np.array([-169, -65, -151, -102.5, -167.5]) * DEG
    expected_upper = np.array([169, 90, 146, 102.5, 167.5]) * DEG
    np.testing.assert_allclose(youbot.lower[3:], expected_lower, rtol=0, atol=1e-12)
    np.testing.assert_allclose(youbot.upper[3:], expected_upper, rtol=0, atol=1e-12)
    assert np.all(np.isinf(youbot.lower[:3])) and np.all(np.isinf(youbot.upper[:3]))
    np.testing.assert_allclose(youbot.velocity_limit, [0.8, 0.8, 1.0] + [np.pi / 2] * 5, atol=1e-12)


def test_base_and_wheels_are_declared(youbot):
    assert youbot.base.kind is wbc.BaseKind.MECANUM
    assert youbot.base.indices == (0, 1, 2)
    wheels = youbot.base.wheels
    assert (wheels.radius, wheels.half_length, wheels.half_width) == (0.0475, 0.235, 0.15)


def test_frame_pose_matches_eq2_on_1000_configurations(youbot, rng):
    for q in random_youbot_configurations(rng, 1000):
        pose = youbot.frame_pose(q, "ee")
        position, rotation = kapustina_eq2(q)
        np.testing.assert_allclose(pose[:3, 3], position, rtol=0, atol=1e-12)
        np.testing.assert_allclose(pose[:3, :3], rotation, rtol=0, atol=1e-12)
        np.testing.assert_array_equal(pose[3], [0, 0, 0, 1])


def test_eq2_sign_branches_describe_the_same_orientation(rng):
    """The +- of eq. (2) only normalises theta_E into [0, pi]: both signs give one rotation."""
    for q in random_youbot_configurations(rng, 200):
        np.testing.assert_allclose(kapustina_eq2(q, +1)[1], kapustina_eq2(q, -1)[1], atol=1e-12)


def test_ee_z_axis_is_the_wrist_axis_toward_e(youbot, rng):
    for q in random_youbot_configurations(rng, 100):
        wrist = youbot.frame_pose(q, "arm_link_4")[:3, 3]
        ee = youbot.frame_pose(q, "ee")
        direction = (ee[:3, 3] - wrist) / C
        np.testing.assert_allclose(ee[:3, 2], direction, atol=1e-12)


def test_stretched_up_at_theta2_theta3_zero(youbot):
    q = np.zeros(8)
    position = youbot.frame_pose(q, "ee")[:3, 3]
    np.testing.assert_allclose(position, [H + A1, 0.0, D1 + A2 + A3 + C], atol=1e-12)


def test_position_jacobian_matches_kapustinas_entries(youbot, rng):
    for q in random_youbot_configurations(rng, 300):
        J = youbot.frame_jacobian(q, "ee")
        np.testing.assert_allclose(J[:3], kapustina_position_jacobian(q), rtol=0, atol=1e-12)


def _finite_difference_jacobian(robot, q, frame, step=1e-6):
    J = np.zeros((6, robot.nv))
    for i in range(robot.nv):
        dq = np.zeros(robot.nv)
        dq[i] = step
        plus = robot.frame_pose(pin.integrate(robot.model, q, dq), frame)
        minus = robot.frame_pose(pin.integrate(robot.model, q, -dq), frame)
        J[:3, i] = (plus[:3, 3] - minus[:3, 3]) / (2 * step)
        J[3:, i] = pin.log3(plus[:3, :3] @ minus[:3, :3].T) / (2 * step)
    return J


@pytest.mark.parametrize("frame", ["ee", "arm_link_3", "arm_link_5", "base_link"])
def test_frame_jacobian_matches_central_differences(youbot, rng, frame):
    for q in random_youbot_configurations(rng, 50):
        np.testing.assert_allclose(youbot.frame_jacobian(q, frame),
                                   _finite_difference_jacobian(youbot, q, frame), rtol=0, atol=1e-8)


def test_urdf_and_mjcf_have_identical_kinematics(youbot, rng):
    import mujoco  # part of the [test] extra: a missing install must fail, not skip

    model = mujoco.MjModel.from_xml_path(str(wbc.model_path("youbot", "mjcf")))
    data = mujoco.MjData(model)
    assert model.nq == model.nv == youbot.nq
    names = [model.joint(i).name for i in range(model.njnt)]
    assert names == youbot.joint_names
    np.testing.assert_allclose(model.jnt_range[3:], np.c_[youbot.lower[3:], youbot.upper[3:]], atol=1e-12)
    site = model.site("ee").id
    for q in random_youbot_configurations(rng, 500):
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        pose = youbot.frame_pose(q, "ee")
        np.testing.assert_allclose(data.site_xpos[site], pose[:3, 3], rtol=0, atol=1e-12)
        np.testing.assert_allclose(data.site_xmat[site].reshape(3, 3), pose[:3, :3], rtol=0, atol=1e-12)
        for body in ("arm_link_2", "arm_link_3", "arm_link_4", "arm_link_5"):
            np.testing.assert_allclose(data.xpos[model.body(body).id], youbot.frame_pose(q, body)[:3, 3],
                                       rtol=0, atol=1e-12)
