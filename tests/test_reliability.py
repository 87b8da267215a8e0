"""Bounded, safe ticks: limits from outside, infeasible QPs, NaN, budgets, stale diagnostics,
and property tests over random states, targets, weights and every installed solver."""

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import wbc
from wbc.constraints.constraint import Constraint, ConstraintData
from wbc.control.diagnostics import StaleDiagnosticsError
from wbc.tasks.task import Task, TaskData

HOME = np.array([0, 0, 0, 0, 0.5, 1.0, 1.2, 0.0])


class PushJoint(Constraint, ConstraintData):
    """One row ``v[index] >= speed`` (beyond the speed limit when ``speed`` is large)."""

    n_inequalities = 1

    def __init__(self, index: int, speed: float, hard: bool) -> None:
        super().__init__()
        self.index, self.speed, self.hard = index, speed, hard

    def write_static(self, rows):
        rows.G[0, self.index], rows.h[0] = -1.0, -self.speed

    def compute(self, kin, dt, rows):
        pass


class NanTask(Task, TaskData):
    """A buggy task that writes NaN."""

    dim = 1

    def compute(self, kin, dt, jacobian, target):
        jacobian.fill(1.0)
        target.fill(np.nan)

    def report(self, v, errors):
        pass


def hold(robot, q):
    task = wbc.FrameTask("ee", 1.0, 0.5, gain=0.5)
    task.set_target_from_configuration(robot, q)
    return task


def within_hard_limits(robot, q, v, tol=1e-7):
    base_twist = robot.base_twist(q, v)
    limits = robot.velocity_limit
    ok = np.all(np.abs(v[3:]) <= limits[3:] + tol) and abs(base_twist[2]) <= limits[2] + tol
    return ok and np.all(np.abs(base_twist[:2]) <= robot.base.max_linear_speed + tol)


@pytest.mark.parametrize("joint", range(3, 8))
@pytest.mark.parametrize("side", ["upper", "lower"])
def test_start_outside_the_position_limits_moves_back_inside(youbot, joint, side):
    q = HOME.copy()
    q[joint] = youbot.upper[joint] + 0.3 if side == "upper" else youbot.lower[joint] - 0.3
    controller = wbc.Controller(youbot, [hold(youbot, HOME)], [wbc.JointPositionLimits(), wbc.JointVelocityLimits()])
    v = controller.step(q)
    assert controller.last.status == "optimal"
    assert (v[joint] < 0) if side == "upper" else (v[joint] > 0)
    assert abs(v[joint]) == pytest.approx(np.pi / 2)  # back at top speed, never beyond it
    for _ in range(30):
        q = youbot.integrate(q, controller.step(q), controller.dt)
    assert youbot.lower[joint] - 1e-12 <= q[joint] <= youbot.upper[joint] + 1e-12  # on the limit, up to rounding


def test_conflicting_soft_row_falls_back_to_the_elastic_solve(youbot):
    controller = wbc.Controller(youbot, [hold(youbot, HOME)],
                                [wbc.JointPositionLimits(), wbc.JointVelocityLimits(), PushJoint(4, 5.0, hard=False)])
    v = controller.step(HOME)
    last = controller.last
    assert last.status.startswith("fallback: elastic") and "infeasible" in last.status and not last.success
    assert np.all(np.isfinite(v)) and within_hard_limits(youbot, HOME, v)
    assert v[4] == pytest.approx(np.pi / 2, abs=1e-6)  # as close to the soft row as the hard limit allows
    assert last.max_violation == pytest.approx(5.0 - np.pi / 2, abs=1e-5)


def test_conflicting_hard_rows_give_the_zero_command(youbot):
    controller = wbc.Controller(youbot, [hold(youbot, HOME)], [wbc.JointVelocityLimits(), PushJoint(4, 5.0, hard=True)])
    v = controller.step(HOME)
    assert controller.last.status.startswith("fallback: zero command") and not controller.last.success
    np.testing.assert_array_equal(v, 0.0)


def test_strict_mode_raises(youbot):
    controller = wbc.Controller(youbot, [hold(youbot, HOME)], [wbc.JointVelocityLimits(), PushJoint(4, 5.0, hard=True)],
                                strict=True)
    with pytest.raises(wbc.SolverError, match="infeasible"):
        controller.step(HOME)


@pytest.mark.parametrize("solver", wbc.available_solvers())
def test_infeasible_qp_never_escapes_as_an_exception_or_nan(youbot, solver):
    controller = wbc.Controller(youbot, [hold(youbot, HOME)],
                                [wbc.JointVelocityLimits(), PushJoint(4, 5.0, hard=False)], solver=solver)
    v = controller.step(HOME)
    assert controller.last.status.startswith("fallback") and np.all(np.isfinite(v))
    assert within_hard_limits(youbot, HOME, v)


def test_nan_from_a_task_is_never_solved(youbot):
    controller = wbc.Controller(youbot, [hold(youbot, HOME), NanTask()], [wbc.JointVelocityLimits()])
    v = controller.step(HOME)
    np.testing.assert_array_equal(v, 0.0)
    assert "NaN" in controller.last.status


def test_iteration_budget_exhaustion_is_handled(youbot):
    task = hold(youbot, HOME)
    target = youbot.frame_pose(HOME, "ee")
    target[:3, 3] += [0.3, 0.3, 0.3]
    task.set_target(target)
    budget = {"iter_limit": 1, "warm_start": False}
    controller = wbc.Controller(youbot, [task], [wbc.JointPositionLimits(), wbc.JointVelocityLimits()],
                                solver_options=budget)
    v = controller.step(HOME)
    assert "iteration limit" in controller.last.status
    assert np.all(np.isfinite(v)) and within_hard_limits(youbot, HOME, v)


@pytest.mark.parametrize("constraints", [[], [wbc.JointPositionLimits()], [wbc.JointVelocityLimits()],
                                         [wbc.JointPositionLimits(), wbc.JointVelocityLimits(),
                                          wbc.MecanumWheelLimits()]])
def test_every_tick_is_solved_by_the_backend_itself(youbot, constraints):
    """Bounds only, rows, nothing: the warm-started workspace solves each tick (no fallback)."""
    target = youbot.frame_pose(HOME, "ee")
    target[:3, 3] += [0.05, 0.02, -0.03]
    task = wbc.FrameTask("ee", 1.0, 0.5, gain=0.2)
    task.set_target(target)
    controller = wbc.Controller(youbot, [task], constraints)
    q = HOME.copy()
    for _ in range(20):
        q = youbot.integrate(q, controller.step(q), controller.dt)
        assert controller.last.status == "optimal" and controller.last.success


def test_warm_start_returns_the_cold_solution(youbot):
    from conftest import TASKS
    from wbc.app.scenario import load_scenario

    scenario = load_scenario(TASKS / "youbot_circle.toml")
    warm = scenario.make_controller()
    cold = wbc.Controller(scenario.robot, scenario.tasks, scenario.constraints, dt=scenario.dt,
                          damping=scenario.damping, solver_options={"warm_start": False})
    q = scenario.q0.copy()
    for k in range(300):
        scenario.reference_task.set_target(*scenario.reference(k * scenario.dt))
        v = warm.step(q)
        np.testing.assert_allclose(cold.step(q), v, rtol=0, atol=1e-9)
        q = scenario.robot.integrate(q, v, scenario.dt)


def test_diagnostics_are_read_now_or_frozen(youbot):
    controller = wbc.Controller(youbot, [hold(youbot, HOME)], [wbc.JointVelocityLimits()])
    controller.step(HOME)
    first = controller.last
    frozen = controller.last.freeze()
    controller.step(HOME)
    assert frozen.task_errors and isinstance(frozen.active_constraints, list)
    second = controller.last
    controller.step(HOME)
    with pytest.raises(StaleDiagnosticsError):
        _ = second.task_errors
    assert first is frozen


def test_bad_targets_of_every_task_are_rejected():
    with pytest.raises(wbc.InvalidInputError):
        wbc.PositionTask("ee").set_target([0.0, np.nan, 0.0])
    with pytest.raises(wbc.InvalidInputError):
        wbc.BaseVelocityTask(1.0).set_target([0.0, 0.0])
    with pytest.raises(wbc.InvalidInputError):
        wbc.FrameTask("ee", 1.0, 1.0).set_target(np.eye(4).astype(complex))
    with pytest.raises(wbc.InvalidInputError):
        wbc.PositionTask("ee", max_speed=0.0)


def test_a_bad_rotation_is_refused_saying_what_is_wrong():
    """A reflection (orthonormal columns, det -1) is refused as a reflection, not with the
    orthogonality defect (~1e-17, which reads as if the matrix were fine)."""
    reflection = np.eye(4)
    reflection[:3, :3] = np.diag([1.0, 1.0, -1.0])
    with pytest.raises(wbc.InvalidInputError, match=r"determinant -1: a reflection, not a rotation"):
        wbc.FrameTask("ee").set_target(reflection)
    sheared = np.eye(4)
    sheared[0, 1] = 0.1
    with pytest.raises(wbc.InvalidInputError, match=r"columns are not orthonormal \(\|R\^T R - I\| = 1.00e-01\)"):
        wbc.FrameTask("ee").set_target(sheared)


# --------------------------------------------------------------------------- properties
YOUBOT = wbc.load_robot("youbot")
DELUCA = wbc.load_robot("deluca_mm")


def _state(data, robot, margin):
    """A configuration within the limits widened by ``margin`` (slightly outside allowed)."""
    low = np.where(np.isfinite(robot.lower), robot.lower - margin, -3.0)
    high = np.where(np.isfinite(robot.upper), robot.upper + margin, 3.0)
    fractions = data.draw(st.lists(st.floats(0.0, 1.0), min_size=robot.nq, max_size=robot.nq))
    return low + np.array(fractions) * (high - low)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data(), solver=st.sampled_from(wbc.available_solvers()),
       margin=st.sampled_from([0.0, 0.05]), reach=st.floats(0.0, 3.0),
       position_cost=st.floats(1e-3, 1e2), orientation_cost=st.floats(0.0, 1e2),
       posture_cost=st.floats(0.0, 1.0), gain=st.floats(0.01, 1.0))
def test_youbot_commands_are_always_finite_and_within_limits(data, solver, margin, reach, position_cost,
                                                             orientation_cost, posture_cost, gain):
    q = _state(data, YOUBOT, margin)
    task = wbc.FrameTask("ee", position_cost, orientation_cost, gain=gain)
    target = YOUBOT.frame_pose(q, "ee")
    direction = data.draw(st.lists(st.floats(-1, 1), min_size=3, max_size=3))
    target[:3, 3] += reach * np.array(direction)  # reachable and unreachable
    task.set_target(target)
    tasks = [task] + ([wbc.PostureTask(posture_cost)] if posture_cost > 0 else [])
    controller = wbc.Controller(YOUBOT, tasks, [wbc.JointPositionLimits(), wbc.JointVelocityLimits(),
                                                wbc.MecanumWheelLimits()], solver=solver)
    v = controller.step(q)
    assert v.shape == (8,) and np.all(np.isfinite(v))
    assert within_hard_limits(YOUBOT, q, v, tol=1e-6)
    assert np.all(np.abs(YOUBOT.wheel_speeds(q, v)) <= YOUBOT.base.wheels.max_speed * (1 + 1e-6))


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data(), solver=st.sampled_from(wbc.available_solvers()), margin=st.sampled_from([0.0, 0.05]),
       reduced=st.booleans(), cost=st.floats(1e-3, 1e2), gain=st.floats(0.01, 1.0))
def test_nonholonomic_commands_never_slip(data, solver, margin, reduced, cost, gain):
    q = _state(data, DELUCA, margin)
    task = wbc.PositionTask("wrist_center", cost, gain=gain)
    task.set_target(data.draw(st.lists(st.floats(-3, 3), min_size=3, max_size=3)))
    controller = wbc.Controller(DELUCA, [task, wbc.SteeringTask(), wbc.PostureTask(1e-3)],
                                [wbc.NonholonomicBase(), wbc.JointPositionLimits(), wbc.JointVelocityLimits()],
                                solver=solver, reduced=reduced)
    v = controller.step(q)
    assert np.all(np.isfinite(v))
    twist = DELUCA.base_twist(q, v)
    assert abs(twist[1]) <= 1e-7
    assert abs(twist[0]) <= 0.5 + 1e-6 and abs(twist[2]) <= 1.0 + 1e-6
    assert np.all(np.abs(v[3:]) <= DELUCA.velocity_limit[3:] + 1e-6)


class BoxBound(Constraint, ConstraintData):
    """Bounds ``lower <= v <= upper`` (hard or soft), for testing the bound merge."""

    has_bounds = True

    def __init__(self, lower, upper, hard):
        super().__init__()
        self.lower, self.upper, self.hard = np.asarray(lower, float), np.asarray(upper, float), hard

    def compute(self, kin, dt, rows):
        rows.lower[:], rows.upper[:] = self.lower, self.upper


@pytest.mark.parametrize("n_hard, n_soft", [(1, 1), (2, 1), (1, 2), (2, 2), (2, 0), (0, 2)])
def test_soft_bounds_are_clipped_into_the_hard_ones(youbot, n_hard, n_soft):
    rng = np.random.default_rng(n_hard * 10 + n_soft)
    hard = [BoxBound(-rng.uniform(0.5, 2, 8), rng.uniform(0.5, 2, 8), True) for _ in range(n_hard)]
    soft = []
    for _ in range(n_soft):
        centre = rng.uniform(-4, 4, 8)  # often entirely outside the hard box
        soft.append(BoxBound(centre - rng.uniform(0, 1, 8), centre + rng.uniform(0, 1, 8), False))
    controller = wbc.Controller(youbot, [wbc.PostureTask(1.0)], hard + soft)
    controller.step(HOME)
    lb, ub = controller.qp.lb, controller.qp.ub
    hard_lb = np.max([b.lower for b in hard], axis=0) if hard else np.full(8, -np.inf)
    hard_ub = np.min([b.upper for b in hard], axis=0) if hard else np.full(8, np.inf)
    soft_lb = np.max([b.lower for b in soft], axis=0) if soft else np.full(8, -np.inf)
    soft_ub = np.min([b.upper for b in soft], axis=0) if soft else np.full(8, np.inf)
    conflict = soft_lb > soft_ub  # soft bounds that exclude each other meet halfway
    soft_lb[conflict] = soft_ub[conflict] = 0.5 * (soft_lb[conflict] + soft_ub[conflict])
    if n_soft == 2:
        assert conflict.any(), "the draw should exercise the soft-soft conflict"
    np.testing.assert_array_equal(lb, np.minimum(np.maximum(soft_lb, hard_lb), hard_ub))
    np.testing.assert_array_equal(ub, np.minimum(np.maximum(soft_ub, hard_lb), hard_ub))
    assert np.all(lb <= ub)


def test_a_backend_that_cycles_is_cut_off_and_answered_by_the_fallback(youbot):
    """A tick found by the property test above on which HiGHS's QP solver cycles for ever:
    its iteration cap stops it, the elastic DAQP solve answers, and the command equals DAQP's."""
    q = np.array([-2.1616357486936906, 0.4308210898981466, -1.1794598913291057, 0.5718367619844802,
                  -0.15601152268813612, -0.7606059456138317, -0.8632010077691539, -2.923426497090502])
    target = np.array([[-0.04275438859166751, 0.5942576693264637, -0.8031375253982543, -2.3536391850223866],
                       [0.2933577315721957, 0.7759051490753315, 0.5584912183420638, 0.4547848806365546],
                       [0.9550462311233775, -0.21172865201730814, -0.20750343209683397, 0.33711331498073094],
                       [0.0, 0.0, 0.0, 1.0]])

    def controller(solver):
        task = wbc.FrameTask("ee", 0.10325106991678025, 1e-06, gain=0.25393289358151583)
        task.set_target(target)
        return wbc.Controller(youbot, [task, wbc.PostureTask(0.5542141958248036)],
                              [wbc.JointPositionLimits(), wbc.JointVelocityLimits(), wbc.MecanumWheelLimits()],
                              solver=solver)

    reference = controller("daqp").step(q)
    highs = controller("highs")
    v = highs.step(q)
    assert highs.last.status == "optimal" or highs.last.status.startswith("fallback: elastic")
    np.testing.assert_allclose(v, reference, atol=1e-6)


def test_a_qp_daqp_calls_infeasible_at_the_damping_floor_is_answered_elastically(youbot):
    """Found by the fuzz suite: an orientation weighted 1e12 beside a position weighted 1 leaves
    the base's x, y to the damping floor (1e-10 of the largest curvature), and DAQP calls the
    QP -- feasible: no rows but the hard wheel limits, which v = 0 meets -- infeasible, and so did
    its elastic re-solve, so the tick fell to v = 0 with the arm outside its limits. The elastic
    re-solve's second, regularised try answers: the arm moves back in, every hard limit holds."""
    q = np.array([0.0, 0.0, 0.0, -3.449606435870417, 2.0707963267948966, 1.5762504807073792, -1.7889624832941877,
                  -2.923426497090502])
    pose = wbc.FrameTask("ee", 1.0, 1e12, gain=1.0)
    pose.set_target(np.array([[0.19799944904722505, -0.3544226504327777, -0.913882269790371, -0.13144004666471476],
                              [-0.29012016277888997, -0.911756374430492, 0.2907414742249803, 0.09469086863403209],
                              [-0.9362833488459281, 0.2075690211605998, -0.28335241683861595, -0.1070873236412225],
                              [0.0, 0.0, 0.0, 1.0]]))
    point = wbc.PositionTask("ee", cost=1.0, gain=1.0)
    point.set_target(np.array([-0.13144004666471476, 0.09469086863403209, -0.1070873236412225]))
    controller = wbc.Controller(youbot, [pose, point, wbc.ManipulabilityTask("ee", cost=1.0, gain=1.0, target=1.0)],
                                [wbc.JointPositionLimits(gain=1e-10), wbc.MecanumWheelLimits()])
    v = controller.step(q)
    assert controller.last.outcome in (wbc.Outcome.OPTIMAL, wbc.Outcome.ELASTIC), controller.last.status
    lower = youbot.model.lowerPositionLimit[3]
    assert v[3] >= (lower - q[3]) / controller.dt * (1 - 1e-9)  # joint 1, below its range: back at full margin
    assert np.max(np.abs(youbot.wheel_speeds(q, v))) <= youbot.base.wheels.max_speed * (1 + 1e-6)
