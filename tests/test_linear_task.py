"""LinearTask: a soft linear equation A v = b on the joint velocity."""

from __future__ import annotations

import numpy as np
import pytest

import wbc
from test_look_at_task import rows

DT = 0.01
Q = np.array([0.1, -0.2, 0.3, 0.2, 0.9, -0.8, 1.0, 0.4])
A = np.array([[0.0, 0.0, 0.0, 1.0, -1.0, 0.0, 0.0, 0.0], [0.5, 0.0, 0.2, 0.0, 0.0, 1.0, 0.0, 0.0]])


def test_rows_and_h_contribution(youbot):
    """W J = W A, W r = W b, so H gets A^T diag(cost) A and c gets -A^T diag(cost) b (written out)."""
    cost, b = np.array([4.0, 0.25]), np.array([0.1, -0.2])
    _, J, WJ, Wr = rows(youbot, Q, wbc.LinearTask(A, b, cost))
    np.testing.assert_array_equal(J, A)
    np.testing.assert_allclose(WJ.T @ WJ, A.T @ np.diag(cost) @ A, rtol=1e-15, atol=0)
    np.testing.assert_allclose(WJ.T @ Wr, A.T @ (cost * b), rtol=1e-15, atol=0)


def test_the_command_is_the_written_out_least_squares_and_follows_new_rows(youbot):
    """With a position task (no active limit, no LM damping): v = (J^T J + A^T C A + damping I)^-1
    (J^T r + A^T C b), for the first rows and after set_target / set_matrix / a cost change; the
    reported error is the residual |A v - b|."""
    reach = wbc.PositionTask("ee", cost=1.0, gain=0.1)
    target = youbot.frame_pose(Q, "ee")[:3, 3] + [0.05, 0.03, -0.02]
    reach.set_target(target)
    task = wbc.LinearTask(A, [0.1, -0.2], cost=[1.0, 2.0])
    controller = wbc.Controller(youbot, [reach, task], dt=DT, damping=1e-4, lm_damping=0.0)
    J = youbot.frame_jacobian(Q, "ee")[:3]
    r = 0.1 / DT * (target - youbot.frame_pose(Q, "ee")[:3, 3])
    matrix, b, cost = A.copy(), np.array([0.1, -0.2]), np.array([1.0, 2.0])
    for change in (None, "target", "matrix", "cost"):
        if change == "target":
            b = np.array([-0.3, 0.05])
            task.set_target(b)
        elif change == "matrix":
            matrix = np.array([[1.0, -1.0, 0, 0, 0, 0, 0, 0], [0, 0, 0, 0, 0, 0, 1.0, 1.0]])
            task.set_matrix(matrix)
        elif change == "cost":
            cost = np.array([10.0, 0.1])
            task.cost = cost
        v = controller.step(Q)
        expected = np.linalg.solve(J.T @ J + matrix.T @ np.diag(cost) @ matrix + 1e-4 * np.eye(8),
                                   J.T @ r + matrix.T @ (cost * b))
        np.testing.assert_allclose(v, expected, rtol=1e-7, atol=1e-9)
        assert controller.last.task_errors[task.name] == pytest.approx(np.linalg.norm(matrix @ v - b), rel=1e-12)


def test_a_coupling_is_held_in_closed_loop(youbot):
    """``v_3 - v_4 = 0`` with a high cost: arm joints 1 and 2 keep their difference while the gripper
    moves 10 cm."""
    q = Q.copy()
    reach = wbc.PositionTask("ee", cost=1.0, gain=0.1)
    reach.set_target(youbot.frame_pose(q, "ee")[:3, 3] + [0.1, 0.0, 0.05])
    coupling = wbc.LinearTask([[0, 0, 0, 1, -1, 0, 0, 0]], cost=1e4)
    controller = wbc.Controller(youbot, [reach, coupling], [wbc.JointPositionLimits(), wbc.JointVelocityLimits()],
                                dt=DT)
    for _ in range(200):
        q = youbot.integrate(q, controller.step(q), DT)
    assert abs((q[3] - q[4]) - (Q[3] - Q[4])) < 1e-3
    assert np.linalg.norm(q - Q) > 0.1


def test_bad_input_is_refused_by_name(youbot):
    with pytest.raises(wbc.InvalidInputError, match="A must be a matrix"):
        wbc.LinearTask([1.0, 2.0])
    with pytest.raises(wbc.InvalidInputError, match="rows have different lengths"):
        wbc.LinearTask([[1.0, 2.0], [3.0]])
    with pytest.raises(wbc.InvalidInputError, match="A contains NaN"):
        wbc.LinearTask([[np.nan] * 8])
    with pytest.raises(wbc.InvalidInputError, match="b must have shape \\(2,\\)"):
        wbc.LinearTask(A, b=[1.0])
    with pytest.raises(wbc.InvalidInputError, match="A has 3 columns, robot 'youbot' has nv = 8"):
        wbc.Controller(youbot, [wbc.LinearTask([[1.0, 0.0, 0.0]])])
    task = wbc.LinearTask(A)
    with pytest.raises(wbc.InvalidInputError, match="A must keep its shape \\(2, 8\\)"):
        task.set_matrix(A[:1])
    with pytest.raises(wbc.InvalidInputError, match="b contains NaN"):
        task.set_target([np.nan, 0.0])
    np.testing.assert_array_equal(task.matrix, A)
    np.testing.assert_array_equal(task.target, [0.0, 0.0])  # kept
    with pytest.raises(wbc.InvalidInputError, match="cost must be >= 0"):
        task.cost = [-1.0, 1.0]
    assert repr(wbc.LinearTask([[1, 2]], [3])) == "LinearTask(A=[[1.0, 2.0]], b=[3.0], cost=[1.0])"
