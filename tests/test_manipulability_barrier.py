"""ManipulabilityBarrier (hard row) and ManipulabilityTask (soft row): rows, closed-loop guarantees."""

import numpy as np
import pinocchio as pin
import pytest

import wbc
from test_manipulability import fd_gradient, shipped_end_effectors
from wbc.model.manipulability import manipulability, manipulability_gradient

DT = 0.01


def test_barrier_row_is_the_discrete_cbf(youbot):
    barrier = wbc.ManipulabilityBarrier("ee", min_value=0.05, gain=0.4)
    controller = wbc.Controller(youbot, [wbc.PostureTask(1.0)], [barrier], dt=DT)
    q = np.array([0.3, 0.1, 0.2, 0.4, -0.6, 0.3, 1.1, 0.2])
    controller.step(q)
    m = manipulability(youbot, q, "ee")
    np.testing.assert_allclose(controller.qp.G[0], -fd_gradient(youbot, q, "ee", "all"), rtol=0, atol=1e-8)
    assert controller.qp.h[0] == pytest.approx(0.4 * (m - 0.05) / DT, rel=1e-12)
    assert controller.data(barrier).value == pytest.approx(m, rel=1e-12)
    assert repr(barrier) == "ManipulabilityBarrier(frame='ee', min_value=0.05, gain=0.4, rows='all')"


def _singular_posture(robot, frame, rows, q0):
    """A configuration with m far below m(q0): Newton steps toward m = 0 (m behaves like |f(q)|
    near a singular set), at most 0.1 rad each, within the joint limits."""
    q = q0.copy()
    for _ in range(100):
        gradient = manipulability_gradient(robot, q, frame, rows)
        step = manipulability(robot, q, frame, rows) * gradient / (gradient @ gradient + 1e-300)
        step *= min(1.0, 0.1 / (np.linalg.norm(step) + 1e-300))
        q = np.clip(pin.integrate(robot.model, q, -step), robot.lower, robot.upper)
    return q


@pytest.mark.parametrize("model, frame", shipped_end_effectors())
def test_barrier_holds_a_posture_pull_into_a_singularity_on_every_model(model, frame, rng):
    """A PostureTask drags the joints to a (numerically found) singular posture. Without the barrier
    m ends near 0; with it m never drops below m_min and the QP is feasible every tick."""
    robot = wbc.load_robot(model)
    for _ in range(10):  # the descent can stall on a joint limit from an unlucky start: draw again
        q0 = robot.random_configuration(rng, base_range=0.0)
        rows = next(r for r in ("all", "position", "orientation") if manipulability(robot, q0, frame, r) > 1e-9)
        singular = _singular_posture(robot, frame, rows, q0)
        m0, m_singular = manipulability(robot, q0, frame, rows), manipulability(robot, singular, frame, rows)
        if m_singular < 0.05 * m0:
            break
    assert m_singular < 0.05 * m0
    m_min = 0.3 * m0
    base_rows = [wbc.NonholonomicBase()] if robot.base.is_nonholonomic else []

    def closed_loop(constraints):
        controller = wbc.Controller(robot, [wbc.PostureTask(1.0, target=singular, gain=0.05)],
                                    [wbc.JointPositionLimits(), wbc.JointVelocityLimits()] + base_rows + constraints,
                                    dt=DT)
        q, history = q0.copy(), [m0]
        for _ in range(300):
            q = robot.integrate(q, controller.step(q), DT)  # SolverError if the QP were infeasible
            history.append(manipulability(robot, q, frame, rows))
        return np.array(history)

    assert closed_loop([])[-1] < m_min
    guarded = closed_loop([wbc.ManipulabilityBarrier(frame, m_min, gain=0.3, rows=rows)])
    # first order the floor is exact; the second-order term (bounded per tick by
    # dt^2/2 |Hess m| |v|^2, see the next test) lets a strongly curved m (PUMA) dip ~0.1 %
    assert guarded.min() >= m_min * (1 - 1e-2)
    assert guarded[-1] < 1.1 * m_min, "the pull is blocked at the floor, not far above it"


def _hessian_norm(robot, q, frame, step=1e-6):
    """Spectral norm of the Hessian of m at q, by central differences of the gradient."""
    columns = []
    for i in range(robot.nv):
        dq = np.zeros(robot.nv)
        dq[i] = step
        columns.append((manipulability_gradient(robot, q + dq, frame) - manipulability_gradient(robot, q - dq, frame))
                       / (2 * step))
    hessian = np.array(columns)
    return np.linalg.norm(0.5 * (hessian + hessian.T), 2)


def test_barrier_margin_shrinks_at_most_geometrically(youbot):
    """Each tick: m+ - m_min >= (1 - gain)(m - m_min) - dt^2/2 |Hess m| |v|^2 (the docstring's claim)."""
    gain, m_min = 0.3, 0.04
    target = np.zeros(8)
    target[6] = 0.5  # theta2 = theta3 = 0: singular
    controller = wbc.Controller(youbot, [wbc.PostureTask(1.0, target=target, gain=0.2)],
                                [wbc.JointVelocityLimits(), wbc.ManipulabilityBarrier("ee", m_min, gain)], dt=DT)
    q = np.array([0.0, 0.0, 0.0, 0.0, -0.9, 0.4, 1.0, 0.0])
    active = 0
    for _ in range(150):
        v = controller.step(q)
        m = manipulability(youbot, q, "ee")
        second_order = 0.5 * DT ** 2 * 1.1 * _hessian_norm(youbot, q, "ee") * float(v @ v)
        q = youbot.integrate(q, v, DT)
        margin = manipulability(youbot, q, "ee") - m_min
        assert margin >= (1 - gain) * (m - m_min) - second_order - 1e-12
        active += margin < 1e-3 * m_min
    assert active > 50, "the barrier must have been the binding constraint for a while"


@pytest.mark.parametrize("kwargs, message", [
    ({"frame": "ee", "min_value": 0.0}, "min_value"),
    ({"frame": "ee", "min_value": 0.1, "gain": 1.5}, "gain"),
    ({"frame": "ee", "min_value": 0.1, "rows": "xyz"}, "rows"),
    ({"frame": 3, "min_value": 0.1}, "frame"),
])
def test_barrier_rejects_bad_arguments(kwargs, message):
    with pytest.raises(wbc.InvalidInputError, match=message):
        wbc.ManipulabilityBarrier(**kwargs)


def test_unknown_frame_fails_when_the_controller_binds(youbot):
    with pytest.raises(wbc.UnknownFrameError):
        wbc.Controller(youbot, [wbc.PostureTask(1.0)], [wbc.ManipulabilityBarrier("gripper", 0.1)])
    with pytest.raises(wbc.UnknownFrameError):
        wbc.Controller(youbot, [wbc.ManipulabilityTask("gripper", 1.0, target=0.2)])


def test_task_row_is_the_log_manipulability_rate(youbot):
    task = wbc.ManipulabilityTask("ee", cost=4.0, gain=0.2, target=0.3, rows="position")
    controller = wbc.Controller(youbot, [task], dt=DT)
    q = np.array([0.3, 0.1, 0.2, 0.4, -0.6, 0.3, 1.1, 0.2])
    controller.step(q)
    m = manipulability(youbot, q, "ee", "position")
    np.testing.assert_allclose(controller._task_stack.stack[0, :-1], 2.0 * fd_gradient(youbot, q, "ee", "position") / m,
                               rtol=0, atol=1e-7)
    assert controller._task_stack.stack[0, -1] == pytest.approx(2.0 * 0.2 / DT * np.log(0.3 / m), rel=1e-12)
    assert controller.last.task_errors[task.name] == pytest.approx(abs(np.log(0.3 / m)), rel=1e-12)
    assert repr(task) == "ManipulabilityTask(frame='ee', cost=4.0, gain=0.2, target=0.3, rows='position')"


@pytest.mark.parametrize("start", [[0.0, 0.0, 0.0, 0.0, 0.05, 0.1, 0.6, 0.0],    # m = 0.034, below m*
                                   [0.0, 0.0, 0.0, 0.0, 0.9, 0.8, 0.3, 0.0]])   # m = 0.28, above m*
def test_task_regulates_m_to_its_target_geometrically(youbot, start):
    """Alone, the row asks ln m* - ln m to shrink by (1 - gain) per tick (slower while the speed
    limits bind): m moves monotonically to m* from either side."""
    gain, target = 0.1, 0.15
    task = wbc.ManipulabilityTask("ee", cost=1.0, gain=gain, target=target)
    controller = wbc.Controller(youbot, [task], [wbc.JointPositionLimits(), wbc.JointVelocityLimits()],
                                dt=DT, damping=1e-9)
    q = np.array(start)
    log_error = [np.log(target / manipulability(youbot, q, "ee"))]
    for _ in range(100):
        q = youbot.integrate(q, controller.step(q), DT)
        log_error.append(np.log(target / manipulability(youbot, q, "ee")))
    assert abs(log_error[0]) > 0.5
    assert abs(log_error[-1]) < 1e-3
    assert np.all(np.diff(np.abs(log_error)) < 0)
    assert np.all(np.diff(np.abs(log_error[60:])) <= -0.99 * gain * np.abs(log_error[60:-1])), "geometric once free"


def test_task_stays_finite_at_an_exact_singularity(youbot):
    task = wbc.ManipulabilityTask("ee", cost=1.0, target=0.2)
    controller = wbc.Controller(youbot, [task, wbc.PostureTask(1e-3)], dt=DT)
    v = controller.step(youbot.neutral())  # theta = 0: the arm straight up, m = 0
    assert np.all(np.isfinite(v))
    assert np.isfinite(controller.data(task).error)


@pytest.mark.parametrize("kwargs, message", [
    ({"frame": "ee", "cost": -1.0, "target": 0.1}, "cost"),
    ({"frame": "ee", "cost": 1.0, "target": -0.1}, "target"),
    ({"frame": "ee", "cost": 1.0, "gain": 0.0, "target": 0.1}, "gain"),
    ({"frame": "ee", "cost": 1.0, "target": 0.1, "rows": "linear"}, "rows"),
])
def test_task_rejects_bad_arguments(kwargs, message):
    with pytest.raises(wbc.InvalidInputError, match=message):
        wbc.ManipulabilityTask(**kwargs)
