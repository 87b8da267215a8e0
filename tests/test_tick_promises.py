"""Regression tests of the README's "What a tick guarantees": each test failed before the
fix it guards (answers checked against the QP, cost normalisation, the position damper
outside a limit, ``reduced`` on holonomic bases, items shared between controllers)."""

import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import wbc
from wbc.control.diagnostics import StaleDiagnosticsError
from wbc.runtime import kernels
from wbc.solvers import QPSolution, QPSolver
from wbc.tasks.task import TaskData

HOME = np.array([0, 0, 0, 0, 0.5, 1.0, 1.2, 0.0])


def hold(robot, q, **costs):
    task = wbc.FrameTask("ee", **({"position_cost": 1.0, "orientation_cost": 0.5} | costs), gain=0.5)
    task.set_target_from_configuration(robot, q)
    return task


def reach(robot, q, offset, **costs):
    task = hold(robot, q, **costs)
    target = robot.frame_pose(q, "ee")
    target[:3, 3] += offset
    task.set_target(target)
    return task


def youbot_within_hard_limits(robot, q, v, tol=1e-7):
    vx, vy, omega = robot.base_twist(q, v)
    return (np.all(np.abs(v[3:]) <= robot.velocity_limit[3:] + tol) and abs(omega) <= robot.base.max_yaw_rate + tol
            and max(abs(vx), abs(vy)) <= robot.base.max_linear_speed + tol)


# ------------------------------------------------------------------ answers are checked
def test_huge_base_cost_gives_the_limited_base_twist_without_slip():
    """BaseVelocityTask(cost=1e11) asking a synchro base for (3, -3, 0.5): the answer is the
    twist clipped to the limits, (0.5, 0, 0.5), not the target (it was, marked optimal)."""
    robot = wbc.load_robot("deluca_mm")
    task = wbc.BaseVelocityTask(cost=1e11)
    task.set_target((3.0, -3.0, 0.5))
    controller = wbc.Controller(robot, [task, wbc.PostureTask(1e-3)], [wbc.JointVelocityLimits(),
                                                                       wbc.NonholonomicBase()])
    q = robot.neutral()
    v = controller.step(q)
    assert controller.last.success
    assert robot.base.max_linear_speed == 0.5 and robot.base.max_yaw_rate >= 0.5
    np.testing.assert_allclose(robot.base_twist(q, v), [0.5, 0.0, 0.5], atol=1e-7)
    assert controller.last.max_violation <= 1e-9


class ZeroRow(wbc.Task, TaskData):
    """A Python task (no compiled ops) that asks nothing: 0 v = 0."""

    dim = 1

    def compute(self, kin, dt, jacobian, target):
        jacobian.fill(0.0)
        target.fill(0.0)

    def report(self, v, errors):
        pass


class WrongAnswers(QPSolver):
    """A backend that claims success with an answer outside the bounds."""

    name = "wrong"

    def __init__(self) -> None:
        self.resets = 0

    def solve(self, qp):
        return QPSolution(np.full(qp.n, 10.0), True, "optimal", 0.0)

    def reset(self) -> None:
        self.resets += 1


def test_an_answer_outside_the_constraints_goes_down_the_fallback_chain(youbot):
    controller = wbc.Controller(youbot, [reach(youbot, HOME, [0.3, 0, 0])],
                                [wbc.JointPositionLimits(), wbc.JointVelocityLimits()])
    controller.solver = wrong = WrongAnswers()
    v = controller.step(HOME)
    assert not controller.last.success
    assert controller.last.status.startswith("fallback: elastic soft rows after wrong: answer violates")
    assert youbot_within_hard_limits(youbot, HOME, v) and wrong.resets == 1


def test_an_answer_outside_the_constraints_raises_in_strict_mode(youbot):
    controller = wbc.Controller(youbot, [reach(youbot, HOME, [0.3, 0, 0])], [wbc.JointVelocityLimits()], strict=True)
    controller.solver = WrongAnswers()
    with pytest.raises(wbc.SolverError, match="violates"):
        controller.step(HOME)


def test_constraint_defect_is_the_relative_violation():
    C = np.array([[1.0, 2.0]])
    upper = np.array([1.0, 1.0, 3.0])  # x1 <= 1, x2 <= 1, x1 + 2 x2 <= 3
    lower = np.array([-1.0, -1.0, -np.inf])
    assert kernels.constraint_defect(C, upper, lower, np.array([1.0, 1.0])) == 0.0
    assert kernels.constraint_defect(C, upper, lower, np.array([-3.0, 0.0])) == pytest.approx(2.0 / 3.0)
    # bound: x2 = 1.25 exceeds 1 by 0.25, relative to max(1, |1|, |x2|) = 1.25
    assert kernels.constraint_defect(C, upper, lower, np.array([1.0, 1.25])) == pytest.approx(0.25 / 1.25)
    # row: x1 + 2 x2 = 3 exceeds 2.5 by 0.5, relative to max(1, 2.5, |1| + |2|) = 3
    upper[2] = 2.5
    assert kernels.constraint_defect(C, upper, lower, np.array([1.0, 1.0])) == pytest.approx(0.5 / 3.0)
    assert kernels.constraint_defect(C, upper, lower, np.array([np.nan, 0.0])) == np.inf


@pytest.mark.parametrize("seed", range(20))
def test_qp_defect_is_the_constraint_defect_of_the_qp_buffer(seed):
    """qp_defect reads C and the bounds from the QP's flat buffer (wbc.qp.problem.QP's layout): the
    relative violation written out here (numpy, from the QP's own C and bounds), with infinite
    bounds and equality rows, equal to constraint_defect's; 0 inside; inf for a NaN answer."""
    from wbc.qp.problem import QP

    rng = np.random.default_rng(seed)
    n, p, e = int(rng.integers(1, 9)), int(rng.integers(0, 6)), int(rng.integers(0, 3))
    qp = QP(n, p, e)
    qp.data[:] = rng.normal(size=qp.data.size)  # H and c too: qp_defect must not read them
    qp.C[:] = rng.normal(size=qp.C.shape) * 10.0 ** rng.integers(-3, 4, size=(p + e, 1))
    x = rng.normal(size=n) * 10.0 ** rng.integers(-2, 3)
    middle = np.r_[x, qp.C @ x]
    qp.upper[:] = middle + rng.normal(size=middle.size) * 0.1
    qp.lower[:] = np.minimum(qp.upper, middle - np.abs(rng.normal(size=middle.size)) * 0.1)
    qp.upper[rng.random(middle.size) < 0.2] = np.inf
    qp.lower[rng.random(middle.size) < 0.2] = -np.inf
    qp.upper[0] = x[0] - 0.5  # (a violation in every draw)
    value = np.r_[x, qp.C @ x]
    size = np.r_[np.abs(x), np.abs(qp.C) @ np.abs(x)]  # sum_j |C_rj x_j|
    excess = np.maximum(value - qp.upper, qp.lower - value)
    bound = np.where(value > qp.upper, qp.upper, qp.lower)
    with np.errstate(invalid="ignore"):  # (inf / inf where a row is inside an infinite bound: not taken)
        relative = excess / np.maximum.reduce([np.ones_like(size), np.abs(bound), size])
    expected = np.max(np.where(excess > 0.0, relative, 0.0))
    assert kernels.qp_defect(qp.data, x) == pytest.approx(expected, rel=1e-12) and expected > 0.0
    assert kernels.qp_defect(qp.data, x) == kernels.constraint_defect(qp.C, qp.upper, qp.lower, x)
    qp.upper[:], qp.lower[:] = middle + 1.0, middle - 1.0
    assert kernels.qp_defect(qp.data, x) == 0.0
    x[rng.integers(n)] = np.nan
    assert kernels.qp_defect(qp.data, x) == np.inf


@pytest.mark.parametrize("scale", [1e-12, 1e-9, 1e-6, 1e6, 1e9, 1e12])
@pytest.mark.parametrize("solver", ["daqp", "proxqp", "osqp"])
def test_the_command_does_not_depend_on_the_cost_scale(youbot, scale, solver):
    """Scaling every cost and the damping by the same factor leaves the minimiser unchanged;
    the command at 1e-12..1e12 equals the one at scale 1 (limits active: a far target)."""
    def command(factor):
        task = reach(youbot, HOME, [0.6, -0.4, 0.2], position_cost=factor, orientation_cost=0.5 * factor)
        controller = wbc.Controller(youbot, [task, wbc.PostureTask(1e-3 * factor, target=HOME, gain=0.05)],
                                    [wbc.JointPositionLimits(), wbc.JointVelocityLimits(), wbc.MecanumWheelLimits()],
                                    damping=1e-3 * factor, solver=solver)
        v = controller.step(HOME)
        assert controller.last.success, controller.last.status
        return v

    reference = command(1.0)
    assert youbot_within_hard_limits(youbot, HOME, reference)
    assert np.max(np.abs(reference[3:]) / youbot.velocity_limit[3:]) > 0.99  # a speed limit is active
    np.testing.assert_allclose(command(scale), reference, rtol=0, atol=1e-6)


def test_normalise_cost_keeps_the_minimiser():
    rng = np.random.default_rng(3)
    M = rng.standard_normal((5, 5))
    Hc = np.vstack([M @ M.T * 1e9, rng.standard_normal(5) * 1e9])
    Hc[:5] += 1e-3 * np.eye(5)  # the damping
    x = np.linalg.solve(Hc[:5], -Hc[5])
    kernels.normalise_cost(Hc, 1e-3, 1e-15)  # damping / scale ~ 1e-13: above the floor, unchanged
    assert np.max(np.diag(Hc[:5])) == pytest.approx(1.0)
    np.testing.assert_allclose(np.linalg.solve(Hc[:5], -Hc[5]), x, rtol=1e-9)


def test_the_damping_is_floored_relative_to_the_cost_scale():
    Hc = np.zeros((4, 3))
    Hc[:3] = np.diag([1e12, 1e12, 0.0])  # one direction without cost and no damping: singular
    Hc[3] = [-1e12, 2e12, 0.0]
    kernels.normalise_cost(Hc, 0.0, 1e-10)
    np.testing.assert_allclose(np.diag(Hc[:3]), [1.0 + 1e-10, 1.0 + 1e-10, 1e-10], rtol=1e-12)
    np.testing.assert_allclose(Hc[3], [-1.0, 2.0, 0.0])
    Hc[:3], Hc[3] = np.diag([1e3, 1e3, 1e-3]), 0.0  # damping 1e-3 over a scale of 1e3: above the floor
    kernels.normalise_cost(Hc, 1e-3, 1e-10)
    np.testing.assert_allclose(np.diag(Hc[:3]), [1.0, 1.0, 1e-6], rtol=1e-12)


def test_a_cost_1e15_times_the_damping_leaves_the_elastic_fallback_solvable():
    """Fuzz-found: orientation cost 1e12 over the default damping on the Scorbot with an
    infeasible barrier row: H is singular in double precision, the elastic DAQP solve
    failed (exitflag -1) and the zero command answered; with the damping floor the elastic
    fallback answers."""
    scorbot = wbc.load_robot("scorbot_er4pc")
    q = np.array([-2.705260340591211, 2.7454191709428537, 2.339118079588274, 2.2689280275926285,
                  -0.7352533540128374])
    target = np.array([[0.8732026140370689, 0.21991762820628447, -0.4349177297408686, 0.04772200181984958],
                       [0.22449622688035767, -0.9735879938604116, -0.04156756340395866, 0.0119945456666557],
                       [-0.4325721199468502, -0.06134048430670783, -0.8995102589908057, 0.35616895246621705],
                       [0.0, 0.0, 0.0, 1.0]])
    task = wbc.FrameTask("ee", 500.6766687274403, 1e12, gain=0.009657440113009449)
    task.set_target(target)
    controller = wbc.Controller(scorbot, [task], [wbc.ManipulabilityBarrier("ee", min_value=0.1, gain=1.0),
                                                  wbc.JointPositionLimits(gain=1e-12)])
    statuses = []
    for _ in range(3):
        v = controller.step(q)
        statuses.append(controller.last.status)
        q = scorbot.integrate(q, v, controller.dt)
    assert statuses == ["optimal"] + ["fallback: elastic soft rows after daqp: infeasible"] * 2


# ------------------------------------------------------------- position limits, any gain
@pytest.mark.parametrize("gain", [1e-4, 1e-3, 0.01, 0.5, 1.0])
@pytest.mark.parametrize("speed_limits", [False, True])
@pytest.mark.parametrize("side", ["upper", "lower"])
def test_a_joint_outside_its_limit_comes_back_for_any_gain(youbot, gain, speed_limits, side):
    q = HOME.copy()
    q[5] = youbot.upper[5] + 0.005 if side == "upper" else youbot.lower[5] - 0.005
    constraints = [wbc.JointPositionLimits(gain=gain)] + ([wbc.JointVelocityLimits()] if speed_limits else [])
    controller = wbc.Controller(youbot, [hold(youbot, HOME), wbc.PostureTask(1e-3)], constraints)
    for _ in range(5):
        q = youbot.integrate(q, controller.step(q), controller.dt)
        assert controller.last.success, controller.last.status
    assert youbot.lower[5] - 1e-12 <= q[5] <= youbot.upper[5] + 1e-12


@settings(max_examples=300, deadline=None)
@given(q=st.floats(-4.0, 4.0), low=st.floats(-3.0, 0.0), width=st.floats(0.0, 3.0),
       gain=st.floats(1e-6, 1.0), dt=st.floats(1e-4, 0.1))
def test_damper_bounds_never_exclude_each_other(q, low, width, gain, dt):
    """lower <= upper always; inside the limits one Euler step stays inside; outside, every
    admissible step moves toward the range and the full way back is admissible."""
    high = low + width
    lower, upper = np.zeros(1), np.zeros(1)
    kernels.position_limit_bounds(np.array([q]), np.array([low]), np.array([high]), gain, dt, lower, upper)
    assert lower[0] <= upper[0]
    if low <= q <= high:
        assert low - 1e-12 <= q + lower[0] * dt and q + upper[0] * dt <= high + 1e-12
    elif q > high:
        assert upper[0] * dt == pytest.approx(high - q) and lower[0] <= upper[0] < 0
    else:
        assert lower[0] * dt == pytest.approx(low - q) and 0 < lower[0] <= upper[0]


# ---------------------------------------------------------------------------- reduced
@pytest.mark.parametrize("model", ["youbot", "puma560"])
def test_reduced_on_a_holonomic_or_fixed_base_is_the_plain_qp(model):
    robot = wbc.load_robot(model)
    q = HOME if model == "youbot" else np.array([0.0, -0.6, 0.4, 0.2, 0.8, 0.1])
    commands = []
    for reduced in (False, True):
        controller = wbc.Controller(robot, [reach(robot, q, [0.05, 0.02, 0.0])],
                                    [wbc.JointPositionLimits(), wbc.JointVelocityLimits()], reduced=reduced)
        commands.append(controller.step(q))
        assert controller.last.success and not controller.reduced
        np.testing.assert_array_equal(controller.last.u, commands[-1])
    np.testing.assert_allclose(commands[1], commands[0], rtol=0, atol=1e-12)


@pytest.mark.parametrize("option", ["reduced", "strict"])
@pytest.mark.parametrize("value", ["false", "True", 1, 0, None])
def test_options_that_are_not_booleans_are_refused(youbot, option, value):
    with pytest.raises(wbc.InvalidInputError, match=option):
        wbc.Controller(youbot, [hold(youbot, HOME)], **{option: value})


# ----------------------------------------------------------------------------- sharing
def test_items_shared_by_controllers_of_different_robots_give_each_its_own_command(youbot):
    """A FrameTask and limits shared by a youBot and a PUMA controller (the youBot's command
    moved by ~3 rad/s when the task's frame data was the PUMA's): each controller has its
    own data, so each commands what it commands alone, with its own task errors."""
    puma = wbc.load_robot("puma560")
    q_puma = np.array([0.0, -0.6, 0.4, 0.2, 0.8, 0.1])
    task = reach(youbot, HOME, [0.1, 0.05, 0.0])
    posture = wbc.PostureTask(1e-3, gain=0.1)
    limits = [wbc.JointPositionLimits(), wbc.JointVelocityLimits()]
    first = wbc.Controller(youbot, [task, posture], limits)
    second = wbc.Controller(puma, [task, posture], limits)
    for _ in range(3):
        v1, v2 = first.step(HOME), second.step(q_puma)
        for robot, q, v, controller in ((youbot, HOME, v1, first), (puma, q_puma, v2, second)):
            own_task = wbc.FrameTask("ee", 1.0, 0.5, gain=0.5)
            own_task.set_target(task.target)
            alone = wbc.Controller(robot, [own_task, wbc.PostureTask(1e-3, gain=posture.gain)],
                                   [wbc.JointPositionLimits(), wbc.JointVelocityLimits()])
            np.testing.assert_allclose(v, alone.step(q), rtol=0, atol=1e-9)
            position = robot.frame_pose(q, "ee")[:3, 3]
            assert controller.last.task_errors["FrameTask(ee).position"] == pytest.approx(
                np.linalg.norm(task.target[:3, 3] - position))
        posture.gain = 0.3  # a setting changed on the shared task reaches both controllers


def test_a_custom_item_that_is_its_own_data_serves_one_robot(youbot):
    class Hold(wbc.Task, TaskData):
        dim = 1

        def compute(self, kin, dt, jacobian, target):
            jacobian[0, 3], target[0] = 1.0, 0.0

    hold_joint = Hold()
    wbc.Controller(youbot, [hold_joint])
    wbc.Controller(youbot, [hold_joint])  # the same robot object: shared
    with pytest.raises(wbc.InvalidInputError, match="another robot object"):
        wbc.Controller(wbc.load_robot("youbot"), [hold_joint])


def test_items_shared_on_one_robot_give_each_controller_its_own_command_and_errors(youbot, rng):
    task = reach(youbot, HOME, [0.2, 0.1, 0.0])
    posture = wbc.PostureTask(1e-2, target=HOME, gain=0.2)
    limits = [wbc.JointPositionLimits(gain=0.3), wbc.JointVelocityLimits(), wbc.MecanumWheelLimits(),
              wbc.ManipulabilityBarrier("ee", min_value=0.01, gain=0.3)]
    first, second = (wbc.Controller(youbot, [task, posture], limits) for _ in range(2))
    target = task.target
    for _ in range(5):
        q1, q2 = HOME + rng.normal(0, 0.2, 8), HOME + rng.normal(0, 0.2, 8)
        posture.gain = rng.uniform(0.05, 1.0)  # settings are shared: both must use the new gain
        v1, v2 = first.step(q1), second.step(q2)  # errors of the first read after the second stepped
        for v, q, last in ((v1, q1, first.last), (v2, q2, second.last)):
            own_task = wbc.FrameTask("ee", 1.0, 0.5, gain=0.5)
            own_task.set_target(target)
            own = wbc.Controller(youbot, [own_task, wbc.PostureTask(1e-2, target=HOME, gain=posture.gain)],
                                 [wbc.JointPositionLimits(gain=0.3), wbc.JointVelocityLimits(),
                                  wbc.MecanumWheelLimits(), wbc.ManipulabilityBarrier("ee", 0.01, 0.3)])
            np.testing.assert_allclose(v, own.step(q), rtol=0, atol=1e-9)
            position = youbot.frame_pose(q, "ee")[:3, 3]
            assert last.task_errors["FrameTask(ee).position"] == pytest.approx(np.linalg.norm(target[:3, 3] - position))


# ------------------------------------------------------------------------- boundary
@pytest.mark.parametrize("make, match", [
    (lambda y: wbc.Controller(y, [hold(y, HOME)], damping="x"), "damping"),
    (lambda y: wbc.Controller(y, [hold(y, HOME)], damping=True), "damping"),
    (lambda y: wbc.Controller(y, hold(y, HOME)), "list of Tasks"),
    (lambda y: wbc.Controller(y, [hold(y, HOME)], wbc.JointVelocityLimits()), "list of Constraints"),
    (lambda y: wbc.Controller(y, [hold(y, HOME)], solver_options=[1, 2]), "solver_options"),
    (lambda y: wbc.FrameTask("ee", position_cost="a"), "position_cost"),
    (lambda y: wbc.FrameTask("ee", position_cost=1j), "position_cost"),
    (lambda y: wbc.FrameTask("ee", position_cost=None), "position_cost"),
    (lambda y: wbc.PositionTask("ee", cost=[1.0, "a", 2.0]), "cost"),
    (lambda y: wbc.PostureTask(1.0, joints="arm_joint_1"), r"joints=\['arm_joint_1'\]"),
])
def test_malformed_arguments_raise_a_wbc_error_naming_them(youbot, make, match):
    with pytest.raises(wbc.InvalidInputError, match=match):
        make(youbot)


@pytest.mark.parametrize("call, match", [
    (lambda y, c, t: c.step([0, 0, 0, [0], 0.5, 1.0, 1.2, 0.0]), r"q must be an array of shape \(8,\)"),
    (lambda y, c, t: y.frame_pose([0, 0, 0, [0], 0.5, 1.0, 1.2, 0.0], "ee"), r"q must be an array of shape \(8,\)"),
    (lambda y, c, t: t.set_target([[1, 0, 0, 0], [0, 1, 0], [0, 0, 1, 0], [0, 0, 0, 1]]),
     r"target pose must be an array of shape \(4, 4\)"),
    (lambda y, c, t: wbc.Sphere([[0.7], 0.0, 0.1], 0.05), r"Sphere center must be an array of shape \(3,\)"),
], ids=["step", "frame_pose", "set_target", "Sphere"])
def test_ragged_nested_lists_are_refused_naming_the_argument(youbot, call, match):
    """Ragged nested lists (numpy cannot make an array of them) raise a wbc error naming the
    argument and the shape it needs, not numpy's "inhomogeneous shape" ValueError."""
    task = wbc.FrameTask("ee")
    controller = wbc.Controller(youbot, [hold(youbot, HOME)])
    with pytest.raises(wbc.InvalidInputError, match=match):
        call(youbot, controller, task)


@pytest.mark.parametrize("q", [np.zeros(8, dtype=bool), np.array(["0"] * 8), [None] * 8,
                               [0.0] * 7 + [True], (0.0, 0.0, np.bool_(False), 0, 0, 0, 0, 0)])
def test_configurations_that_are_not_numbers_are_refused(youbot, q):
    controller = wbc.Controller(youbot, [hold(youbot, HOME)])
    with pytest.raises(wbc.InvalidInputError, match="q must be numeric"):
        controller.step(q)


def test_a_boolean_among_numbers_is_refused_in_every_array_input(youbot):
    """numpy reads [0.5, True, 0.4] as floats; wbc refuses true/false wherever it wants numbers."""
    pose = np.eye(4).tolist()
    pose[0][3] = True
    with pytest.raises(wbc.InvalidInputError, match="target pose must be numeric .*not true/false"):
        wbc.FrameTask("ee").set_target(pose)
    with pytest.raises(wbc.InvalidInputError, match="center must be numeric .*not true/false"):
        wbc.Sphere([0.5, True, 0.4], 0.1)
    with pytest.raises(wbc.InvalidInputError, match="cost must be numeric .*not true/false"):
        wbc.Controller(youbot, [wbc.PostureTask(cost=[1.0] * (youbot.nv - 1) + [False])])
    assert wbc.Sphere([0.5, 1, 0.4], 0.1).center.tolist() == [0.5, 1.0, 0.4]  # ints are numbers


def test_integer_and_object_configurations_are_converted(youbot):
    controller = wbc.Controller(youbot, [hold(youbot, HOME)], [wbc.JointVelocityLimits()])
    reference = controller.step(np.zeros(8))
    for q in (np.zeros(8, dtype=int), np.array([0.0] * 8, dtype=object), [0] * 8):
        np.testing.assert_allclose(controller.step(q), reference, rtol=0, atol=1e-9)  # warm vs cold start


def test_settings_assigned_after_construction_act_on_the_next_tick(youbot):
    """Costs, gains, dt and damping reassigned between ticks give the command of a controller
    built with the new values (they were silently ignored)."""
    task = reach(youbot, HOME, [0.2, 0.1, 0.0])
    manipulability = wbc.ManipulabilityTask("ee", cost=1e-3, gain=0.1, target=0.2)
    controller = wbc.Controller(youbot, [task, manipulability], [wbc.JointVelocityLimits()])
    controller.step(HOME)
    task.position_cost, task.orientation_cost = [2.0, 3.0, 4.0], 0.1
    manipulability.cost, manipulability.gain, manipulability.target = 1e-2, 0.3, 0.1
    controller.dt, controller.damping = 0.02, 1e-2
    fresh_task = reach(youbot, HOME, [0.2, 0.1, 0.0], position_cost=[2.0, 3.0, 4.0], orientation_cost=0.1)
    fresh = wbc.Controller(youbot, [fresh_task, wbc.ManipulabilityTask("ee", cost=1e-2, gain=0.3, target=0.1)],
                           [wbc.JointVelocityLimits()], dt=0.02, damping=1e-2)
    np.testing.assert_allclose(controller.step(HOME), fresh.step(HOME), rtol=0, atol=1e-10)
    np.testing.assert_array_equal(task.position_cost, [2.0, 3.0, 4.0])


@pytest.mark.parametrize("assign, match", [
    (lambda t, m, c: setattr(m, "gain", float("nan")), "gain"),
    (lambda t, m, c: setattr(m, "cost", -1.0), "cost"),
    (lambda t, m, c: setattr(t, "position_cost", "a"), "position_cost"),
    (lambda t, m, c: setattr(t, "frame", "base_link"), "frame cannot change"),
    (lambda t, m, c: setattr(t, "target", np.eye(4)), "read-only"),
    (lambda t, m, c: setattr(c, "dt", 0.0), "dt"),
    (lambda t, m, c: setattr(c, "damping", -1e-3), "damping"),
])
def test_invalid_or_ineffective_assignments_raise(youbot, assign, match):
    task = hold(youbot, HOME)
    manipulability = wbc.ManipulabilityTask("ee", cost=1e-3, target=0.2)
    controller = wbc.Controller(youbot, [task, manipulability])
    with pytest.raises(wbc.InvalidInputError, match=match):
        assign(task, manipulability, controller)


def test_the_elastic_fallback_keeps_bounds_that_daqp_soft_mode_misses(youbot):
    """A fuzz-found tick (cond(H) ~ 1e9, damper boxes ~1e-9 wide, an infeasible barrier row):
    DAQP's elastic answer was 4e-6 outside the hard bounds, so the zero command answered;
    the elastic answer is now projected onto the bounds and its rows checked."""
    q = np.array([-1.3587796317364305, 5.0, -0.4378818720638966, 2.949606435870417, -0.361027618541753,
                  -0.08746027016836289, 1.829923566571769, -2.9234266162997917])
    target = np.array([[-0.34281887285774415, 0.16273211684005742, -0.9251991561611478, 0.20340380444739026],
                       [-0.23278542491117304, 0.939447698719269, 0.2514934737125279, 5.008118370703418],
                       [0.910102283461299, 0.30158958788363893, -0.284178736218434, 3.596698748278864],
                       [0.0, 0.0, 0.0, 1.0]])
    task = wbc.FrameTask("ee", 1e-12, 1e-12, gain=1.0, max_speed=0.003572457911839863,
                         max_angular_speed=0.03941324628936638)
    task.set_target(target)
    limits = wbc.JointPositionLimits(gain=2.8608077615635767e-12)
    controller = wbc.Controller(
        youbot,
        [task, wbc.ManipulabilityTask("ee", cost=277021.57814671274, gain=1e-12, target=3.1358218617635436e-05)],
        [wbc.ManipulabilityBarrier("ee", min_value=0.007262418412154669, gain=1e-12), limits,
         wbc.MecanumWheelLimits(), wbc.JointVelocityLimits()])
    v = controller.step(q)
    assert controller.last.status == "fallback: elastic soft rows after daqp: infeasible"
    assert youbot_within_hard_limits(youbot, q, v)
    assert np.all(np.abs(youbot.wheel_speeds(q, v)) <= youbot.base.wheels.max_speed)
    margin_low, margin_high = (youbot.lower - q) / controller.dt, (youbot.upper - q) / controller.dt
    inside = (q >= youbot.lower) & (q <= youbot.upper)
    scale = np.where(inside, limits.gain, 1.0)[3:]
    limit = youbot.velocity_limit[3:]  # soft damper bounds clipped into the hard speed limits
    assert np.all(v[3:] >= np.clip(scale * margin_low[3:], -limit, limit))
    assert np.all(v[3:] <= np.clip(scale * margin_high[3:], -limit, limit))


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
@pytest.mark.parametrize("python_item", [False, True])
def test_every_non_finite_coordinate_of_q_is_refused(youbot, bad, python_item):
    """q's finiteness is screened inside the tick program (compiled items only) or up front
    (a Python task sees the kinematics first): either way each coordinate, even one no task
    reads (the wrist roll, with a position-only task), raises; the record of
    the previous tick goes stale instead of reading overwritten buffers; the next tick works."""
    task = wbc.PositionTask("ee", gain=0.5)
    task.set_target(youbot.frame_pose(HOME, "ee")[:3, 3])
    extra = [ZeroRow()] if python_item else []
    controller = wbc.Controller(youbot, [task, *extra], [wbc.JointVelocityLimits()])
    assert controller._q_screened is not python_item
    reference = controller.step(HOME)
    for i in range(youbot.nq):
        previous = controller.last
        q = HOME.copy()
        q[i] = bad
        with pytest.raises(wbc.InvalidInputError, match="q contains NaN or inf"):
            controller.step(q)
        if not python_item:
            with pytest.raises(StaleDiagnosticsError):
                _ = previous.task_errors
    np.testing.assert_allclose(controller.step(HOME), reference, atol=1e-12)
    assert controller.last.outcome is wbc.Outcome.OPTIMAL


@pytest.mark.parametrize("huge", [1e308, -1e308, 1e200, 2e154])
@pytest.mark.parametrize("python_item", [False, True])
def test_huge_finite_inputs_are_answered_without_a_warning(youbot, huge, python_item):
    """Nothing is printed by a tick: q = 1e308 (finite) is answered with a finite command and no
    numpy warning (``q . q`` overflows from 1e154 on and numpy warned twice, in the controller's
    and check_configuration's screens); so are a target of 1e308 (set_target's screen) and a base
    twist of 1e308 weighted 1e6 (inf: a task computed in Python), and their task errors."""
    task = wbc.PositionTask("ee", gain=0.5)
    task.set_target(youbot.frame_pose(HOME, "ee")[:3, 3])
    base = wbc.BaseVelocityTask(1.0)
    extra = [ZeroRow()] if python_item else []
    controller = wbc.Controller(youbot, [task, base, wbc.PostureTask(1e-3), *extra], [wbc.JointVelocityLimits()])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        commands = [controller.step(np.full(8, huge))]
        _ = controller.last.task_errors
        task.set_target(np.full(3, huge))
        commands.append(controller.step(HOME))
        _ = controller.last.task_errors
        task.set_target(youbot.frame_pose(HOME, "ee")[:3, 3])
        base.cost = 1e12
        base.set_target(np.full(3, abs(huge)))  # weighted: inf for 1e308
        commands.append(controller.step(HOME))
        _ = controller.last.task_errors
    for v in commands:
        assert np.all(np.isfinite(v)) and youbot_within_hard_limits(youbot, HOME, v)


@pytest.mark.parametrize("solver", wbc.available_solvers())
@pytest.mark.parametrize("model", ["youbot", "deluca_mm"])
def test_a_configuration_of_1e200_warns_nothing_with_any_backend(model, solver):
    """The backends' answer checks (qpsolvers' residuals of x ~ 1e200 overflowed in quadprog's
    check) and the elastic fallback (DAQP's regularised retry of an overflowed H warned on deluca)
    say nothing either."""
    robot = wbc.load_robot(model)
    task = wbc.PositionTask(robot.end_effector, gain=0.5)
    task.set_target(robot.frame_pose(robot.neutral(), robot.end_effector)[:3, 3])
    constraints = [wbc.JointVelocityLimits(), wbc.JointPositionLimits()]
    constraints += [wbc.NonholonomicBase()] if robot.base.is_nonholonomic else []
    controller = wbc.Controller(robot, [task, wbc.PostureTask(1e-3)], constraints, solver=solver)
    far = robot.neutral().copy()
    far[0] = 1e200
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for q in (np.full(robot.nq, 1e200), far):
            assert np.all(np.isfinite(controller.step(q)))
            _ = controller.last.task_errors


def test_the_finiteness_screen_is_exact_and_never_warns(rng):
    """``x . w`` (wbc.core.validation.finite_weights) is finite iff every entry of x is, for every size
    and magnitude up to the largest float, with no warning (nor an underflow error)."""
    from wbc.core.validation import all_finite

    largest = np.finfo(float).max
    with warnings.catch_warnings(), np.errstate(over="raise", invalid="raise", divide="raise"):
        warnings.simplefilter("error")
        for size in range(0, 40):
            for _ in range(50):
                x = rng.choice([-1.0, 1.0], size) * 10.0 ** rng.uniform(-320, 308.25, size)
                x[rng.random(size) < 0.2] = rng.choice([largest, -largest, 5e-324, 0.0])
                assert all_finite(x)
                if size:
                    x[rng.integers(size)] = rng.choice([np.nan, np.inf, -np.inf])
                    assert not all_finite(x)
