"""Public API surface and bad input: clear exceptions at the boundary, before any solver runs."""

import copy
import importlib.metadata
import shutil

import numpy as np
import pytest

import wbc


def make_controller(robot, **kwargs):
    task = wbc.FrameTask("ee", position_cost=1.0, orientation_cost=0.5, gain=0.5)
    q = np.array([0, 0, 0, 0, 0.5, 1.0, 1.2, 0.0])
    task.set_target_from_configuration(robot, q)
    return wbc.Controller(robot, [task], [wbc.JointPositionLimits(), wbc.JointVelocityLimits()], **kwargs), q


def test_public_names_are_importable_from_wbc():
    for name in ("load_robot", "Robot", "Controller", "FrameTask", "BaseVelocityTask", "PostureTask",
                 "JointPositionLimits", "JointVelocityLimits", "available_solvers"):
        assert hasattr(wbc, name), name


def test_version_is_the_installed_distributions():
    """One version: pyproject reads it from wbc.__version__, so the installed metadata must agree."""
    assert wbc.__version__ == importlib.metadata.version("wbc")


def test_robot_interface(youbot):
    q = youbot.neutral()
    assert q.shape == (8,) and youbot.within_limits(q)
    assert youbot.frame_pose(q, "ee").shape == (4, 4)
    assert youbot.frame_jacobian(q, "ee").shape == (6, 8)
    v = np.arange(8) * 0.1
    np.testing.assert_allclose(youbot.integrate(q, v, 0.5), q + 0.05 * np.arange(8), atol=1e-15)
    with pytest.raises(ValueError):
        youbot.lower[0] = 1.0  # limits are read-only


def test_step_returns_nv_vector_and_diagnostics(youbot):
    controller, q = make_controller(youbot)
    v = controller.step(q)
    assert v.shape == (8,) and np.all(np.isfinite(v))
    last = controller.last
    assert last.success and last.status == "optimal" and last.solver == "daqp"
    assert last.solve_time > 0 and last.tick_time >= last.solve_time
    assert set(last.task_errors) == {"FrameTask(ee).position", "FrameTask(ee).orientation"}
    assert last.task_errors["FrameTask(ee).position"] < 1e-12
    assert isinstance(last.active_constraints, list)


def test_last_before_the_first_step_is_a_clear_error(youbot):
    """``controller.last`` is typed TickDiagnostics (never None): before the first step it raises a
    wbc error saying what to do, which is also an AttributeError (hasattr / getattr probes)."""
    controller, q = make_controller(youbot)
    with pytest.raises(wbc.WbcError, match=r"no tick yet; call controller\.step\(q\) first"):
        controller.last  # noqa: B018 -- the read is the test
    assert not hasattr(controller, "last") and getattr(controller, "last", None) is None
    controller.step(q)
    assert controller.last.tick == 1 and hasattr(controller, "last")


def test_a_refused_target_keeps_the_previous_one():
    """FrameTask.set_target's docstring: a bad pose or twist raises and leaves the target as it was."""
    task = wbc.FrameTask("ee")
    pose = np.eye(4)
    pose[:3, 3] = (1.0, 2.0, 3.0)
    task.set_target(pose)
    for bad_pose, twist in ((np.diag([2.0, 1.0, 1.0, 1.0]), None), (np.full((4, 4), np.nan), None), (pose, [1.0, 2.0])):
        with pytest.raises(wbc.InvalidInputError):
            task.set_target(bad_pose, twist)
        np.testing.assert_array_equal(task.target, pose)


@pytest.mark.parametrize("make", [lambda: wbc.PositionTask("ee", gain=0.5), lambda: wbc.CoMTask(gain=0.5)],
                         ids=["PositionTask", "CoMTask"])
def test_a_refused_point_target_keeps_the_previous_point_and_velocity(youbot, make):
    """set_target(position, velocity): a good position with a bad velocity (or the reverse) is
    refused whole -- the next command is that of a task given only the earlier target (the
    position was written before the velocity was checked: the target moved on a refused call)."""
    q = np.array([0.0, 0.0, 0.3, 0.2, 0.5, 1.0, 1.2, 0.0])
    point, velocity = np.array([0.4, -0.2, 0.3]), np.array([0.05, 0.0, -0.02])
    task, reference = make(), make()
    task.set_target(point, velocity)
    reference.set_target(point, velocity)
    for bad_point, bad_velocity in (([9.0, 9.0, 9.0], [np.nan, 0.0, 0.0]), ([np.inf, 0.0, 0.0], [0.1, 0.1, 0.1]),
                                    ([9.0, 9.0, 9.0], [1.0, 2.0])):
        with pytest.raises(wbc.InvalidInputError):
            task.set_target(bad_point, bad_velocity)
    commands = [wbc.Controller(youbot, [t, wbc.PostureTask(1e-3)], [wbc.JointVelocityLimits()]).step(q)
                for t in (task, reference)]
    np.testing.assert_array_equal(commands[0], commands[1])
    np.testing.assert_array_equal(task.target, point)


def test_a_target_with_a_twist_is_kept_whole_or_replaced_whole(youbot):
    """FrameTask.set_target: a refused pose or twist keeps the previous pose *and* feed-forward
    twist; a later target without a twist drops the twist. Checked through the command, against a
    task given only the expected target (a twist of 0.2 m/s changes the command)."""
    q = np.array([0, 0, 0, 0, 0.5, 1.0, 1.2, 0.0])
    pose, twist = youbot.frame_pose(q, "ee"), np.array([0.2, 0.0, -0.1, 0.0, 0.3, 0.0])
    pose[0, 3] += 0.02

    def command(*target):
        task = wbc.FrameTask("ee", position_cost=1.0, orientation_cost=0.5, gain=0.5)
        task.set_target(*target)
        return task, wbc.Controller(youbot, [task], [wbc.JointVelocityLimits()])

    task, controller = command(pose, twist)
    with_twist = controller.step(q)
    for bad_pose, bad_twist in ((np.diag([2.0, 1.0, 1.0, 1.0]), -twist), (np.full((4, 4), np.nan), -twist),
                                (pose, [1.0, 2.0]), (pose, [0, 0, np.inf, 0, 0, 0])):
        with pytest.raises(wbc.InvalidInputError):
            task.set_target(bad_pose, bad_twist)
        np.testing.assert_array_equal(controller.step(q), with_twist)
    without_twist = command(pose)[1].step(q)
    assert np.abs(with_twist - without_twist).max() > 1e-3
    task.set_target(pose)
    np.testing.assert_array_equal(controller.step(q), without_twist)


def test_active_constraints_name_the_saturated_limits(youbot):
    controller, q = make_controller(youbot)
    target = youbot.frame_pose(q, "ee")
    target[2, 3] += 0.3  # far: the command saturates
    controller.tasks[0].set_target(target)
    v = controller.step(q)
    active = controller.last.active_constraints
    assert active, "a far target must saturate some speed limit"
    for label in active:
        assert label.startswith(("JointVelocityLimits", "JointPositionLimits"))
    saturated = np.flatnonzero(np.abs(np.abs(v[3:]) - np.pi / 2) < 1e-7) + 3
    for i in saturated:
        assert any(youbot.joint_names[i] in label for label in active)


@pytest.mark.parametrize("bad", [np.full(8, np.nan), np.r_[np.zeros(7), np.inf], np.zeros(7), np.zeros((8, 1)),
                                 "not a vector", None])
def test_bad_configuration_is_rejected(youbot, bad):
    controller, _ = make_controller(youbot)
    with pytest.raises(wbc.InvalidInputError):
        controller.step(bad)
    with pytest.raises(wbc.InvalidInputError):
        youbot.frame_pose(bad, "ee")


def test_unknown_frame_is_reported_with_a_suggestion(youbot):
    with pytest.raises(wbc.UnknownFrameError, match="did you mean"):
        youbot.frame_pose(youbot.neutral(), "e")
    with pytest.raises(wbc.UnknownFrameError):
        wbc.Controller(youbot, [wbc.FrameTask("gripper", 1.0, 1.0)])


def test_unknown_solver_lists_the_installed_ones(youbot):
    with pytest.raises(wbc.UnknownSolverError, match="daqp"):
        make_controller(youbot, solver="no_such_solver")


@pytest.mark.parametrize("dt", [0.0, -0.01, np.nan, np.inf])
def test_bad_dt_is_rejected(youbot, dt):
    with pytest.raises(wbc.InvalidInputError):
        make_controller(youbot, dt=dt)
    with pytest.raises(wbc.InvalidInputError):
        youbot.integrate(youbot.neutral(), np.zeros(8), dt)


def test_bad_targets_are_rejected():
    task = wbc.FrameTask("ee", 1.0, 1.0)
    pose = np.eye(4)
    for bad in (pose[:3], np.full((4, 4), np.nan), np.diag([2.0, 1.0, 1.0, 1.0]),
                np.diag([-1.0, 1.0, -1.0, 1.0]) @ np.diag([1, 1, -1, 1.0])):
        with pytest.raises(wbc.InvalidInputError):
            task.set_target(bad)
    with pytest.raises(wbc.InvalidInputError):
        task.set_target(pose, twist=[0, 0, 0, np.nan, 0, 0])
    with pytest.raises(wbc.InvalidInputError):
        wbc.FrameTask("ee", 1.0, 1.0, gain=1.5)
    with pytest.raises(wbc.InvalidInputError):
        wbc.FrameTask("ee", -1.0, 1.0)


def test_stepping_without_a_target_is_an_error(youbot):
    controller = wbc.Controller(youbot, [wbc.FrameTask("ee", 1.0, 1.0)])
    with pytest.raises(wbc.InvalidInputError, match="set_target"):
        controller.step(youbot.neutral())


def test_a_refused_first_target_leaves_the_task_without_one(youbot):
    """Whether a FrameTask has a target is written by the compiled setter with the target, only for
    a pose it accepts: a refused first target (on the fast path or with a twist) leaves the task
    waiting for one; a copy takes the state of its original."""
    task = wbc.FrameTask("ee", 1.0, 1.0)
    controller = wbc.Controller(youbot, [task], warm_up=False)
    q = youbot.neutral()
    pose = youbot.frame_pose(q, "ee")
    unready = copy.deepcopy(task)
    for bad_pose, twist in ((np.full((4, 4), np.nan), None), (np.diag([2.0, 1.0, 1.0, 1.0]), None),
                            (np.eye(3), None), (pose, [1.0, 2.0]), (np.diag([2.0, 1.0, 1.0, 1.0]), np.zeros(6))):
        with pytest.raises(wbc.InvalidInputError):
            task.set_target(bad_pose, twist)
        with pytest.raises(wbc.InvalidInputError, match="no target set"):
            controller.step(q)
    task.set_target(pose)
    ready = copy.deepcopy(task)
    controller.step(q)
    assert controller.last.success
    for copied, has_target in ((unready, False), (ready, True)):
        other = wbc.Controller(youbot, [copied], warm_up=False)
        if has_target:
            np.testing.assert_allclose(other.step(q), controller.step(q), atol=1e-12)
        else:
            with pytest.raises(wbc.InvalidInputError, match="no target set"):
                other.step(q)


def test_controller_rejects_empty_or_foreign_stacks(youbot):
    with pytest.raises(wbc.InvalidInputError):
        wbc.Controller(youbot, [])
    with pytest.raises(wbc.InvalidInputError):
        wbc.Controller(youbot, [object()])
    with pytest.raises(wbc.InvalidInputError):
        wbc.Controller(youbot, [wbc.PostureTask(1.0)], [object()])


def test_load_robot_errors(tmp_path):
    with pytest.raises(wbc.ModelError):
        wbc.load_robot("no_such_robot")
    broken = tmp_path / "broken.urdf"
    broken.write_text("<robot name='x'><joint name='j' type='revolute'/></robot>")
    with pytest.raises(wbc.ModelError):
        wbc.load_robot(broken)
    for not_a_name in (None, 3, ["youbot"]):  # (a raw TypeError of pathlib before)
        with pytest.raises(wbc.ModelError, match="takes a shipped model's name .*youbot.* or a file's path, got"):
            wbc.load_robot(not_a_name)


def test_any_urdf_path_loads_and_a_planar_base_is_detected(tmp_path):
    urdf = tmp_path / "copy.urdf"
    shutil.copy(wbc.model_path("youbot", "urdf"), urdf)  # no sidecar next to it
    robot = wbc.load_robot(urdf)
    assert robot.base.kind is wbc.BaseKind.PLANAR and robot.base.indices == (0, 1, 2)
    assert robot.base.max_linear_speed == 0.8 and robot.base.max_yaw_rate == 1.0


def test_fixed_base_urdf(tmp_path):
    urdf = tmp_path / "arm.urdf"
    urdf.write_text("""<robot name="arm">
      <link name="base"/><link name="l1"/><link name="tip"/>
      <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><axis xyz="0 0 1"/>
        <limit lower="-1" upper="1" effort="1" velocity="2"/></joint>
      <joint name="tip_joint" type="fixed"><parent link="l1"/><child link="tip"/><origin xyz="0.5 0 0"/></joint>
    </robot>""")
    robot = wbc.load_robot(urdf)
    assert robot.base.kind is wbc.BaseKind.FIXED and robot.nv == 1
    np.testing.assert_allclose(robot.frame_pose([np.pi / 2], "tip")[:3, 3], [0, 0.5, 0], atol=1e-15)
    with pytest.raises(wbc.InvalidInputError):
        wbc.Controller(robot, [wbc.BaseVelocityTask(1.0)])


def test_tasks_have_readable_repr():
    assert "FrameTask(frame='ee'" in repr(wbc.FrameTask("ee", 1.0, 0.5, gain=0.3))
    assert "PostureTask" in repr(wbc.PostureTask(1e-3))
    assert "BaseVelocityTask" in repr(wbc.BaseVelocityTask(1.0))
    assert repr(wbc.JointPositionLimits(0.3)) == "JointPositionLimits(gain=0.3)"
