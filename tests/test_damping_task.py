"""DampingTask: per-coordinate velocity costs, reassignable between ticks."""

from __future__ import annotations

import numpy as np
import pytest

import wbc
from test_look_at_task import rows
from wbc.qp import lifting

DT = 0.01
Q = np.array([0.1, -0.2, 0.3, 0.2, 0.9, -0.8, 1.0, 0.4])


def test_the_h_contribution_is_diag_cost(youbot):
    """(W J)^T (W J) = diag(cost) written out, base included by default; with joints, cost on those
    coordinates only (in the order named), zero elsewhere; the target is zero."""
    cost = np.array([4.0, 4.0, 2.0, 1.0, 1.0, 0.5, 0.5, 0.25])
    _, _, WJ, Wr = rows(youbot, Q, wbc.DampingTask(cost))
    np.testing.assert_allclose(WJ.T @ WJ, np.diag(cost), rtol=1e-15, atol=0)
    assert not Wr.any()
    _, _, WJ, Wr = rows(youbot, Q, wbc.DampingTask([3.0, 5.0], joints=["arm_joint_3", "base_x"]))
    expected = np.zeros((8, 8))
    expected[5, 5], expected[0, 0] = 3.0, 5.0
    np.testing.assert_allclose(WJ.T @ WJ, expected, rtol=1e-15, atol=0)
    _, _, WJ, _ = rows(youbot, Q, wbc.DampingTask(2.0))
    np.testing.assert_allclose(WJ.T @ WJ, 2.0 * np.eye(8), rtol=1e-15, atol=0)


def test_the_controllers_cost_is_the_written_out_least_squares_and_follows_reassigned_costs(youbot):
    """With a position task and no active limit, the command is the minimiser written out,
    ``(J^T w J + diag(cost) + damping I)^-1 J^T w r``, before and after the costs change (platform
    a hundred times costlier than the arm: it then moves less, the arm more)."""
    reach = wbc.PositionTask("ee", cost=1.0, gain=0.1)
    target = wbc.load_robot("youbot").frame_pose(Q, "ee")[:3, 3] + [0.05, 0.03, -0.02]
    reach.set_target(target)
    damping = wbc.DampingTask(1e-2)
    controller = wbc.Controller(youbot, [reach, damping], dt=DT, damping=1e-4, lm_damping=0.0)
    J = youbot.frame_jacobian(Q, "ee")[:3]
    r = 0.1 / DT * (target - youbot.frame_pose(Q, "ee")[:3, 3])
    commands = []
    for cost in (np.full(8, 1e-2), np.r_[np.full(3, 1.0), np.full(5, 1e-2)]):
        damping.cost = cost
        v = controller.step(Q)
        expected = np.linalg.solve(J.T @ J + np.diag(cost) + 1e-4 * np.eye(8), J.T @ r)
        np.testing.assert_allclose(v, expected, rtol=1e-7, atol=1e-9)
        commands.append(v)
    assert np.linalg.norm(commands[1][:3]) < 0.5 * np.linalg.norm(commands[0][:3])
    assert np.linalg.norm(commands[1][3:]) > np.linalg.norm(commands[0][3:])


def test_high_dof_lifted_qps_keep_the_rows_diagonal_and_agree_with_the_dense_ones(tmp_path, monkeypatch):
    """On a 32-joint chain the damping rows (diagonal_rows) take no auxiliary variable of the lifted
    QP (k = 6: the frame task's rows only), and the lifted controller commands what a dense one does,
    before and after the costs change."""
    from benchmarks.scaling import chain_urdf, initial_configuration

    path = tmp_path / "chain32.urdf"
    path.write_text(chain_urdf(32))
    chain, q = wbc.load_robot(path), initial_configuration(32)
    controllers, tasks = {}, {}
    for mode, minimum in (("lifted", lifting.LIFT_MIN_DOF), ("dense", 10**6)):
        monkeypatch.setattr(lifting, "LIFT_MIN_DOF", minimum)
        ee = wbc.FrameTask("ee", 1.0, 0.5, gain=0.5)
        target = chain.frame_pose(q, "ee")
        target[:3, 3] += [0.2, -0.1, 0.1]
        ee.set_target(target)
        tasks[mode] = wbc.DampingTask(np.linspace(1e-3, 1e-1, 32))
        controllers[mode] = wbc.Controller(chain, [ee, tasks[mode]], [wbc.JointVelocityLimits()])
    assert controllers["lifted"]._lifted is not None and controllers["lifted"]._lifted.k == 6
    assert controllers["dense"]._lifted is None
    for tick in range(20):
        if tick == 10:
            for task in tasks.values():
                task.cost = np.linspace(1.0, 1e-3, 32)
        v, reference = controllers["lifted"].step(q), controllers["dense"].step(q)
        np.testing.assert_allclose(v, reference, rtol=0, atol=1e-7 * (1 + np.abs(reference).max()))
        q = chain.integrate(q, v, 0.01)


def test_bad_input_is_refused_by_name(youbot):
    with pytest.raises(wbc.InvalidInputError, match="write joints=\\['base_x'\\]"):
        wbc.DampingTask(1.0, joints="base_x")
    with pytest.raises(wbc.InvalidInputError, match="joints is empty"):
        wbc.DampingTask(1.0, joints=[])
    with pytest.raises(wbc.InvalidInputError, match="cost must be >= 0"):
        wbc.DampingTask([1.0, -1.0])
    with pytest.raises(wbc.InvalidInputError, match="cost contains NaN"):
        wbc.DampingTask(np.nan)
    with pytest.raises(wbc.InvalidInputError, match="cost is empty"):
        wbc.DampingTask([])
    with pytest.raises(wbc.ModelError, match="'arm_joint_9' is not a joint.*did you mean"):
        wbc.Controller(youbot, [wbc.DampingTask(1.0, joints=["arm_joint_9"])])
    with pytest.raises(wbc.InvalidInputError, match="named twice"):
        wbc.Controller(youbot, [wbc.DampingTask(1.0, joints=["base_x", "base_x"])])
    with pytest.raises(wbc.InvalidInputError, match="3 costs, but robot 'youbot' has 8 velocity coordinates"):
        wbc.Controller(youbot, [wbc.DampingTask([1.0, 2.0, 3.0])])
    task = wbc.DampingTask(1.0)
    wbc.Controller(youbot, [task])
    np.testing.assert_array_equal(task.cost, np.ones(8))  # sized by the robot
    with pytest.raises(wbc.InvalidInputError, match="cost must have shape \\(8,\\)"):
        task.cost = [1.0, 2.0]
    with pytest.raises(wbc.InvalidInputError, match="2 velocity coordinates.*create another DampingTask"):
        wbc.Controller(wbc.load_robot("deluca_mm"), [wbc.DampingTask(1.0, joints=["base_x", "base_y"]),
                                                     wbc.DampingTask([1.0, 2.0, 3.0], joints=["base_x", "base_y"])],
                       [wbc.NonholonomicBase()])
    np.testing.assert_array_equal(task.cost, np.ones(8))  # kept
    task.cost = 3.0
    assert repr(task) == "DampingTask(cost=[3.0, 3.0, 3.0, 3.0, 3.0, 3.0, 3.0, 3.0], joints=None)"
