"""A task's feed-forward is weighted with the cost of the tick, not the cost at ``set_target``."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

import wbc
from test_kernels import _python_only

DT = 0.01
Q = np.array([0.1, -0.2, 0.3, 0.2, 0.9, 0.8, 1.0, 0.4])
TWIST = np.array([0.05, 0.02, -0.01, 0.0, 0.03, 0.1])


def _target(robot: wbc.Robot) -> np.ndarray:
    target = robot.frame_pose(Q, "ee")
    target[:3, 3] += [0.02, -0.01, 0.03]
    target[:3, :3] = pin.exp3(np.array([0.02, -0.01, 0.03])) @ target[:3, :3]
    return target


def _rows(robot: wbc.Robot, target: np.ndarray, position_cost: float, orientation_cost: float,
          gain: float) -> tuple[np.ndarray, np.ndarray]:
    """(W J, W r) of a FrameTask written out: W = sqrt(cost), r = gain/dt e + xi."""
    pose, J = robot.frame_pose(Q, "ee"), robot.frame_jacobian(Q, "ee")
    error = np.r_[target[:3, 3] - pose[:3, 3], pin.log3(target[:3, :3] @ pose[:3, :3].T)]
    W = np.sqrt(np.r_[np.full(3, position_cost), np.full(3, orientation_cost)])
    return W[:, None] * J, W * (gain / DT * error + TWIST)


@pytest.mark.parametrize("compiled", [True, False])
def test_frame_task_costs_changed_after_set_target_weight_the_feedforward(youbot, compiled, monkeypatch):
    """set_target(pose, twist), then new costs: the command is the unconstrained optimum of
    ``|W J v - W r|^2 + d |v|^2`` with the new W on the whole of r (its feed-forward included)."""
    if not compiled:
        _python_only(monkeypatch)
    target = _target(youbot)
    task = wbc.FrameTask("ee", position_cost=1.0, orientation_cost=1.0, gain=0.5)
    task.set_target(target, TWIST)
    controller = wbc.Controller(youbot, [task], [], dt=DT, lm_damping=0.0, damping=1e-3)
    task.position_cost, task.orientation_cost = 9.0, 0.25
    v = controller.step(Q)
    A, b = _rows(youbot, target, 9.0, 0.25, 0.5)
    expected = np.linalg.solve(A.T @ A + 1e-3 * np.eye(youbot.nv), A.T @ b)
    np.testing.assert_allclose(v, expected, rtol=0, atol=1e-9 * (1 + np.abs(expected).max()))
