"""Manipulability m(q) and its analytic gradient: value oracles, the kinematic-Hessian layout,
central finite differences on every shipped model, and planar / free-flyer bases."""

import numpy as np
import pinocchio as pin
import pytest

import wbc
from conftest import random_youbot_configurations
from test_youbot_model import kapustina_position_jacobian
from wbc.model.kinematics import Kinematics
from wbc.model.manipulability import ROWS, Manipulability, manipulability, manipulability_gradient

FD_STEP = 1e-6
SAMPLES = 20


def shipped_end_effectors():
    cases = []
    for name in wbc.shipped_models():
        robot = wbc.load_robot(name)
        if robot.end_effector is not None:
            cases.append((name, robot.end_effector))
    return cases


def fd_gradient(robot, q, frame, rows):
    """Central differences of m along each tangent direction (``pin.integrate``)."""
    grad = np.zeros(robot.nv)
    for i in range(robot.nv):
        dq = np.zeros(robot.nv)
        dq[i] = FD_STEP
        plus = manipulability(robot, pin.integrate(robot.model, q, dq), frame, rows)
        minus = manipulability(robot, pin.integrate(robot.model, q, -dq), frame, rows)
        grad[i] = (plus - minus) / (2 * FD_STEP)
    return grad


def fd_jacobian_derivative(robot, q, frame):
    """(6, nv, nv): [:, :, i] = central difference of the frame Jacobian along direction i."""
    out = np.zeros((6, robot.nv, robot.nv))
    for i in range(robot.nv):
        dq = np.zeros(robot.nv)
        dq[i] = FD_STEP
        plus = robot.frame_jacobian(pin.integrate(robot.model, q, dq), frame)
        minus = robot.frame_jacobian(pin.integrate(robot.model, q, -dq), frame)
        out[:, :, i] = (plus - minus) / (2 * FD_STEP)
    return out


def test_every_shipped_model_is_covered():
    assert ("youbot", "ee") in shipped_end_effectors()


@pytest.mark.parametrize("model, frame", shipped_end_effectors())
def test_frame_hessian_layout_matches_finite_differences(model, frame, rng):
    """T[a, j, i] = dJ[a, j]/dq_i, whatever memory layout Pinocchio's binding returns."""
    robot = wbc.load_robot(model)
    kin = Kinematics(robot)
    for _ in range(5):
        q = robot.random_configuration(rng)
        kin.update(q)
        hessian = kin.frame_hessian(robot.frame_id(frame))
        np.testing.assert_allclose(hessian, fd_jacobian_derivative(robot, q, frame), rtol=0, atol=1e-7)


@pytest.mark.parametrize("rows", sorted(ROWS))
@pytest.mark.parametrize("model, frame", shipped_end_effectors())
def test_gradient_matches_central_differences(model, frame, rows, rng):
    robot = wbc.load_robot(model)
    configurations = [robot.random_configuration(rng) for _ in range(SAMPLES)]
    scale = max(np.prod(np.linalg.svd(robot.frame_jacobian(q, frame)[ROWS[rows]], compute_uv=False)[:-1])
                for q in configurations)
    structurally_singular = max(manipulability(robot, q, frame, rows) for q in configurations) < 1e-12 * scale
    for q in configurations:
        analytic = manipulability_gradient(robot, q, frame, rows)
        numeric = fd_gradient(robot, q, frame, rows)
        if structurally_singular:  # m = 0 everywhere (e.g. too few joints for these rows): so is grad m
            assert np.linalg.norm(analytic) < 1e-9 * scale
        else:
            assert np.linalg.norm(analytic - numeric) <= 1e-6 * np.linalg.norm(numeric), (q, analytic, numeric)


def test_value_is_sqrt_det_for_wide_and_tall_jacobians(youbot, rng):
    tall = wbc.Robot(name="five_joints", model=_arm(pin.JointModelRZ()))  # 6 x 5: tall with rows="all"
    pin.seed(int(rng.integers(2**31)))  # pin.randomConfiguration's generator: the same configurations every run
    for robot, frame in ((youbot, "ee"), (tall, "ee")):
        for _ in range(20):
            q = pin.randomConfiguration(robot.model, -np.ones(robot.nq), np.ones(robot.nq))
            for rows, selection in ROWS.items():
                J = robot.frame_jacobian(q, frame)[selection]
                gram = J @ J.T if J.shape[0] <= J.shape[1] else J.T @ J
                expected = np.sqrt(max(np.linalg.det(gram), 0.0))
                assert manipulability(robot, q, frame, rows) == pytest.approx(expected, rel=1e-8, abs=1e-12)


def test_position_manipulability_from_kapustinas_jacobian(youbot, rng):
    """Her position rows j_13..j_37 give sqrt(det(J J^T)) independently of Pinocchio."""
    for q in random_youbot_configurations(rng, 200):
        J = kapustina_position_jacobian(q)
        assert manipulability(youbot, q, "ee", "position") == pytest.approx(np.sqrt(np.linalg.det(J @ J.T)),
                                                                             rel=1e-9)


def test_whole_body_manipulability_vanishes_exactly_on_theta2_theta3_zero(youbot, rng):
    for q in random_youbot_configurations(rng, 200):
        m = manipulability(youbot, q, "ee")
        assert m > 1e-6, "generic configurations have full rank 6"
        q[4:6] = 0.0
        assert manipulability(youbot, q, "ee") < 1e-12


def test_evaluator_reuses_one_kinematics_and_matches_the_convenience_functions(youbot, rng):
    kin = Kinematics(youbot)
    evaluator = Manipulability(youbot, "ee", "position")
    for q in random_youbot_configurations(rng, 10):
        kin.update(q)
        assert evaluator.compute(kin) == pytest.approx(manipulability(youbot, q, "ee", "position"), rel=1e-12)
        np.testing.assert_allclose(evaluator.gradient, manipulability_gradient(youbot, q, "ee", "position"),
                                   rtol=1e-12, atol=1e-15)
    assert repr(evaluator) == "Manipulability(frame='ee', rows='position')"


def _arm(root) -> pin.Model:
    """A root joint carrying a 4-joint arm with skew axes and offsets, frame 'ee' at the tip."""
    model = pin.Model()
    parent = model.addJoint(0, root, pin.SE3.Identity(), "root")
    for name, joint, offset in (("a1", pin.JointModelRZ(), (0.1, 0.0, 0.2)),
                                ("a2", pin.JointModelRY(), (0.0, 0.0, 0.15)),
                                ("a3", pin.JointModelRY(), (0.0, 0.05, 0.3)),
                                ("a4", pin.JointModelRX(), (0.0, 0.0, 0.25))):
        parent = model.addJoint(parent, joint, pin.SE3(np.eye(3), np.array(offset)), name)
    model.addFrame(pin.Frame("ee", parent, pin.SE3(np.eye(3), np.array([0.05, 0.0, 0.1])), pin.FrameType.OP_FRAME))
    return model


@pytest.mark.parametrize("root", [pin.JointModelPlanar(), pin.JointModelFreeFlyer(), pin.JointModelPX()],
                         ids=["planar", "free-flyer", "prismatic"])
def test_gradient_with_multi_dof_and_prismatic_roots(root, rng):
    """Planar (nq 4, nv 3) and free-flyer (nq 7, nv 6) roots: grad m is along the tangent space."""
    robot = wbc.Robot(name="arm_on_" + root.shortname(), model=_arm(root))
    pin.seed(int(rng.integers(2**31)))  # pin.randomConfiguration's generator: the same configurations every run
    for _ in range(10):
        q = pin.randomConfiguration(robot.model, -np.ones(robot.nq), np.ones(robot.nq))
        for rows in ROWS:
            numeric = fd_gradient(robot, q, "ee", rows)
            analytic = manipulability_gradient(robot, q, "ee", rows)
            assert np.linalg.norm(analytic - numeric) <= 1e-6 * np.linalg.norm(numeric)


def test_gradient_is_finite_on_and_accurate_next_to_the_singular_set(youbot):
    q = np.array([0.3, -0.2, 0.4, 0.1, 0.0, 0.0, 0.7, -0.3])
    assert np.all(np.isfinite(manipulability_gradient(youbot, q, "ee")))  # m is not differentiable here
    q[4:6] = 1e-3, -2e-3
    numeric = fd_gradient(youbot, q, "ee", "all")
    assert np.linalg.norm(manipulability_gradient(youbot, q, "ee") - numeric) <= 1e-5 * np.linalg.norm(numeric)


def test_bad_input_raises_wbc_errors(youbot):
    with pytest.raises(wbc.InvalidInputError, match="rows"):
        manipulability(youbot, np.zeros(8), "ee", rows="linear")
    with pytest.raises(wbc.UnknownFrameError):
        manipulability_gradient(youbot, np.zeros(8), "gripper")
    with pytest.raises(wbc.InvalidInputError):
        manipulability(youbot, np.zeros(7), "ee")
    with pytest.raises(wbc.InvalidInputError):
        manipulability_gradient(youbot, np.full(8, np.nan), "ee")
