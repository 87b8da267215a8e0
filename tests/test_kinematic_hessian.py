"""The derivative of a frame Jacobian (Kinematics.frame_hessian / contract_frame_hessian) on every
Pinocchio wbc supports: wbc's own closed form (the only one pin 3.x offers, whose binding has no
kinematic Hessian) and Pinocchio's (pin >= 4), each against central differences of the frame
Jacobian along pin.integrate, and against each other where both exist."""

import numpy as np
import pinocchio as pin
import pytest

import wbc
from wbc.model import kinematics
from wbc.model.kinematics import (
    HESSIAN_JOINTS,
    Kinematics,
    contract_jacobian_derivative,
    hessian_ancestry,
    jacobian_derivative,
)
from wbc.model.manipulability import manipulability, manipulability_gradient

FD_STEP = 1e-6
DT = 0.01
#: the ways Kinematics can get the tensor here: its own closed form always, Pinocchio's where the
#: binding has it (pin >= 4, which the main CI job installs; the oldest-versions job runs pin 3.x)
PATHS = [False, True] if kinematics.PINOCCHIO_HESSIANS else [False]
needs_pinocchio_hessians = pytest.mark.skipif(not kinematics.PINOCCHIO_HESSIANS,
                                              reason=f"pin {pin.__version__} has no kinematic Hessian binding")


def arm(root: pin.JointModel) -> pin.Model:
    """``root`` carrying a 4-joint arm with skew axes and offsets; frame 'ee' (rotated) at the tip."""
    model = pin.Model()
    parent = model.addJoint(0, root, pin.SE3(pin.rpy.rpyToMatrix(0.2, -0.1, 0.3), np.array([0.1, -0.2, 0.05])),
                            "root")
    for name, joint, offset in (("a1", pin.JointModelRZ(), (0.1, 0.0, 0.2)),
                                ("a2", pin.JointModelRY(), (0.0, 0.0, 0.15)),
                                ("a3", pin.JointModelRevoluteUnaligned(0.6, 0.0, 0.8), (0.0, 0.05, 0.3)),
                                ("a4", pin.JointModelPrismaticUnaligned(0.0, 0.8, 0.6), (0.0, 0.0, 0.25))):
        parent = model.addJoint(parent, joint, pin.SE3(np.eye(3), np.array(offset)), name)
    model.addFrame(pin.Frame("ee", parent, pin.SE3(pin.rpy.rpyToMatrix(0.4, 0.3, -0.2), np.array([0.05, 0.0, 0.1])),
                             pin.FrameType.OP_FRAME))
    return model


#: a root joint of every supported kind with more than one DOF or an unaligned axis
ROOTS = {
    "planar": pin.JointModelPlanar(),
    "free-flyer": pin.JointModelFreeFlyer(),
    "spherical": pin.JointModelSpherical(),
    "translation": pin.JointModelTranslation(),
    "helical": pin.JointModelHelicalUnaligned(np.array([0.0, 0.6, 0.8]), 0.3),
    "continuous": pin.JointModelRUBZ(),
}


def random_configuration(model: pin.Model, rng: np.random.Generator) -> np.ndarray:
    """A configuration with every coordinate drawn in [-1, 1] (normalised where the joint needs it)."""
    return pin.normalize(model, rng.uniform(-1.0, 1.0, model.nq))


def fd_jacobian_derivative(model: pin.Model, q: np.ndarray, frame_id: int) -> np.ndarray:
    """(6, nv, nv): [:, :, i] = central difference of the frame Jacobian along tangent direction i."""
    out = np.zeros((6, model.nv, model.nv))
    data = model.createData()
    for i in range(model.nv):
        dq = np.zeros(model.nv)
        dq[i] = FD_STEP
        plus = pin.computeFrameJacobian(model, data, pin.integrate(model, q, dq), frame_id, kinematics._LWA)
        minus = pin.computeFrameJacobian(model, data, pin.integrate(model, q, -dq), frame_id, kinematics._LWA)
        out[:, :, i] = (plus - minus) / (2 * FD_STEP)
    return out


def kinematics_on(robot: wbc.Robot, pinocchio_hessians: bool, monkeypatch) -> Kinematics:
    """A Kinematics taking the tensor from Pinocchio's binding, or from wbc's closed form."""
    with monkeypatch.context() as patch:
        patch.setattr(kinematics, "PINOCCHIO_HESSIANS", pinocchio_hessians)
        return Kinematics(robot)


def shipped_frames():
    """(model name, frame) for every frame of every shipped model that a joint carries."""
    cases = []
    for name in wbc.shipped_models():
        model = wbc.load_robot(name).model
        cases += [(name, frame.name) for frame in model.frames if frame.parentJoint > 0]
    return cases


def test_every_shipped_model_has_frames_to_check():
    names = {name for name, _ in shipped_frames()}
    assert names == set(wbc.shipped_models()) and ("youbot", "ee") in shipped_frames()


@pytest.mark.parametrize("pinocchio_hessians", PATHS, ids=lambda p: "pinocchio" if p else "closed-form")
@pytest.mark.parametrize("name", sorted(wbc.shipped_models()))
def test_frame_hessian_is_the_derivative_of_the_jacobian_on_every_shipped_frame(name, pinocchio_hessians, rng,
                                                                                monkeypatch):
    robot = wbc.load_robot(name)
    kin = kinematics_on(robot, pinocchio_hessians, monkeypatch)
    frames = [frame for model_name, frame in shipped_frames() if model_name == name]
    for _ in range(3):
        q = robot.random_configuration(rng)
        kin.update(q)
        for frame in frames:
            frame_id = robot.frame_id(frame)
            np.testing.assert_allclose(kin.frame_hessian(frame_id), fd_jacobian_derivative(robot.model, q, frame_id),
                                       rtol=0, atol=1e-7, err_msg=frame)


@pytest.mark.parametrize("pinocchio_hessians", PATHS, ids=lambda p: "pinocchio" if p else "closed-form")
@pytest.mark.parametrize("root", sorted(ROOTS))
def test_frame_hessian_and_its_contraction_on_multi_dof_roots(root, pinocchio_hessians, rng, monkeypatch):
    """Within a planar, free-flyer or spherical joint, moving along one tangent direction turns the
    joint's other columns too: the derivative is taken along pin.integrate, as the gradient's is."""
    robot = wbc.Robot(name="arm_on_" + root, model=arm(ROOTS[root]))
    kin = kinematics_on(robot, pinocchio_hessians, monkeypatch)
    frame_id = robot.frame_id("ee")
    out = np.zeros(robot.nv)
    for _ in range(5):
        q = random_configuration(robot.model, rng)
        kin.update(q)
        reference = fd_jacobian_derivative(robot.model, q, frame_id)
        np.testing.assert_allclose(kin.frame_hessian(frame_id), reference, rtol=0, atol=1e-7)
        weights = rng.standard_normal((6, robot.nv))
        kin.contract_frame_hessian(frame_id, np.ascontiguousarray(weights.T), out)
        np.testing.assert_allclose(out, np.einsum("aj,aji->i", weights, reference), rtol=0, atol=1e-6)


@needs_pinocchio_hessians
@pytest.mark.parametrize("root", sorted(ROOTS))
def test_closed_form_is_pinocchios_kinematic_hessian(root, rng):
    """To rounding, wbc's tensor is Pinocchio's getFrameKinematicHessian(LOCAL_WORLD_ALIGNED)."""
    model = arm(ROOTS[root])
    data = model.createData()
    frame_id = model.getFrameId("ee")
    ancestry_t = hessian_ancestry(model, frame_id).T
    for _ in range(10):
        pin.computeJointJacobians(model, data, random_configuration(model, rng))
        pin.computeJointKinematicHessians(model, data)
        raw = pin.getFrameKinematicHessian(model, data, frame_id, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
        # Eigen's column-major (6, nv, nv) buffer: element (a, j, i) at a + 6 j + 6 nv i
        expected = np.ravel(raw, order="K").reshape(model.nv, model.nv, 6).transpose(2, 1, 0)
        jacobian = pin.getFrameJacobian(model, data, frame_id, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
        np.testing.assert_allclose(jacobian_derivative(jacobian, ancestry_t), expected, rtol=0, atol=1e-14)


def test_contraction_is_the_tensor_contracted(rng):
    """contract_jacobian_derivative == sum_{a, j} W[a, j] T[a, j, i] for any J, W and mask."""
    for nv in (1, 4, 9):
        jacobian = rng.standard_normal((6, nv))
        weights = rng.standard_normal((6, nv))
        ancestry_t = (rng.random((nv, nv)) < 0.5).astype(float)
        out = np.full(nv, np.nan)
        contract_jacobian_derivative(jacobian, np.ascontiguousarray(weights.T), ancestry_t, 1.0 - ancestry_t, out)
        expected = np.einsum("aj,aji->i", weights, jacobian_derivative(jacobian, ancestry_t))
        np.testing.assert_allclose(out, expected, rtol=1e-13, atol=1e-13)


def test_ancestry_of_a_chain_is_joint_order():
    """On a chain, A[i, j] = 1 iff the joint of velocity coordinate i comes no later than that of j."""
    model = arm(pin.JointModelFreeFlyer())  # columns 0-5: the free flyer, 6-9: a1..a4
    joint_of = np.array([1] * 6 + [2, 3, 4, 5])
    expected = (joint_of[:, None] <= joint_of[None, :]).astype(float)
    np.testing.assert_array_equal(hessian_ancestry(model, model.getFrameId("ee")), expected)
    # a frame on a1 is carried by the free flyer and a1 only: nothing from a2..a4
    model.addFrame(pin.Frame("on_a1", 2, pin.SE3.Identity(), pin.FrameType.OP_FRAME))
    expected[:, 7:] = 0.0
    expected[7:, :] = 0.0
    np.testing.assert_array_equal(hessian_ancestry(model, model.getFrameId("on_a1")), expected)


@pytest.mark.parametrize("joint", ["JointModelSphericalZYX", "JointModelUniversal"])
def test_configuration_dependent_joints_raise_model_error(joint, monkeypatch):
    """Their motion subspace turns with q, which neither formula (nor Pinocchio's) accounts for."""
    assert joint not in HESSIAN_JOINTS
    root = pin.JointModelSphericalZYX() if joint == "JointModelSphericalZYX" else pin.JointModelUniversal(
        np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0]))
    robot = wbc.Robot(name="arm_on_" + joint, model=arm(root))
    q = pin.neutral(robot.model)
    for pinocchio_hessians in PATHS:
        kin = kinematics_on(robot, pinocchio_hessians, monkeypatch)
        kin.update(q)
        with pytest.raises(wbc.ModelError, match=f"joint 'root' \\({joint}"):
            kin.frame_hessian(robot.frame_id("ee"))
        with pytest.raises(wbc.ModelError, match="motion subspace is not constant in the joint frame"):
            kin.contract_frame_hessian(robot.frame_id("ee"), np.zeros((robot.nv, 6)), np.zeros(robot.nv))
    with pytest.raises(wbc.ModelError):
        manipulability_gradient(robot, q, "ee")


@pytest.mark.parametrize("root", ["planar", "free-flyer"])
def test_manipulability_task_on_a_multi_dof_root_runs_a_controller(root):
    """End to end (the path pin 3.x died on at construction): a Controller with a ManipulabilityTask
    on a planar / free-flyer base builds, and its row is 2 grad(ln m) by central differences."""
    robot = wbc.Robot(name="arm_on_" + root, model=arm(ROOTS[root]))
    task = wbc.ManipulabilityTask("ee", cost=4.0, gain=0.2, target=0.3, rows="position")
    controller = wbc.Controller(robot, [task], dt=DT)
    q = random_configuration(robot.model, np.random.default_rng(7))
    assert np.all(np.isfinite(controller.step(q)))
    m = manipulability(robot, q, "ee", "position")
    gradient = np.zeros(robot.nv)
    for i in range(robot.nv):
        dq = np.zeros(robot.nv)
        dq[i] = FD_STEP
        gradient[i] = (manipulability(robot, pin.integrate(robot.model, q, dq), "ee", "position")
                       - manipulability(robot, pin.integrate(robot.model, q, -dq), "ee", "position")) / (2 * FD_STEP)
    np.testing.assert_allclose(controller._task_stack.stack[0, :-1], 2.0 * gradient / m, rtol=0, atol=1e-7)
