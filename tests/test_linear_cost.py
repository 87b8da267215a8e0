"""wbc.LinearCost (a user's c^T v in the objective) and wbc.ManipulabilityGradient (NEO's
climbing term), issue 25 §6 and §9: the command is the minimiser of the objective with the
term, checked against a formula written out here and against a second solver on the QP
written out here; the gradient against finite differences of Pinocchio's measure."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
import qpsolvers

import wbc

Q = np.array([0.1, -0.2, 0.3, 0.2, 0.9, -0.8, 1.0, 0.4])
C = np.array([2e-3, -1e-3, 4e-3, 0.0, 1e-3, -2e-3, 0.0, 3e-3])
DAMPING = 1e-3


@pytest.mark.parametrize("solver", ["daqp", "proxqp", "osqp"])
def test_posture_and_a_linear_cost_give_the_formula(youbot, solver):
    """PostureTask (cost w^2, gain g, target q*; the arm's coordinates) plus c^T v, no
    constraint: per arm coordinate min 1/2 (w^2 (v - g e / dt)^2 + d v^2) + c v  ->
    v = (w^2 g e / dt - c) / (w^2 + d); per base coordinate (no posture row) v = -c / d."""
    target = Q + np.linspace(-0.2, 0.2, 8)
    w2, gain, dt = 0.5, 0.3, 0.01
    controller = wbc.Controller(youbot, [wbc.PostureTask(w2, target=target, gain=gain), wbc.LinearCost(C)],
                                solver=solver, dt=dt, damping=DAMPING)
    expected = (w2 * gain * (target - Q) / dt - C) / (w2 + DAMPING)
    expected[:3] = -C[:3] / DAMPING
    np.testing.assert_allclose(controller.step(Q), expected, rtol=1e-5, atol=1e-7)


def _qp_written_out(robot, q, target, w2, gain, dt, c, vmax):
    """The same objective and velocity bounds, built here from the posture rows (the arm's)."""
    arm = np.r_[np.zeros(3), np.ones(robot.nv - 3)]
    e = target - q  # every youBot coordinate is a vector-space one
    H = np.diag(w2 * arm + DAMPING)
    g = -w2 * gain * arm * e / dt + c
    return H, g, -vmax, vmax


def test_with_active_limits_the_command_is_a_second_solvers_minimiser(youbot):
    """Heading 0: the platform's speed limits (base frame) are then a box in v too."""
    q = Q.copy()
    q[2] = 0.0
    target, w2, gain, dt = q + 0.3, 1e-3, 0.5, 0.01
    c = 50 * C  # large enough that several coordinates hit their velocity limits
    controller = wbc.Controller(youbot, [wbc.PostureTask(w2, target=target, gain=gain), wbc.LinearCost(c)],
                                [wbc.JointVelocityLimits()], dt=dt, damping=DAMPING)
    v = controller.step(q)
    H, g, lower, upper = _qp_written_out(youbot, q, target, w2, gain, dt, c, youbot.velocity_limit)
    reference = qpsolvers.solve_qp(H, g, lb=lower, ub=upper, solver="proxqp", eps_abs=1e-12)
    assert np.sum(np.isclose(np.abs(v), youbot.velocity_limit)) >= 2  # limits active
    np.testing.assert_allclose(v, reference, atol=1e-7)


def test_c_reassigned_between_ticks_acts_from_the_next(youbot):
    cost = wbc.LinearCost()  # zeros until assigned, sized by the controller
    controller = wbc.Controller(youbot, [wbc.PostureTask(1.0, target=Q), cost], damping=DAMPING)
    np.testing.assert_allclose(controller.step(Q), 0.0, atol=1e-12)
    cost.c = C
    np.testing.assert_allclose(controller.step(Q), -C / (np.r_[0, 0, 0, 1, 1, 1, 1, 1] + DAMPING), rtol=1e-6,
                               atol=1e-12)


def test_in_a_hierarchy_it_belongs_to_the_last_level(youbot):
    ee = wbc.PositionTask("ee", gain=0.5)
    ee.set_target(youbot.frame_pose(Q, "ee")[:3, 3] + [0.1, 0.0, 0.0])
    controller = wbc.Controller(youbot, [[ee], [wbc.PostureTask(1e-3, target=Q), wbc.LinearCost(C)]],
                                damping=DAMPING)
    flat_top = wbc.Controller(youbot, [[ee], [wbc.PostureTask(1e-3, target=Q)]], damping=DAMPING)
    v, without = controller.step(Q), flat_top.step(Q)
    J = youbot.frame_jacobian(Q, "ee")[:3]
    np.testing.assert_allclose(J @ v, J @ without, atol=1e-7)  # the top level is untouched
    assert C @ v < C @ without - 1e-6  # the linear term moved the command down its slope
    with pytest.raises(wbc.InvalidInputError, match=r"linear cost terms \['LinearCost'\] sit above the last "
                                                    r"priority level.*put them in the last level"):
        wbc.Controller(youbot, [[ee, wbc.LinearCost(C)], [wbc.PostureTask(1e-3)]])


def test_a_high_dof_controller_with_a_linear_cost_solves_it(tmp_path):
    """A 32-joint chain, where the lifted QP would be used: the formula still holds (the linear
    term is kept in the dense QP)."""
    from benchmarks.scaling import chain_urdf, initial_configuration

    path = tmp_path / "chain32.urdf"
    path.write_text(chain_urdf(32))
    chain, q = wbc.load_robot(path), initial_configuration(32)
    c = np.linspace(-1e-3, 1e-3, 32)
    controller = wbc.Controller(chain, [wbc.DampingTask(np.linspace(1e-2, 1.0, 32)), wbc.LinearCost(c)],
                                damping=DAMPING)
    np.testing.assert_allclose(controller.step(q), -c / (np.linspace(1e-2, 1.0, 32) + DAMPING), rtol=1e-6)


def test_bad_vectors_are_refused_by_name(youbot):
    with pytest.raises(wbc.InvalidInputError, match="c contains NaN"):
        wbc.LinearCost([0.0, np.nan])
    with pytest.raises(wbc.InvalidInputError, match="c must be a vector"):
        wbc.LinearCost(1.0)
    with pytest.raises(wbc.InvalidInputError, match="c must be a vector"):
        wbc.LinearCost(np.zeros((2, 8)))
    cost = wbc.LinearCost(np.zeros(3))
    with pytest.raises(wbc.InvalidInputError, match="c has 3 entries but robot 'youbot' has nv = 8"):
        wbc.Controller(youbot, [cost])
    cost = wbc.LinearCost(np.zeros(8))
    with pytest.raises(wbc.InvalidInputError, match="c contains NaN"):
        cost.c = np.full(8, np.inf)
    np.testing.assert_array_equal(cost.c, 0.0)  # kept


# ------------------------------------------------------------------ ManipulabilityGradient
def _arm_measure(robot, q, frame="ee", columns=slice(3, 8)):
    """sqrt(det(J J^T)) of the frame's world-aligned Jacobian, chain columns only (Pinocchio)."""
    model, data = robot.model, robot.model.createData()
    J = pin.computeFrameJacobian(model, data, q, model.getFrameId(frame), pin.LOCAL_WORLD_ALIGNED)[:, columns]
    return float(np.sqrt(np.linalg.det(J @ J.T)))


def test_the_gradient_is_minus_cost_grad_ln_m(youbot):
    """c = -cost d(ln m)/dv, against central differences of Pinocchio's arm measure (the arm's
    five joints: the 6x5 Jacobian, J^T J form -- m = sqrt(det(J^T J)))."""
    arm = ["arm_joint_1", "arm_joint_2", "arm_joint_3", "arm_joint_4", "arm_joint_5"]
    task = wbc.ManipulabilityGradient("ee", cost=0.7, joints=arm)
    data = task.bind(youbot)
    from wbc.model.kinematics import Kinematics

    kin = Kinematics(youbot)
    kin.update(Q)
    c = np.zeros(youbot.nv)
    data.compute_gradient(kin, c)

    def log_measure(q):
        model, pdata = youbot.model, youbot.model.createData()
        J = pin.computeFrameJacobian(model, pdata, q, model.getFrameId("ee"), pin.LOCAL_WORLD_ALIGNED)[:, 3:]
        return 0.5 * np.log(np.linalg.det(J.T @ J))

    h, numeric = 1e-6, np.zeros(youbot.nv)
    for i in range(youbot.nv):
        step = np.zeros(youbot.nv)
        step[i] = h
        numeric[i] = (log_measure(pin.integrate(youbot.model, Q, step))
                      - log_measure(pin.integrate(youbot.model, Q, -step))) / (2 * h)
    np.testing.assert_allclose(c, -0.7 * numeric, rtol=1e-5, atol=1e-7)  # central differences: O(h^2) + rounding


def test_climbing_raises_the_arm_measure_while_the_gripper_holds(youbot):
    """The gripper held in place (PositionTask) and the arm's measure climbed: it rises well
    above where it started; without the term it stays where it was."""
    arm = ["arm_joint_1", "arm_joint_2", "arm_joint_3", "arm_joint_4", "arm_joint_5"]
    start = np.array([0.0, 0.0, 0.0, 0.0, 0.3, -0.4, 0.2, 0.0])  # arm near-folded: low measure

    def run(extra):
        hold = wbc.PositionTask("ee", gain=0.5)
        hold.set_target(youbot.frame_pose(start, "ee")[:3, 3])
        controller = wbc.Controller(youbot, [hold, *extra], [wbc.JointPositionLimits(), wbc.JointVelocityLimits()])
        q = start.copy()
        for _ in range(300):
            q = youbot.integrate(q, controller.step(q), controller.dt)
        return q, np.linalg.norm(youbot.frame_pose(q, "ee")[:3, 3] - youbot.frame_pose(start, "ee")[:3, 3])

    q_climb, drift = run([wbc.ManipulabilityGradient("ee", cost=3e-4, rows="position", joints=arm)])
    q_plain, _ = run([])
    columns = slice(3, 8)
    m0, m_climb, m_plain = (_measure_position(youbot, q, columns) for q in (start, q_climb, q_plain))
    assert m_climb > 1.4 * m0 and abs(m_plain - m0) < 0.05 * m0  # measured: 1.56 m0
    # [m] the gripper held, up to the balance of the term's constant push and the hold's
    # feedback (~ cost |grad ln m| / (gain / dt)): 0.53 mm measured
    assert drift < 1e-3


def _measure_position(robot, q, columns):
    model, data = robot.model, robot.model.createData()
    J = pin.computeFrameJacobian(model, data, q, model.getFrameId("ee"), pin.LOCAL_WORLD_ALIGNED)[:3, columns]
    return float(np.sqrt(np.linalg.det(J @ J.T)))


# ------------------------------------------------------------------ LinearConstraint (the hard A v = b)
def test_a_linear_constraint_holds_exactly_and_moves_the_rest(youbot):
    """Two arm joints coupled with an offset (v_3 - v_4 = 0.05) while the gripper reaches: the
    command satisfies the rows to the solver's precision every tick, b and A changed between ticks."""
    couple = wbc.LinearConstraint([[0, 0, 0, 1, -1, 0, 0, 0]], b=[0.05])
    ee = wbc.PositionTask("ee", gain=0.3)
    ee.set_target(youbot.frame_pose(Q, "ee")[:3, 3] + [0.1, 0.05, 0.0])
    controller = wbc.Controller(youbot, [ee, wbc.PostureTask(1e-3)], [wbc.JointVelocityLimits(), couple])
    q = Q.copy()
    for k in range(60):
        if k == 30:
            couple.set_target([-0.02])
            couple.set_matrix([[0, 0, 0, 1, 0, -1, 0, 0]])
        v = controller.step(q)
        A, b = ([[0, 0, 0, 1, -1, 0, 0, 0]], 0.05) if k < 30 else ([[0, 0, 0, 1, 0, -1, 0, 0]], -0.02)
        np.testing.assert_allclose(np.asarray(A) @ v, [b], atol=1e-9)
        q = youbot.integrate(q, v, controller.dt)
    soft = wbc.Controller(youbot, [ee, wbc.PostureTask(1e-3)], [wbc.JointVelocityLimits()])
    assert abs(soft.step(q)[3] - soft.step(q)[5] + 0.02) > 1e-3  # without it the rows would not hold


def test_an_infeasible_linear_constraint_is_named_in_the_conflicts(youbot):
    """b beyond the velocity limits: the fallback answers within the limits and names the rows."""
    too_fast = wbc.LinearConstraint([[0, 0, 0, 1, 0, 0, 0, 0]], b=[50.0], name="too_fast")
    controller = wbc.Controller(youbot, [wbc.PostureTask(1e-3)], [wbc.JointVelocityLimits(), too_fast])
    v = controller.step(Q)
    assert not controller.last.success
    assert np.all(np.abs(v) <= youbot.velocity_limit + 1e-9)
    assert any("too_fast" in label for label in controller.last.conflicts)


def test_bad_linear_constraints_are_refused_by_name(youbot):
    with pytest.raises(wbc.InvalidInputError, match="A must be a matrix"):
        wbc.LinearConstraint([1.0, 2.0])
    with pytest.raises(wbc.InvalidInputError, match="A has 3 columns, robot 'youbot' has nv = 8"):
        wbc.Controller(youbot, [wbc.PostureTask(1e-3)], [wbc.LinearConstraint([[1.0, 0.0, 0.0]])])
    constraint = wbc.LinearConstraint([[0, 0, 0, 1, -1, 0, 0, 0]])
    with pytest.raises(wbc.InvalidInputError, match="b contains NaN"):
        constraint.set_target([np.nan])
    with pytest.raises(wbc.InvalidInputError, match="A must keep its shape"):
        constraint.set_matrix(np.zeros((2, 8)))
