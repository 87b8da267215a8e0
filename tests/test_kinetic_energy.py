"""KineticEnergyRegularization: the QP's H gets cost M(q), M from Pinocchio's CRBA."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

import wbc
from conftest import random_youbot_configurations
from test_look_at_task import rows

DT = 0.01


def mass_matrix(robot: wbc.Robot, q: np.ndarray) -> np.ndarray:
    """M(q) from Pinocchio's CRBA, symmetrised from its upper triangle."""
    upper = np.triu(pin.crba(robot.model, robot.model.createData(), q))
    return upper + np.triu(upper, 1).T


def test_the_h_contribution_is_cost_times_the_mass_matrix(youbot, rng):
    """(W J)^T (W J) = cost M(q) at random configurations, J upper triangular, the target zero."""
    task = wbc.KineticEnergyRegularization(0.3)
    for q in random_youbot_configurations(rng, 6):
        _, J, WJ, Wr = rows(youbot, q, task)
        M = mass_matrix(youbot, q)
        np.testing.assert_allclose(WJ.T @ WJ, 0.3 * M, rtol=0, atol=1e-12 * np.abs(M).max())
        np.testing.assert_array_equal(np.tril(J, -1), 0.0)
        assert not Wr.any()


def test_the_command_is_the_mass_weighted_least_squares(youbot):
    """With a position task and no active limit, v = (J^T J + cost M + damping I)^-1 J^T r written out,
    before and after the cost changes; heavier coordinates (the platform) move less than under a
    plain damping of the same trace."""
    q = np.array([0.1, -0.2, 0.3, 0.2, 0.9, -0.8, 1.0, 0.4])
    reach = wbc.PositionTask("ee", cost=1.0, gain=0.1)
    target = youbot.frame_pose(q, "ee")[:3, 3] + [0.05, 0.03, -0.02]
    reach.set_target(target)
    energy = wbc.KineticEnergyRegularization(1e-3)
    controller = wbc.Controller(youbot, [reach, energy], dt=DT, damping=1e-4, lm_damping=0.0)
    J = youbot.frame_jacobian(q, "ee")[:3]
    r = 0.1 / DT * (target - youbot.frame_pose(q, "ee")[:3, 3])
    M = mass_matrix(youbot, q)
    for cost in (1e-3, 1e-2):
        energy.cost = cost
        v = controller.step(q)
        expected = np.linalg.solve(J.T @ J + cost * M + 1e-4 * np.eye(8), J.T @ r)
        np.testing.assert_allclose(v, expected, rtol=1e-7, atol=1e-9)
    plain = np.linalg.solve(J.T @ J + 1e-2 * np.trace(M) / 8 * np.eye(8) + 1e-4 * np.eye(8), J.T @ r)
    assert np.linalg.norm(v[:3]) / np.linalg.norm(v) < np.linalg.norm(plain[:3]) / np.linalg.norm(plain)


def test_a_robot_without_inertias_is_refused_naming_the_fix():
    """The PUMA 560 model has no <inertial> elements: its mass matrix is zero."""
    puma = wbc.load_robot("puma560")
    with pytest.raises(wbc.ModelError, match="not positive definite.*Add <inertial> elements.*DampingTask"):
        wbc.Controller(puma, [wbc.KineticEnergyRegularization(1.0)])


def test_bad_input_is_refused_by_name(youbot):
    with pytest.raises(wbc.InvalidInputError, match="cost must be finite and >= 0"):
        wbc.KineticEnergyRegularization(-1.0)
    task = wbc.KineticEnergyRegularization(0.5)
    wbc.Controller(youbot, [task])
    with pytest.raises(wbc.InvalidInputError, match="cost must be a number"):
        task.cost = [1.0, 2.0]
    with pytest.raises(wbc.ModelError, match="nv = 6: create another KineticEnergyRegularization"):
        wbc.Controller(wbc.load_robot("deluca_mm"), [task], [wbc.NonholonomicBase()])
    assert task.cost == 0.5 and repr(task) == "KineticEnergyRegularization(cost=0.5)"
