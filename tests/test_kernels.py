"""The compiled kernels and the tick program compute what Pinocchio and the plain formulas compute."""

import importlib
import sys
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import wbc
from conftest import TASKS
from wbc.app.scenario import load_scenario
from wbc.constraints.constraint import ConstraintData
from wbc.model.kinematics import Kinematics
from wbc.runtime import kernels
from wbc.runtime.program import TickProgram
from wbc.tasks.frame_task import FrameTaskData
from wbc.tasks.task import TaskData

importlib.import_module("wbc.model.manipulability")
manipulability_module = sys.modules["wbc.model.manipulability"]  # wbc.manipulability is the function

MODELS = [("youbot", "ee"), ("deluca_mm", "wrist_center"), ("scorbot_er4pc", "ee"), ("puma560", "wrist_center")]


def rotation_vectors(rng, count):
    """Angles spread over [0, pi], with clusters next to 0 and next to pi."""
    axes = rng.standard_normal((count, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    angles = np.concatenate([rng.uniform(0, np.pi, count - 2 * (count // 3)),
                             10.0 ** rng.uniform(-12, -2, count // 3),
                             np.pi - 10.0 ** rng.uniform(-12, -2, count // 3)])
    return axes * angles[:, None]


def test_log3_inverts_exp3_over_the_whole_angle_range(rng):
    out = np.zeros(3)
    for w in rotation_vectors(rng, 3000):
        R = pin.exp3(w)
        kernels.log3(R.ravel(), out)
        np.testing.assert_allclose(pin.exp3(out), R, rtol=0, atol=2e-15)
        assert np.linalg.norm(out) <= np.pi + 1e-15
        if np.linalg.norm(w) < 3.0:  # unique vector, well conditioned (1 / sin(angle)): Pinocchio's
            np.testing.assert_allclose(out, pin.log3(R), rtol=0, atol=1e-12)


@pytest.mark.parametrize("name, frame", MODELS)
def test_frame_task_rows_are_pinocchios_jacobian_and_error(name, frame, rng):
    robot = wbc.load_robot(name)
    task = wbc.FrameTask(frame, [1.0, 2.0, 3.0], [0.5, 0.25, 4.0], gain=0.3, max_speed=0.2, max_angular_speed=0.5)
    rows_of = task.bind(robot)  # the task's data for one controller
    kin = Kinematics(robot)
    W = np.sqrt([1.0, 2.0, 3.0, 0.5, 0.25, 4.0])
    dt = 0.01
    for _ in range(20):
        q = robot.random_configuration(rng)
        data = robot.model.createData()
        pin.computeJointJacobians(robot.model, data, q)
        frame_id = robot.frame_id(frame)
        placement = pin.updateFramePlacement(robot.model, data, frame_id)
        # orientation errors up to 2.5 rad (log3 near pi is tested above)
        w = rng.standard_normal(3)
        w *= rng.uniform(0, 2.5) / np.linalg.norm(w)
        target = pin.SE3(pin.exp3(w) @ placement.rotation, rng.uniform(-1, 1, 3))
        twist = rng.standard_normal(6)
        task.set_target(target.homogeneous, twist)
        kin.update(q)
        jacobian, rows = np.zeros((6, robot.nv)), np.zeros(6)
        rows_of.compute(kin, dt, jacobian, rows)

        J = pin.getFrameJacobian(robot.model, data, frame_id, pin.LOCAL_WORLD_ALIGNED)
        error = np.concatenate([target.translation - placement.translation,
                                pin.log3(target.rotation @ placement.rotation.T)])
        feedback = 0.3 / dt * error
        for part, limit in ((slice(0, 3), 0.2), (slice(3, 6), 0.5)):
            norm = np.linalg.norm(feedback[part])
            if norm > limit:
                feedback[part] *= limit / norm
        np.testing.assert_allclose(rows_of.error, error, rtol=0, atol=1e-12)
        np.testing.assert_allclose(jacobian, W[:, None] * J, rtol=0, atol=1e-12)
        np.testing.assert_allclose(rows, W * (feedback + twist), rtol=0, atol=1e-10)


@pytest.mark.parametrize("name, frame", MODELS)
def test_position_task_rows_are_pinocchios(name, frame, rng):
    robot = wbc.load_robot(name)
    task = wbc.PositionTask(frame, [1.0, 4.0, 9.0], gain=0.2, max_speed=0.3)
    rows_of = task.bind(robot)  # the task's data for one controller
    kin = Kinematics(robot)
    dt = 0.01
    for _ in range(20):
        q = robot.random_configuration(rng)
        goal, velocity = rng.uniform(-1, 1, 3), rng.standard_normal(3)
        task.set_target(goal, velocity)
        kin.update(q)
        jacobian, rows = np.zeros((3, robot.nv)), np.zeros(3)
        rows_of.compute(kin, dt, jacobian, rows)
        J = robot.frame_jacobian(q, frame)[:3]
        error = goal - robot.frame_pose(q, frame)[:3, 3]
        feedback = 0.2 / dt * error
        feedback *= min(1.0, 0.3 / np.linalg.norm(feedback))
        np.testing.assert_allclose(rows_of.error, error, rtol=0, atol=1e-12)
        np.testing.assert_allclose(jacobian, np.array([1.0, 2.0, 3.0])[:, None] * J, rtol=0, atol=1e-12)
        np.testing.assert_allclose(rows, [1.0, 2.0, 3.0] * (feedback + velocity), rtol=0, atol=1e-10)


@pytest.mark.parametrize("name, frame", MODELS)
@pytest.mark.parametrize("rows", ["all", "position", "orientation"])
def test_compiled_manipulability_is_the_kinematic_hessian_form(name, frame, rows, rng):
    """dJ/dq from motion cross products (compiled) vs Pinocchio's kinematic Hessian, on random
    configurations and, for the youBot, next to its gripper-vertical singular set."""
    robot = wbc.load_robot(name)
    compiled = manipulability_module.Manipulability(robot, frame, rows)
    reference = manipulability_module.Manipulability(robot, frame, rows)
    assert compiled.compiled
    reference._compiled = False
    kin = Kinematics(robot)
    for k in range(40):
        q = robot.random_configuration(rng)
        if name == "youbot" and k % 2:
            q[6] = -(q[4] + q[5]) + 10.0 ** rng.uniform(-8, -2)  # s_min from ~1e-8 to ~1e-2
        kin.update(q)
        value = compiled.compute(kin)
        expected = reference.compute(kin)
        scale = max(np.abs(reference.gradient).max(), 1e-9)
        assert value == pytest.approx(expected, rel=1e-9, abs=1e-15)
        np.testing.assert_allclose(compiled.gradient, reference.gradient, rtol=0, atol=1e-8 * scale + 1e-14)


def _python_only(monkeypatch):
    """Every task and constraint computed by its Python compute (no compiled ops)."""
    classes = {TaskData, ConstraintData}
    while True:
        more = {sub for cls in classes for sub in cls.__subclasses__()} - classes
        if not more:
            break
        classes |= more
    for cls in classes:
        for name in ("add_ops", "add_preview_ops"):
            if name in vars(cls):
                monkeypatch.setattr(cls, name, lambda self, *args: False)


@pytest.mark.parametrize("path", sorted(TASKS.glob("*.toml")), ids=lambda p: p.stem)
def test_the_program_computes_what_the_python_path_computes(path: Path, monkeypatch):
    """Same scenario, same ticks: the compiled program (operands by address, rows at offsets)
    and the per-item Python path give the same QP and the same command."""
    compiled = load_scenario(path)
    controller = compiled.make_controller("daqp")
    compiled_items = (len(controller._task_blocks) - len(controller._python_tasks)
                      + len(controller._constraint_blocks) - len(controller._python_constraints))
    assert compiled_items > 0, "the shipped stacks have compiled ops"
    with monkeypatch.context() as patch:
        _python_only(patch)
        plain = load_scenario(path)
        reference = plain.make_controller("daqp")
    assert len(reference._python_tasks) == len(reference._task_blocks)
    assert len(reference._python_constraints) == len(reference._constraint_blocks)
    q = compiled.q0.copy()
    for k in range(0, compiled.ticks, max(1, compiled.ticks // 25)):
        for scenario in (compiled, plain):
            scenario.reference_task.set_target(*scenario.reference(k * scenario.dt))
        v = controller.step(q)
        v_reference = reference.step(q)
        np.testing.assert_allclose(controller._qp_v.data, reference._qp_v.data, rtol=0, atol=1e-12)
        np.testing.assert_allclose(v, v_reference, rtol=0, atol=1e-9)
        q = compiled.robot.integrate(q, v, compiled.dt)


def test_a_subclass_with_its_own_compute_is_not_compiled(youbot):
    class HalvedData(FrameTaskData):
        def compute(self, kin, dt, jacobian, target):
            super().compute(kin, dt, jacobian, target)
            target *= 0.5

    class Halved(wbc.FrameTask):
        def bind(self, robot):
            return HalvedData(self, robot)

    task, halved = wbc.FrameTask("ee"), Halved("ee")
    for t in (task, halved):
        t.set_target(youbot.frame_pose(youbot.neutral(), "ee"))
    q = youbot.neutral()
    q[4] = 0.4
    # (without the error-scaled damping, whose mu grows with the target, v is linear in the target)
    full = wbc.Controller(youbot, [task], lm_damping=0.0).step(q)
    half = wbc.Controller(youbot, [halved], lm_damping=0.0).step(q)
    assert np.abs(full).max() > 1e-3
    np.testing.assert_allclose(half, 0.5 * full, rtol=1e-6, atol=1e-9)


def test_a_specification_that_overrides_its_datas_methods_is_refused(youbot):
    """Rows of a built-in item are computed by its data (FrameTaskData): a subclass of the
    specification overriding compute would be silently ignored, so it is refused."""
    class Halved(wbc.FrameTask):
        def compute(self, kin, dt, jacobian, target):
            pass

    task = Halved("ee")
    task.set_target(youbot.frame_pose(youbot.neutral(), "ee"))
    with pytest.raises(wbc.InvalidInputError, match="FrameTaskData"):
        wbc.Controller(youbot, [task])


def test_inherited_ops_never_replace_an_overridden_compute():
    """The rule behind the subclass test above, for constraints and preview tasks too."""
    from wbc.constraints.joint_position_limits import JointPositionLimitsData
    from wbc.runtime.program import ops_follow_compute
    from wbc.tasks.steering_task import SteeringTaskData

    class LimitsData(JointPositionLimitsData):
        def compute(self, kin, dt, rows):
            super().compute(kin, dt, rows)

    class Limits(wbc.JointPositionLimits):
        def bind(self, robot):
            return LimitsData(self, robot)

    class SteeringData(SteeringTaskData):
        def compute_preview(self, kin, dt, jacobian, target, preview):
            super().compute_preview(kin, dt, jacobian, target, preview)

    class Steering(wbc.SteeringTask):
        def bind(self, robot):
            return SteeringData(self, robot)

    class OwnOps(JointPositionLimitsData):  # overrides both: its own ops stand
        def compute(self, kin, dt, rows):
            super().compute(kin, dt, rows)

        def add_ops(self, program, kin, rows):
            return super().add_ops(program, kin, rows)

    robot = wbc.load_robot("deluca_mm")
    limits = wbc.JointPositionLimits()
    assert ops_follow_compute(limits.bind(robot)) and ops_follow_compute(OwnOps(limits, robot))
    assert not ops_follow_compute(LimitsData(limits, robot))
    assert not ops_follow_compute(Steering().bind(robot), "compute_preview", "add_preview_ops")
    task = wbc.PositionTask("wrist_center")
    task.set_target([1.0, 0.5, 0.5])
    controller = wbc.Controller(robot, [task, Steering()], [wbc.NonholonomicBase(), Limits()])
    assert [type(t) for t, _, _ in controller._python_preview] == [SteeringData]  # not compiled
    assert [type(c) for c, _ in controller._python_constraints] == [LimitsData]
    assert np.all(np.isfinite(controller.step(robot.neutral())))


def test_program_operands_must_be_contiguous_float64():
    program = TickProgram()
    with pytest.raises(TypeError):
        program.array(np.zeros((3, 4))[:, 1])
    with pytest.raises(TypeError):
        program.array(np.zeros(3, dtype=np.float32))
    base = np.zeros(5)
    assert program.array(base) == program.array(base) == 0  # registered once


def test_pose_check_agrees_with_the_plain_checks(rng):
    """The compiled fast path of as_pose accepts exactly what the numpy checks accept."""
    from wbc.core.errors import InvalidInputError
    from wbc.core.validation import ROTATION_TOLERANCE

    def plain_ok(pose):
        if not np.all(np.isfinite(pose)) or np.max(np.abs(pose[3] - [0, 0, 0, 1])) > 1e-12:
            return False
        R = pose[:3, :3]
        return (np.max(np.abs(R.T @ R - np.eye(3))) <= ROTATION_TOLERANCE
                and abs(np.linalg.det(R) - 1.0) <= ROTATION_TOLERANCE)

    for k in range(2000):
        pose = np.eye(4)
        pose[:3, :3] = pin.exp3(rng.standard_normal(3))
        pose[:3, 3] = rng.standard_normal(3)
        kind = k % 5
        if kind == 1:
            pose[:3, :3] += rng.standard_normal((3, 3)) * 10.0 ** rng.uniform(-8, -4)  # near the tolerance
        elif kind == 2:
            pose[rng.integers(4), rng.integers(4)] = rng.choice([np.nan, np.inf, -np.inf])
        elif kind == 3:
            pose[3, rng.integers(4)] += 10.0 ** rng.uniform(-14, -10)
        elif kind == 4:
            pose[:3, 0] *= -1.0  # a reflection
        assert (kernels.pose_defect(pose, ROTATION_TOLERANCE) == kernels.POSE_OK) == plain_ok(pose)
        if not plain_ok(pose):
            with pytest.raises(InvalidInputError):
                wbc.core.validation.as_pose(pose, "pose")


@pytest.mark.parametrize("compiled", [True, False])
def test_steering_preview_without_damping_is_a_safe_zero_preview(compiled, monkeypatch):
    """No damping (nor error-scaled damping) and fewer task rows than DOF: H is singular, the
    holonomic relaxation has no unique solution. The preview is then zero (the steering row fades out) instead of an
    exception from the solve, on the compiled and the Python path alike."""
    if not compiled:
        _python_only(monkeypatch)
    robot = wbc.load_robot("deluca_mm")
    task = wbc.PositionTask("wrist_center", 1.0, gain=0.1)
    task.set_target([1.0, 2.0, 0.5])
    steering = wbc.SteeringTask()
    controller = wbc.Controller(robot, [task, steering], [wbc.NonholonomicBase(), wbc.JointVelocityLimits()],
                                damping=0.0, lm_damping=0.0)
    assert (controller._program_after_preview is None) == compiled  # Python preview: a second part
    v = controller.step(robot.neutral())
    assert np.all(np.isfinite(v))
    np.testing.assert_array_equal(controller._preview, 0.0)
    assert controller.data(steering).error[0] == 0.0


def test_settings_changed_between_ticks_reach_the_compiled_ops(youbot):
    """Gains, speed bounds and barrier settings assigned after construction act on the next
    tick exactly as if the controller had been built with them (and are validated)."""
    def stack(gain, speed, limit_gain, floor):
        frame = wbc.FrameTask("ee", 1.0, 0.5, gain=gain, max_speed=speed)
        frame.set_target(youbot.frame_pose(youbot.neutral(), "ee"))
        posture = wbc.PostureTask(1e-2, gain=gain)
        limits = wbc.JointPositionLimits(gain=limit_gain)
        barrier = wbc.ManipulabilityBarrier("ee", min_value=floor, gain=gain)
        controller = wbc.Controller(youbot, [frame, posture], [limits, wbc.JointVelocityLimits(), barrier])
        return controller, (frame, posture, limits, barrier)

    q = youbot.neutral()
    q[3:] = [2.9, 1.5, -2.5, 1.7, 0.3]  # near some position limits
    tuned, (frame, posture, limits, barrier) = stack(0.5, None, 0.5, 1e-4)
    tuned.step(q)
    frame.gain = posture.gain = barrier.gain = 0.2
    frame.max_speed, limits.gain, barrier.min_value = 0.05, 0.9, 0.02
    fresh, _ = stack(0.2, 0.05, 0.9, 0.02)
    np.testing.assert_allclose(tuned.step(q), fresh.step(q), rtol=0, atol=1e-9)
    with pytest.raises(wbc.InvalidInputError):
        frame.gain = 1.5
    with pytest.raises(wbc.InvalidInputError):
        barrier.min_value = -1.0


@pytest.mark.parametrize("infinite", [0, 1])
def test_the_nan_screens_agree_with_numpy(infinite, rng):
    """The NaN screen (``has_nan``; ``has_non_finite`` for q) as a compiled function on contiguous and
    strided arrays and as the HAS_NAN op: NaN (and, for ``infinite``, +-inf) at any position of
    arrays of 0-300 entries -- the one-pass reductions miss none, and an infinite entry alone is
    not a NaN."""
    screen = kernels.has_non_finite if infinite else kernels.has_nan
    expected_of = (lambda a: not np.all(np.isfinite(a))) if infinite else (lambda a: bool(np.isnan(a).any()))
    found = 0
    for _ in range(400):
        size = int(rng.integers(0, 300))
        data = rng.normal(size=size)
        for value in (np.nan, np.inf, -np.inf):
            if size and rng.random() < 0.3:
                data[rng.integers(size)] = value
        expected = expected_of(data)
        found += expected
        assert screen(data) is expected
        assert screen(data[::2]) is expected_of(data[::2])
        if size:
            buffer = data.copy()
            program = TickProgram()
            program.add(kernels.HAS_NAN, data=buffer, size=size, infinite=infinite)
            assert program.run(0.01) is expected
    assert 50 < found < 350
