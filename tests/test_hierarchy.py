"""Strict task priorities (wbc.control.hierarchy) against references written here, independently of
wbc's kernels: the task rows from Pinocchio's Jacobians and the task definitions of the README,
the classical null-space projection for equality-only stacks (task-1 pseudo-inverse + projected
task 2), and with active inequalities a brute-force cascade solved by SciPy and Clarabel."""

import numpy as np
import pinocchio as pin
import pytest
import qpsolvers
import scipy.linalg
import scipy.sparse
from scipy.optimize import lsq_linear

import wbc
from conftest import TASKS
from wbc.app.closed_loop import run
from wbc.app.scenario import load_scenario
from wbc.tasks.task import TaskData

DT = 0.01
ARM = slice(3, 8)  # the youBot's arm coordinates (the base is x, y, theta)


# ---------------------------------------------------------------- reference task rows
def frame_rows(robot, q, frame, target, position_cost, orientation_cost, gain):
    """``W J``, ``W r`` of a FrameTask: ``r = gain e / dt``, ``e = (p* - p, log3(R* R^T))``."""
    pose = robot.frame_pose(q, frame)
    error = np.r_[target[:3, 3] - pose[:3, 3], pin.log3(target[:3, :3] @ pose[:3, :3].T)]
    weights = np.sqrt(np.r_[np.full(3, position_cost), np.full(3, orientation_cost)])
    return weights[:, None] * robot.frame_jacobian(q, frame), weights * gain * error / DT


def position_rows(robot, q, frame, target, cost, gain):
    """``W J``, ``W r`` of a PositionTask (the linear rows of the frame Jacobian)."""
    error = target - robot.frame_pose(q, frame)[:3, 3]
    weight = np.sqrt(cost)
    return weight * robot.frame_jacobian(q, frame)[:3], weight * gain * error / DT


def posture_rows(q, target, cost, gain, joints):
    """``W J``, ``W r`` of a PostureTask on the coordinates ``joints`` (1-DOF joints, nq = nv)."""
    selection = np.eye(q.size)[joints]
    weight = np.sqrt(cost)
    return weight * selection, weight * gain * (target - q)[joints] / DT


def null_space_projection(levels, damping):
    """The classical solution of an equality-only hierarchy: level 1 by its pseudo-inverse, each
    next level by the pseudo-inverse of its rows projected on the null space of the levels above
    (damped least squares at the last level, ``damping |v|^2``)."""
    def pinv(matrix):  # the pseudo-inverse, rank decided at 1e-9 of the largest singular value
        return np.linalg.pinv(matrix, rcond=1e-9)

    (A, b), rest = levels[0], levels[1:]
    v = pinv(A) @ b
    null = np.eye(A.shape[1]) - pinv(A) @ A
    for k, (A, b) in enumerate(rest):
        projected = A @ null
        if k == len(rest) - 1 and damping > 0:  # min |A (v + N z) - b|^2 + damping |v + N z|^2, v _|_ N
            basis = scipy.linalg.null_space(np.vstack([a for a, _ in levels[:-1]]))
            z = np.linalg.solve(basis.T @ A.T @ A @ basis + damping * np.eye(basis.shape[1]),
                                basis.T @ A.T @ (b - A @ v))
            return v + basis @ z
        v = v + pinv(projected) @ (b - A @ v)
        null = null - pinv(projected) @ projected
    return v


def youbot_pose_target(robot, q, rng, reach=0.05):
    """The gripper's pose at q moved by up to ``reach`` [m] and turned by up to 2 ``reach`` [rad]."""
    target = robot.frame_pose(q, "ee").copy()
    target[:3, 3] += rng.uniform(-reach, reach, 3)
    target[:3, :3] = target[:3, :3] @ pin.exp3(rng.uniform(-2 * reach, 2 * reach, 3))
    return target


# ----------------------------------------------------------------------------- the API
def test_a_flat_list_is_one_weighted_level_unchanged(youbot):
    """A flat list and a single level are today's controller: no hierarchy, the same commands."""
    q = np.array([0, 0, 0, 0, 0.5, 1.0, 1.2, 0.0])
    ee = wbc.FrameTask("ee", gain=0.5)
    ee.set_target(youbot_pose_target(youbot, q, np.random.default_rng(1)))
    posture = wbc.PostureTask(1e-3, gain=0.05)
    flat = wbc.Controller(youbot, [ee, posture], [wbc.JointVelocityLimits()])
    single = wbc.Controller(youbot, [[ee, posture]], [wbc.JointVelocityLimits()])
    assert flat._hierarchy is None and single._hierarchy is None
    assert flat.levels == single.levels == [[ee, posture]]
    for _ in range(20):
        v = flat.step(q)
        assert np.array_equal(v, single.step(q))
        q = youbot.integrate(q, v, DT)
    assert len(flat.last.level_errors) == 1
    assert flat.last.level_errors == flat.last.level_optima


@pytest.mark.parametrize("tasks, message", [
    (lambda ee, posture: [[ee], []], "level 1 is empty"),
    (lambda ee, posture: [[ee], posture], "mixes tasks and lists"),
    (lambda ee, posture: [ee, [posture]], "mixes tasks and lists"),
    (lambda ee, posture: [[ee], [[posture]]], "level 1: not a Task"),
    (lambda ee, posture: [[ee], ["posture"]], "level 1: not a Task"),
    (lambda ee, posture: [[ee, posture], [ee]], "appears in levels 0 and 1"),
    (lambda ee, posture: [[ee, ee], [posture]], "appears twice in level 0"),
    (lambda ee, posture: [[], [ee]], "level 0 is empty"),
])
def test_malformed_levels_are_refused_naming_the_fix(youbot, tasks, message):
    ee, posture = wbc.FrameTask("ee"), wbc.PostureTask(1.0)
    with pytest.raises(wbc.InvalidInputError, match=message):
        wbc.Controller(youbot, tasks(ee, posture))


def test_levels_and_repr(youbot):
    ee, posture, base = wbc.FrameTask("ee"), wbc.PostureTask(1.0), wbc.BaseVelocityTask(1.0)
    controller = wbc.Controller(youbot, ([ee], (posture, base)))
    assert controller.levels == [[ee], [posture, base]]
    assert controller.tasks == [ee, posture, base]
    assert "tasks=[[FrameTask" in repr(controller)


# ------------------------------------------------------------- equality-only references
#: backends that solve every level of the tests below as it is (exact active-set methods); the
#: others may hand a level to the elastic fallback (README, "Strict priorities"), whose command
#: is checked all the same
EXACT = ("daqp", "quadprog")


@pytest.mark.parametrize("solver", wbc.available_solvers())
@pytest.mark.parametrize("damping", [0.0, 1e-3])
def test_two_levels_match_the_null_space_projection(youbot, rng, solver, damping):
    """Pose over posture, speed limits inactive: the classical null-space solution (the damping at
    the last level only); the pose task is met up to the band, the posture as well as its null
    space allows."""
    for _ in range(5):
        q = np.r_[rng.uniform(-1, 1, 3), rng.uniform(-1, 1, 5) * 0.8 + np.array([0, 0.5, 1.0, 1.2, 0])]
        target = youbot_pose_target(youbot, q, rng, reach=0.01)
        posture_target = q + rng.uniform(-0.2, 0.2, 8)
        ee = wbc.FrameTask("ee", position_cost=1.0, orientation_cost=0.5, gain=0.03)
        ee.set_target(target)
        posture = wbc.PostureTask(0.3, target=posture_target, gain=0.01)
        controller = wbc.Controller(youbot, [[ee], [posture]], [wbc.JointVelocityLimits()], solver=solver,
                                    damping=damping, lm_damping=0.0)  # the classical hierarchy
        v = controller.step(q)
        assert controller.last.success or solver not in EXACT, controller.last.status
        A1, b1 = frame_rows(youbot, q, "ee", target, 1.0, 0.5, 0.03)
        A2, b2 = posture_rows(q, posture_target, 0.3, 0.01, ARM)
        reference = null_space_projection([(A1, b1), (A2, b2)], damping)
        assert np.all(np.abs(reference) < 0.9 * youbot.velocity_limit), "the limits must be inactive"
        np.testing.assert_allclose(v, reference, rtol=0, atol=1e-6)
        # level 0 is met (its targets are reachable) up to the band of wbc.control.hierarchy (plus the
        # regularisation floor of its QP, 1e-10 of its largest curvature: < 1e-7 relative here)
        slack = 2 * wbc.control.hierarchy.BAND * np.linalg.norm(A1, axis=1) * max(1.0, np.abs(v).max())
        slack += 1e-7 * np.abs(b1).max()
        assert np.all(np.abs(A1 @ v - b1) <= slack)
        errors, optima = controller.last.level_errors, controller.last.level_optima
        assert errors[0] <= np.linalg.norm(slack) and optima[0] <= np.linalg.norm(slack)
        # the band is all level 1 may gain over the exact hierarchy
        assert errors[1] == pytest.approx(np.linalg.norm(A2 @ reference - b2), rel=1e-5)


def test_three_levels_match_the_recursive_projection(youbot, rng):
    """Position over orientation over posture (a FrameTask with position_cost 0 has zero rows)."""
    for _ in range(5):
        q = np.r_[rng.uniform(-1, 1, 3), np.array([0.2, 0.5, 1.0, 1.2, 0.3]) + rng.uniform(-0.3, 0.3, 5)]
        target = youbot_pose_target(youbot, q, rng)
        posture_target = q + rng.uniform(-0.5, 0.5, 8)
        position = wbc.PositionTask("ee", cost=1.0, gain=0.3)
        position.set_target(target[:3, 3])
        orientation = wbc.FrameTask("ee", position_cost=0.0, orientation_cost=1.0, gain=0.3)
        orientation.set_target(target)
        posture = wbc.PostureTask(1.0, target=posture_target, gain=0.1)
        controller = wbc.Controller(youbot, [[position], [orientation], [posture]], damping=0.0, lm_damping=0.0)
        v = controller.step(q)
        assert controller.last.success
        rows, targets = frame_rows(youbot, q, "ee", target, 0.0, 1.0, 0.3)
        levels = [position_rows(youbot, q, "ee", target[:3, 3], 1.0, 0.3), (rows[3:], targets[3:]),
                  posture_rows(q, posture_target, 1.0, 0.1, ARM)]
        reference = null_space_projection(levels, 0.0)
        np.testing.assert_allclose(v, reference, rtol=0, atol=1e-6 * max(1.0, np.abs(reference).max()))
        assert len(controller.last.level_errors) == 3


# ------------------------------------------------------ with active inequalities
def brute_force_cascade(levels, lower, upper, damping):
    """Lexicographic least squares under bounds, written out: level 0 by SciPy's bounded least
    squares, each next level by Clarabel (an interior-point method) with the task values of the
    levels above as equality rows (damping at the last level); the optimal task values ``y_k``."""
    A, b = levels[0]
    first = lsq_linear(A, b, bounds=(lower, upper), tol=1e-14, lsmr_tol="auto", max_iter=10_000)
    fixed, values = [A], [A @ first.x]
    v = first.x
    for k, (A, b) in enumerate(levels[1:], start=1):
        reg = damping if k == len(levels) - 1 else 1e-12
        rows, targets = np.vstack(fixed), np.concatenate(values)
        problem = qpsolvers.Problem(scipy.sparse.csc_matrix(A.T @ A + reg * np.eye(A.shape[1])), -A.T @ b, None, None,
                                    scipy.sparse.csc_matrix(rows), targets, lower, upper)
        solution = qpsolvers.solve_problem(problem, solver="clarabel", tol_gap_abs=1e-12, tol_gap_rel=1e-12,
                                           tol_feas=1e-12)
        assert solution.found
        v = solution.x
        fixed.append(A)
        values.append(A @ v)
    return v, values


def _puma_wrist_draw(robot: wbc.Robot, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, wbc.PositionTask]:
    """(q, goal, wrist): a PUMA configuration within 1 rad of (0, -0.5, 0.5, 0, 0.8, 0), a wrist-centre goal up to
    0.3 m away per axis, and the wrist-centre PositionTask (cost 1, gain 0.5) aiming at it."""
    q = rng.uniform(-1.0, 1.0, 6) + np.array([0, -0.5, 0.5, 0, 0.8, 0])
    goal = robot.frame_pose(q, "wrist_center")[:3, 3] + rng.uniform(-0.3, 0.3, 3)
    wrist = wbc.PositionTask("wrist_center", cost=1.0, gain=0.5)
    wrist.set_target(goal)
    return q, goal, wrist


@pytest.mark.parametrize("solver", wbc.available_solvers())
def test_a_level_infeasible_alone_takes_its_least_squares_optimum(solver):
    """PUMA 560: the wrist centre is asked to move faster than the joint speed limits allow
    (level 0 alone is infeasible: it takes its bounded least-squares optimum, joints at their
    limits); the posture (level 1) still uses what is left. Against the brute-force cascade."""
    robot = wbc.load_robot("puma560")
    rng = np.random.default_rng(7)
    checked = 0
    for _ in range(6):
        q, goal, wrist = _puma_wrist_draw(robot, rng)
        posture_target = q + rng.uniform(-1, 1, 6)
        posture = wbc.PostureTask(1.0, target=posture_target, gain=0.005)
        controller = wbc.Controller(robot, [[wrist], [posture]], [wbc.JointVelocityLimits()], solver=solver,
                                    lm_damping=0.0)  # the exact lexicographic optimum
        v = controller.step(q)
        A1, b1 = position_rows(robot, q, "wrist_center", goal, 1.0, 0.5)
        A2, b2 = posture_rows(q, posture_target, 1.0, 0.005, slice(0, 6))
        limit = robot.velocity_limit
        reference, values = brute_force_cascade([(A1, b1), (A2, b2)], -limit, limit, controller.damping)
        at_limits = np.isclose(np.abs(reference), limit, atol=1e-9)
        assert at_limits.any() and not at_limits.all(), "the test needs active bounds and freedom for level 1"
        checked += np.linalg.norm(A1 @ reference - b1) > 1e-3  # level 0 not reached: infeasible alone
        np.testing.assert_allclose(v, reference, rtol=0, atol=1e-6)
        assert np.all(np.abs(v) <= limit * (1 + 1e-9))
        optimum = np.linalg.norm(values[0] - b1)
        assert controller.last.level_errors[0] == pytest.approx(optimum, rel=1e-7, abs=1e-9)
        assert controller.last.success or solver not in EXACT, controller.last.status
    assert checked >= 3, "most draws must make level 0 infeasible alone"


def test_four_levels_under_active_bounds_match_the_brute_force_cascade():
    """PUMA 560, four levels in the tick program (native DAQP): the wrist centre asked faster
    than the joint speed limits allow, then postures of joints 1-2, of joint 3 and of every
    joint (their rows pin v at the last level). Levels below the second get the controller's
    limits and the bands of the levels above copied from the level above them
    (Hierarchy._add_level_copy); against the brute-force cascade written out."""
    robot = wbc.load_robot("puma560")
    rng = np.random.default_rng(11)
    solved = 0
    for _ in range(6):
        q, goal, wrist = _puma_wrist_draw(robot, rng)
        targets = [q + rng.uniform(-1, 1, 6) for _ in range(3)]
        joints = [["joint_1", "joint_2"], ["joint_3"], None]
        postures = [wbc.PostureTask(1.0, target=target, gain=0.01, joints=names)
                    for target, names in zip(targets, joints, strict=True)]
        controller = wbc.Controller(robot, [[wrist], *[[posture] for posture in postures]],
                                    [wbc.JointVelocityLimits()], lm_damping=0.0)
        assert controller._hierarchy.in_program
        v = controller.step(q)
        levels = [position_rows(robot, q, "wrist_center", goal, 1.0, 0.5)]
        levels += [posture_rows(q, target, 1.0, 0.01, index) for target, index
                   in zip(targets, [slice(0, 2), slice(2, 3), slice(0, 6)], strict=True)]
        limit = robot.velocity_limit
        reference, _ = brute_force_cascade(levels, -limit, limit, controller.damping)
        assert np.isclose(np.abs(reference), limit, atol=1e-9).any(), "the test needs active bounds"
        np.testing.assert_allclose(v, reference, rtol=0, atol=1e-6)
        assert np.all(np.abs(v) <= limit * (1 + 1e-6))  # (DAQP's primal tolerance in the levels, main's too)
        solved += controller.last.success
    assert solved >= 4, "most ticks answered by the cascade itself, not the fallback"


# ------------------------------------------------------------ mobile bases
def deluca_setup(rng):
    robot = wbc.load_robot("deluca_mm")
    q = np.r_[rng.uniform(-1, 1, 2), rng.uniform(-np.pi, np.pi), np.array([0.3, 0.5, -1.0]) + rng.uniform(-.3, .3, 3)]
    goal = robot.frame_pose(q, "wrist_center")[:3, 3] + rng.uniform(-0.2, 0.2, 3)
    wrist = wbc.PositionTask("wrist_center", cost=1.0, gain=0.1)
    wrist.set_target(goal)
    posture_target = q + rng.uniform(-0.5, 0.5, 6)
    posture = wbc.PostureTask(1.0, target=posture_target, gain=0.1)
    return robot, q, wrist, goal, posture, posture_target


def test_nonholonomic_base_equality_and_reduced_forms_match_the_projection_over_the_inputs():
    """De Luca's synchro drive: level 0 the wrist centre, level 1 the posture. The equality form
    (no-slip rows) and the reduced form (v = S u) give the null-space solution over the inputs u."""
    rng = np.random.default_rng(3)
    for _ in range(5):
        robot, q, wrist, goal, posture, posture_target = deluca_setup(rng)
        S = robot.input_map(q)
        A1, b1 = position_rows(robot, q, "wrist_center", goal, 1.0, 0.1)
        A2, b2 = posture_rows(q, posture_target, 1.0, 0.1, slice(3, 6))
        damping = 1e-3
        # over u: level 0 by its pseudo-inverse; level 1 on {u : A1 S u = y1}, damping |S u|^2
        u1 = np.linalg.pinv(A1 @ S) @ b1
        basis = scipy.linalg.null_space(A1 @ S)
        stacked = np.vstack([A2 @ S @ basis, np.sqrt(damping) * S @ basis])
        z = np.linalg.lstsq(stacked, np.r_[b2 - A2 @ S @ u1, -np.sqrt(damping) * S @ u1], rcond=None)[0]
        reference = S @ (u1 + basis @ z)
        for reduced in (False, True):
            constraints = [] if reduced else [wbc.NonholonomicBase()]
            controller = wbc.Controller(robot, [[wrist], [posture]], constraints, reduced=reduced, damping=damping,
                                        lm_damping=0.0)
            v = controller.step(q)
            assert controller.last.success, controller.last.status
            np.testing.assert_allclose(v, reference, rtol=0, atol=1e-6)
            assert abs(robot.base_twist(q, v)[1]) < 1e-9  # no lateral slip


def test_the_steering_preview_of_a_hierarchy_is_its_cascade_without_constraints():
    """SteeringTask at level 1: the preview it reads is the unconstrained cascade of the other
    tasks (position at level 0, then posture with the damping), computed here by projection."""
    rng = np.random.default_rng(5)
    for _ in range(5):
        robot, q, wrist, goal, posture, posture_target = deluca_setup(rng)
        controller = wbc.Controller(robot, [[wrist], [posture, wbc.SteeringTask(1.0)]], [wbc.NonholonomicBase()])
        controller.step(q)
        A1, b1 = position_rows(robot, q, "wrist_center", goal, 1.0, 0.1)
        A2, b2 = posture_rows(q, posture_target, 1.0, 0.1, slice(3, 6))
        reference = null_space_projection([(A1, b1), (A2, b2)], controller.damping)
        np.testing.assert_allclose(controller._preview, reference, rtol=0, atol=1e-7 * max(1, np.abs(reference).max()))


def test_parking_with_priorities_reaches_the_point():
    """tasks/deluca_parking.toml with the wrist centre at level 0 and posture and steering at
    level 1: the base steers and drives, the point is reached, no lateral slip."""
    scenario = load_scenario(TASKS / "deluca_parking.toml")
    wrist, posture, steering = scenario.tasks
    controller = wbc.Controller(scenario.robot, [[wrist], [posture, steering]], scenario.constraints,
                                dt=scenario.dt, damping=scenario.damping)
    result = run(scenario, controller=controller)
    assert result.fallback_ticks == 0
    assert result.position_error[-1] < 1e-3
    assert result.lateral_slip.max() < 1e-8


# ------------------------------------------------------------------- fallback chain
def test_the_elastic_fallback_keeps_the_hierarchy(youbot):
    """A manipulability barrier (soft) that the speed limits (hard) cannot honour makes level 0
    fail; the cascade is re-solved elastically from level 0 on: hard limits hold and level 1
    still does not move level 0's task values."""
    q = np.array([0, 0, 0, 0, 0.3, 0.3, 0.3, 0.0])
    ee = wbc.FrameTask("ee", gain=0.5)
    ee.set_target(youbot_pose_target(youbot, q, np.random.default_rng(2)))
    posture = wbc.PostureTask(1.0, target=q + 0.5, gain=0.2)
    barrier = wbc.ManipulabilityBarrier("ee", min_value=1.0, gain=1.0)  # m far below 1: unreachable
    limits = wbc.JointVelocityLimits()
    controller = wbc.Controller(youbot, [[ee], [posture]], [limits, barrier])
    v = controller.step(q)
    assert controller.last.outcome is wbc.Outcome.ELASTIC
    assert "level 0" in controller.last.status
    assert np.all(np.abs(v[2:]) <= youbot.velocity_limit[2:] * (1 + 1e-9))
    errors, optima = controller.last.level_errors, controller.last.level_optima
    assert abs(errors[0] - optima[0]) <= 1e-6 * max(1.0, optima[0])
    with pytest.raises(wbc.SolverError, match="level 0"):
        wbc.Controller(youbot, [[ee], [posture]], [limits, barrier], strict=True).step(q)


def test_a_failed_lower_level_is_re_solved_elastically_from_there(youbot, monkeypatch):
    """Level 1's solve fails (a backend failure, simulated): level 0's answer stands, level 1 is
    solved by the elastic fallback within level 0's band; the command is the full cascade's."""
    q = np.array([0, 0, 0, 0, 0.5, 1.0, 1.2, 0.0])
    ee = wbc.FrameTask("ee", gain=0.5)
    ee.set_target(youbot_pose_target(youbot, q, np.random.default_rng(4)))
    posture = wbc.PostureTask(1.0, target=q + 0.3, gain=0.2)
    constraints = [wbc.JointPositionLimits(), wbc.JointVelocityLimits()]
    expected = wbc.Controller(youbot, [[ee], [posture]], constraints, solver="quadprog").step(q)
    controller = wbc.Controller(youbot, [[ee], [posture]], constraints, solver="quadprog")
    solve = controller.solver.solve
    last_level = controller.qp
    monkeypatch.setattr(controller.solver, "solve", lambda qp: (wbc.solvers.QPSolution(None, False, "simulated", 0.0)
                                                                if qp is last_level else solve(qp)))
    v = controller.step(q)
    assert controller.last.outcome is wbc.Outcome.ELASTIC
    assert controller.last.status == "fallback: elastic soft rows after quadprog: level 1: simulated"
    np.testing.assert_allclose(v, expected, rtol=0, atol=1e-6)


def test_nan_in_a_level_gives_the_zero_command(youbot):
    class SometimesNan(wbc.Task, TaskData):
        dim, broken = 1, False

        def compute(self, kin, dt, jacobian, target):
            jacobian.fill(1.0)
            target.fill(np.nan if SometimesNan.broken else 0.0)

        def report(self, v, errors):
            pass

    q = np.array([0, 0, 0, 0, 0.5, 1.0, 1.2, 0.0])
    ee = wbc.FrameTask("ee")
    ee.set_target(youbot.frame_pose(q, "ee"))
    task = SometimesNan()
    controller = wbc.Controller(youbot, [[ee], [task]], [wbc.JointVelocityLimits()])
    controller.step(q)
    assert controller.last.success and not np.any(np.isnan(controller.last.level_optima))
    SometimesNan.broken = True
    v = controller.step(q)
    assert controller.last.outcome is wbc.Outcome.ZERO and np.all(v == 0.0)
    assert np.all(np.isnan(controller.last.level_optima))  # not the previous tick's answers


def test_a_level_whose_rows_are_all_zero_leaves_the_freedom_to_the_next(youbot):
    """A FrameTask with zero costs at level 0 asks for nothing: level 1 decides alone."""
    q = np.array([0, 0, 0, 0, 0.5, 1.0, 1.2, 0.0])
    silent = wbc.FrameTask("ee", position_cost=0.0, orientation_cost=0.0)
    silent.set_target(youbot.frame_pose(q, "ee"))
    posture = wbc.PostureTask(1.0, target=q + 0.2, gain=0.1)
    hierarchy = wbc.Controller(youbot, [[silent], [posture]], [wbc.JointVelocityLimits()])
    alone = wbc.Controller(youbot, [posture], [wbc.JointVelocityLimits()])
    np.testing.assert_allclose(hierarchy.step(q), alone.step(q), rtol=0, atol=1e-9)
    assert hierarchy.last.success


# ----------------------------------------------------------------- scenario files
def test_scenario_levels_and_their_mistakes(tmp_path):
    scenario = load_scenario(TASKS / "youbot_priorities.toml")
    assert scenario.levels == [0, 1]
    assert [len(level) for level in scenario.make_controller().levels] == [1, 1]
    weighted = load_scenario(TASKS / "youbot_priorities_weighted.toml")
    assert weighted.levels == [] and weighted.make_controller()._hierarchy is None
    text = (TASKS / "youbot_priorities.toml").read_text()
    assert text.count("level = 1 ") == 1
    for bad, message in [("level = 2 ", "level = 2 but no task has level = 1; levels must be 0, 1, 2"),
                         ("level = -1 ", "level = -1: input should be greater than or equal to 0"),
                         ('level = "1" ', "level = '1': value should be a valid integer; write an integer without"),
                         ("level = 1.0 ", "level = 1.0: value should be a valid integer")]:
        path = tmp_path / "bad.toml"
        path.write_text(text.replace("level = 1 ", bad))
        with pytest.raises(wbc.ScenarioError, match=message):
            load_scenario(path)


def test_the_priorities_scenario_holds_the_pose_and_improves_the_posture_in_the_null_space():
    """tasks/youbot_priorities.toml: after convergence the pose error stays below 1e-6 m (the
    same stack weighted leaks more than 1 mm); the posture ends where the null space of the pose
    task can improve it no further (its error is orthogonal to every null-space motion)."""
    strict, weighted = (load_scenario(TASKS / f"{name}.toml")
                        for name in ("youbot_priorities", "youbot_priorities_weighted"))
    result, leaky = run(strict), run(weighted)
    after = result.time >= 5.0
    assert result.fallback_ticks == 0 and leaky.fallback_ticks == 0
    assert result.position_error[after].max() < 1e-6 and result.orientation_error[after].max() < 1e-6
    assert leaky.position_error[after].min() > 1e-3
    robot, q = strict.robot, result.q[-1]
    posture = strict.tasks[1]
    error = (posture.target - q)[ARM]
    assert np.linalg.norm(error) < 0.5 * np.linalg.norm((posture.target - strict.q0)[ARM])  # improved
    null = scipy.linalg.null_space(robot.frame_jacobian(q, "ee"))
    assert np.linalg.norm(null[ARM].T @ error) < 1e-6 * np.linalg.norm(error)  # as far as it can
    assert np.all(robot.within_limits(q))


# -------------------------------------------------------------------- benchmark harness
def test_the_priorities_benchmark_measures_both_controllers_on_one_loop(capsys):
    """benchmarks/priorities.py (correctness only: no timing is asserted)."""


    from benchmarks import priorities

    scenario = load_scenario(TASKS / "youbot_circle.toml")
    one, two = priorities.controllers(scenario).values()
    assert one._hierarchy is None and two.levels == [[scenario.reference_task], scenario.tasks[1:]]
    times, fallbacks = priorities.measure(scenario, 40)
    assert all(values.shape == (40,) and np.all(values > 0) for values in times.values())
    assert list(fallbacks.values()) == [0, 0]
    assert priorities.main(["--repeats", "1", "--ticks", "30", "--warmup", "5"]) == 0
    assert "median ratio 2 levels / 1 level:" in capsys.readouterr().out
    one, two, three = priorities.controllers(scenario, 3).values()
    extra = one.tasks[-1]
    assert isinstance(extra, wbc.PostureTask) and two.levels[-1][-1] is extra
    assert three.levels == [[scenario.reference_task], scenario.tasks[1:], [extra]]
    assert priorities.main(["--repeats", "1", "--ticks", "30", "--warmup", "5", "--levels", "3"]) == 0
    assert "median ratio 3 levels / 1 level:" in capsys.readouterr().out


def test_the_plot_of_priorities_shows_the_posture_next_to_the_weighted_stack():
    """`wbc run ..._weighted.toml ...priorities.toml --plot`: a posture panel with both runs,
    starting at the posture error of the initial configuration (1 rad: written out here)."""
    from wbc.app.closed_loop import posture_traces
    from wbc.app.plotting import figure

    runs = [(scenario, run(scenario, duration=0.3)) for scenario in
            (load_scenario(TASKS / f"{name}.toml") for name in ("youbot_priorities_weighted", "youbot_priorities"))]
    series = posture_traces(runs)
    start = np.linalg.norm(np.array([-0.8, 0.9, 0.6, 1.4, 0.0]) - np.array([0.0, 0.5, 1.0, 1.2, 0.0]))
    assert [s.shape for s in series] == [(31,), (31,)] and series[0][0] == series[1][0] == pytest.approx(start)
    assert series[1][-1] < 0.9 * start  # the posture improves at level 1
    axes = {ax.get_label(): ax for ax in figure(runs).axes}
    assert [line.get_label() for line in axes["posture"].get_lines()] == [scenario.name for scenario, _ in runs]
    circle = load_scenario(TASKS / "youbot_circle.toml")
    assert posture_traces([(circle, run(circle, duration=0.05))]) is None  # no levels: no panel


# ---------------------------------------------- found by the fuzz suite (tests/test_fuzz.py)
PUMA_Q = np.array([-2.792526803190927, -0.7853981633974483, -3.9269908169872414, -1.9198621771937625,
                   -1.7453292519943295, -4.642575810304916])  # outside the limits, damper gain 1
PUMA_TARGET = np.array([[-0.056032099528763195, 0.8756487679422087, -0.47968702194627966, 0.06752401721830886],
                        [0.3548026892228373, 0.4665459865462646, 0.8102159552599636, 0.18425660712555375],
                        [0.9332606578778736, -0.12479614432691602, -0.33682408883346515, -0.2850287081163513],
                        [0.0, 0.0, 0.0, 1.0]])


def posture_over_pose(posture_cost, orientation_cost, solver):
    puma = wbc.load_robot("puma560")
    pose = wbc.FrameTask("ee", 1.0, orientation_cost, gain=1.0)
    pose.set_target(PUMA_TARGET)
    return puma, wbc.Controller(puma, [[wbc.PostureTask(posture_cost, gain=1.0)], [pose]],
                                [wbc.JointPositionLimits(gain=1.0), wbc.JointVelocityLimits()], solver=solver, dt=DT)


@pytest.mark.parametrize("solver", ["daqp", "quadprog"])
def test_a_level_weighted_1e_12_binds_the_levels_below_as_one_weighted_1(solver):
    """A posture at level 0 fixes every coordinate, whatever its weight: the pose below cannot
    move v. Its band rows are unit rows (weighted 1e-12, rows of norm 1e-6 were inside every
    1e-6 tolerance, and level 1 answered v = 0 instead of level 0's v)."""
    puma, controller = posture_over_pose(1e-12, 10.0, solver)
    v = controller.step(PUMA_Q)
    # level 0 alone: the posture's speed (q* - q) / dt = -q / dt within [lower, upper], per joint
    qp = controller._hierarchy.qps[0]
    expected = np.clip(-PUMA_Q / DT, qp.lb, qp.ub)
    assert controller.last.success
    np.testing.assert_allclose(v, expected, rtol=0, atol=1e-6 * np.max(np.abs(expected)))


def test_a_level_below_a_fully_determined_one_falls_back_to_its_answer(monkeypatch):
    """DAQP calls level 1 infeasible under a posture that fixes every coordinate on the velocity
    bounds (its bands touch the bounds). The elastic re-solve (regularised on its second try)
    answers with level 0's point; had it failed too, the command is level 0's answer
    (Outcome.LEVEL_ABOVE), not v = 0 -- within every limit, optimal for level 0."""
    puma, controller = posture_over_pose(1.0, 1e9, "daqp")
    qp = controller._hierarchy.qps[0]
    v = controller.step(PUMA_Q)
    expected = np.clip(-PUMA_Q / DT, qp.lb, qp.ub)
    assert controller.last.outcome in (wbc.Outcome.OPTIMAL, wbc.Outcome.ELASTIC), controller.last.status
    np.testing.assert_allclose(v, expected, rtol=0, atol=1e-6 * np.max(np.abs(expected)))

    def fails(self, qp):
        return wbc.solvers.QPSolution(None, False, "exitflag -1", 0.0)

    monkeypatch.setattr(wbc.control.fallback.Fallback, "elastic_solve", fails)
    puma, controller = posture_over_pose(1.0, 1e9, "daqp")
    v = controller.step(PUMA_Q)
    assert controller.last.outcome is wbc.Outcome.LEVEL_ABOVE, controller.last.status
    assert controller.last.status.startswith("fallback: level 0's answer after daqp: level 1:")
    np.testing.assert_allclose(v, expected, rtol=0, atol=1e-9 * np.max(np.abs(expected)))
    assert np.all(np.abs(v) <= puma.velocity_limit + 1e-12)


def test_a_semidefinite_upper_level_the_backend_refuses_is_re_solved_with_the_floor():
    """Clarabel gets a level above the last without the regularisation floor (it takes a
    semidefinite H); qpsolvers refused this one ("unbounded below": c barely outside the range
    of H). The elastic re-solve is DAQP's, which factorises H: it gets the floor, and answers
    (it had called the level unbounded and the tick fell to v = 0)."""
    robot = wbc.load_robot("deluca_mm")
    q = np.array([0.0, 0.0, 0.0, -2.792526803190927, -0.7853981633974483, -2.356194490192345])
    wrist = wbc.PositionTask("wrist_center", cost=1.0, gain=1.0)
    wrist.set_target(np.array([0.11889918564360491, 0.0432757644527636, 0.29452987052741136]))
    levels = [[wrist, wbc.ManipulabilityTask("wrist_center", cost=1.0, gain=1.0, target=1.0)],
              [wbc.PostureTask(1.0, gain=1.0), wbc.PostureTask(1.0, gain=1.0)]]
    controller = wbc.Controller(robot, levels, solver="clarabel", reduced=True, dt=DT)
    reference = wbc.Controller(robot, levels, solver="daqp", reduced=True, dt=DT)
    v, expected = controller.step(q), reference.step(q)
    assert reference.last.success
    assert controller.last.outcome in (wbc.Outcome.OPTIMAL, wbc.Outcome.ELASTIC), controller.last.status
    np.testing.assert_allclose(v, expected, rtol=0, atol=1e-6 * (1 + np.max(np.abs(expected))))


@pytest.mark.parametrize("two_sided", [True, False])
def test_band_rows_hold_each_task_value_within_its_relative_width(rng, two_sided):
    """The band of a solved level, written out: for each row a of the level (a zero row among
    them) at the answer x projected onto the bounds, y = â x_b with â = a / |a| and
    eps = BAND max(1, |x_b|_inf); for DAQP one row ``y - eps <= â v <= y + eps`` (its sides m
    entries apart), for the G v <= h backends two rows ``+-â v <= +-y + eps``. A zero row is
    inert: ``0 v <= 0`` with its other side open (never an equality row)."""
    nv, rows = 5, 6
    stack_t = rng.normal(size=(nv + 1, rows))
    stack_t[:, 3] = 0.0  # a zero row of the level
    first, last, first_p, last_p = 1, 4, 5, 6  # the level's rows 1, 2, 3 and its preview row 5
    lower, upper = -np.ones(nv), np.ones(nv)
    x = np.array([0.3, -2.0, 0.5, 1.5, -0.1])  # outside the bounds at coordinates 1 and 3
    x_b = np.clip(x, lower, upper)
    qp = wbc.qp.problem.QP(nv, 10, 0)
    start = 2  # the band's first row of C
    sides = 1 if two_sided else 2
    wbc.runtime.kernels.band_rows(stack_t, first, last, first_p, last_p, x, lower, upper, 1e-9, qp.data, start, 10,
                                  int(two_sided))
    eps = 1e-9 * max(1.0, np.max(np.abs(x_b)))
    for slot, r in enumerate([1, 2, 3, 5]):
        a = stack_t[:nv, r]
        norm = np.linalg.norm(a)
        unit = a / norm if norm > 0 else np.zeros(nv)
        y = unit @ x_b
        row = start + sides * slot
        np.testing.assert_allclose(qp.C[row], unit, rtol=1e-15, atol=1e-15)
        if norm == 0:
            assert qp.upper[nv + row] == 0.0
            assert (qp.lower[nv + row] if two_sided else qp.upper[nv + row + 1]) == (-np.inf if two_sided else 0.0)
            continue
        assert qp.upper[nv + row] == pytest.approx(y + eps, rel=0, abs=1e-15)
        if two_sided:
            assert qp.lower[nv + row] == pytest.approx(y - eps, rel=0, abs=1e-15)
        else:
            np.testing.assert_array_equal(qp.C[row + 1], -qp.C[row])
            assert qp.upper[nv + row + 1] == pytest.approx(eps - y, rel=0, abs=1e-15)
            assert qp.lower[nv + row + 1] == -np.inf
    untouched = [r for r in range(10) if not start <= r < start + sides * 4]
    assert np.all(qp.C[untouched] == 0.0) and np.all(qp.upper[nv + np.array(untouched)] == np.inf)
