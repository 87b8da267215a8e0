"""The shortcuts of the control tick compute what the plain formulas compute."""

import daqp
import numpy as np
import pytest

import wbc
from conftest import TASKS, random_youbot_configurations
from wbc.app.scenario import load_scenario
from wbc.qp.problem import QP
from wbc.solvers import DaqpBackend


def random_qp(rng, qp: QP) -> None:
    """Fill ``qp`` in place with a feasible strictly convex QP (rows, equalities, bounds)."""
    n = qp.n
    M = rng.standard_normal((n, n))
    qp.H[:] = M @ M.T + 0.1 * np.eye(n)
    qp.c[:] = rng.standard_normal(n)
    qp.C[:] = rng.standard_normal(qp.C.shape)
    x0 = rng.uniform(-0.5, 0.5, n)  # strictly feasible point
    qp.ub[:], qp.lb[:] = x0 + rng.uniform(0.1, 1.0, n), x0 - rng.uniform(0.1, 1.0, n)
    qp.h[:] = qp.G @ x0 + rng.uniform(0.0, 0.5, qp.n_ineq)
    qp.b[:] = qp.A @ x0
    qp.sync_equalities()


def cold_daqp(qp: QP) -> np.ndarray:
    sense = np.zeros(qp.n + qp.n_ineq + qp.n_eq, dtype=np.int32)
    sense[qp.n + qp.n_ineq:] = 5
    x, _, exitflag, _ = daqp.solve(qp.H.copy(), qp.c.copy(), qp.C.copy(), qp.upper.copy(), qp.lower.copy(), sense)
    assert exitflag == 1
    return x


@pytest.mark.parametrize("warm_start", [True, False])
@pytest.mark.parametrize("shape", [(6, 0, 0), (6, 5, 0), (6, 4, 2)])
def test_daqp_workspace_sees_every_in_place_change_of_the_qp(rng, shape, warm_start):
    """The backend only calls update(H): c, rows and bounds must be read through its pointers."""
    backend = DaqpBackend({"warm_start": warm_start})
    qp = QP(*shape)
    for _ in range(30):
        random_qp(rng, qp)
        solution = backend.solve(qp)
        assert solution.success
        np.testing.assert_allclose(solution.x, cold_daqp(qp), rtol=0, atol=1e-9)


def test_daqp_workspace_follows_the_qp_object_it_is_given(rng):
    """Two QPs of one shape through one backend: the workspace must not keep reading the first."""
    backend = DaqpBackend()
    first, second = QP(5, 3, 1), QP(5, 3, 1)
    random_qp(rng, first)
    random_qp(rng, second)
    for qp in (first, second, first, second):
        np.testing.assert_allclose(backend.solve(qp).x, cold_daqp(qp), rtol=0, atol=1e-9)


@pytest.mark.parametrize("segment", ["H", "c", "C", "upper", "lower"])
def test_nan_screen_finds_a_nan_anywhere_and_nothing_else(segment):
    qp = QP(4, 2, 1)
    qp.H[:] = np.eye(4)
    qp.C[:] = 1e200  # huge but finite
    assert np.isinf(qp.upper).any() and not qp.has_nan()
    getattr(qp, segment).reshape(-1)[-1] = np.nan
    assert qp.has_nan()


def test_one_constraint_instance_can_serve_two_controllers(youbot, rng):
    """Constraint objects cache views into the controller's buffers: sharing them between two
    controllers stepped alternately must give each the command it gets alone."""
    scenario = load_scenario(TASKS / "youbot_reach.toml")
    barrier = wbc.ManipulabilityBarrier("ee", min_value=0.05, gain=0.3)
    shared = scenario.constraints + [barrier]
    task = wbc.FrameTask("ee", 1.0, 0.5)
    task.set_target(youbot.frame_pose(youbot.neutral(), "ee"))

    def controller(constraints):
        return wbc.Controller(youbot, [task, wbc.PostureTask(1e-2)], constraints, dt=scenario.dt)

    first, second = controller(shared), controller(shared)
    configurations = random_youbot_configurations(rng, 20)
    # arm joints just outside a limit: the position dampers decide the command
    side = rng.integers(0, 2, size=(20, 5)).astype(bool)
    configurations[:, 3:] = np.where(side, youbot.upper[3:] + 0.05, youbot.lower[3:] - 0.05)
    for q1, q2 in configurations.reshape(10, 2, 8):
        v1, v2 = first.step(q1), second.step(q2)
        alone = load_scenario(TASKS / "youbot_reach.toml").constraints
        # cold vs warm-started DAQP: equal up to rounding; a stale view would be off by O(1)
        for v, q in ((v1, q1), (v2, q2)):
            fresh = controller(alone + [wbc.ManipulabilityBarrier("ee", 0.05, 0.3)]).step(q)
            np.testing.assert_allclose(v, fresh, rtol=0, atol=1e-9)


def test_heading_rows_are_the_base_frame_limits(youbot, rng):
    """Base speed rows bound the base-frame twist and wheel rows give the wheel speeds, at any heading."""
    speed, wheels = wbc.JointVelocityLimits(), wbc.MecanumWheelLimits()
    controller = wbc.Controller(youbot, [wbc.PostureTask(1.0)], [speed, wheels])
    blocks = {type(c.constraint): rows for c, rows in controller._constraint_blocks}
    for q in random_youbot_configurations(rng, 10):
        controller.step(q)
        v = rng.standard_normal(8)
        vx, vy, _ = youbot.base_twist(q, v)
        np.testing.assert_allclose(blocks[wbc.JointVelocityLimits].G @ v, [vx, -vx, vy, -vy], atol=1e-12)
        rates = youbot.wheel_speeds(q, v)
        np.testing.assert_allclose(blocks[wbc.MecanumWheelLimits].G @ v, np.concatenate([rates, -rates]),
                                   atol=1e-12)
