"""The lifted form of high-DOF QPs (wbc.qp.lifting): the same minimiser over v as the dense
normal equations, written out here from the task stack and solved by two other solvers."""

import numpy as np
import pytest
import qpsolvers

import wbc
from benchmarks.peer_setups import WorldVelocityLimits
from benchmarks.scaling import chain_urdf, initial_configuration
from wbc import solvers
from wbc.qp import lifting
from wbc.tasks.task import TaskData


@pytest.fixture(scope="module")
def chain32(tmp_path_factory) -> wbc.Robot:
    path = tmp_path_factory.mktemp("chain") / "chain32.urdf"
    path.write_text(chain_urdf(32))
    return wbc.load_robot(path)


def far_target(robot: wbc.Robot, q0: np.ndarray, offset=(0.5, -0.3, 0.2)) -> np.ndarray:
    target = robot.frame_pose(q0, "ee")
    target[:3, 3] += offset
    return target


def stack(robot, q0, scale=1.0, constraints=None, **options):
    ee = wbc.FrameTask("ee", 1.0 * scale, 0.5 * scale, gain=0.5)
    ee.set_target(far_target(robot, q0))
    posture = wbc.PostureTask(1e-3 * scale, target=q0, gain=0.05)
    limits = constraints if constraints is not None else [wbc.JointPositionLimits(gain=0.5), wbc.JointVelocityLimits()]
    return wbc.Controller(robot, [ee, posture], limits, damping=1e-3 * scale, **options)


def dense_minimiser(controller: wbc.Controller, solver: str) -> np.ndarray:
    """The tick's QP in v, with H and c formed here from the controller's task stack
    (``H = A^T A`` over the [W J | W r] rows, ``c = -A^T (W r)``; its damping rows hold this
    tick's ``sqrt(max(damping, mu))``) and its limits."""
    rows = controller._task_stack.stack[:controller._task_stack.n_plain]
    WJ, Wr = rows[:, :-1], rows[:, -1]
    qp = controller._qp_v
    G = qp.G if qp.n_ineq else None
    A = qp.A if qp.n_eq else None
    # ProxQP at 1e-12: at its default 1e-10 on this unnormalised H its answer was 2e-6 off DAQP's (and
    # the controller's, which agree to 1e-13) once the error-scaled damping is in the damping rows
    settings = {**solvers.DEFAULT_SETTINGS.get(solver, {}), **({"eps_abs": 1e-12} if solver == "proxqp" else {})}
    return qpsolvers.solve_qp(WJ.T @ WJ, -WJ.T @ Wr, G, qp.h if G is not None else None, A,
                                          qp.b if A is not None else None, qp.lb, qp.ub, solver=solver, **settings)


def test_high_dof_controllers_solve_the_lifted_qp_and_small_ones_the_dense(chain32, youbot):
    q0 = initial_configuration(32)
    controller = stack(chain32, q0)
    assert controller._lifted is not None and controller._lifted.k == 6
    assert controller.qp.n == 32 + 6 and controller.qp.n_eq == 6
    small = wbc.Controller(youbot, [wbc.FrameTask("ee"), wbc.PostureTask(1e-3)], [wbc.JointVelocityLimits()])
    assert small._lifted is None  # 8 DOF, 6 dense rows
    assert stack(chain32, q0, solver="proxqp")._lifted is None  # a backend that forms its own factorisation


@pytest.mark.parametrize("solver", ["proxqp", "daqp"])
def test_the_lifted_minimiser_is_the_dense_one(chain32, solver):
    """A far target: position and speed limits active. Every tick's command equals the
    minimiser of the dense QP written out in the test (ProxQP, DAQP's Python binding)."""
    q0 = initial_configuration(32)
    controller = stack(chain32, q0)
    q, saturated = q0.copy(), 0
    for _ in range(60):
        v = controller.step(q)
        assert controller.last.success
        reference = dense_minimiser(controller, solver)
        assert np.max(np.abs(v - reference)) < 1e-6 * (1.0 + np.max(np.abs(reference)))
        saturated += bool(controller.last.active_constraints)
        q = chain32.integrate(q, v, 0.01)
    assert saturated > 10


def test_lifted_and_dense_controllers_agree_along_a_closed_loop(chain32, monkeypatch):
    """200 ticks driven by the lifted controller (world-axis speed box: general rows); at every
    tick a dense controller gets the same q: the same command and the same outcome."""
    q0 = initial_configuration(32)
    controllers = {}
    for mode, minimum in (("lifted", lifting.LIFT_MIN_DOF), ("dense", 10**6)):
        monkeypatch.setattr(lifting, "LIFT_MIN_DOF", minimum)
        controllers[mode] = stack(chain32, q0, constraints=[wbc.JointPositionLimits(gain=0.5), WorldVelocityLimits()])
        assert (controllers[mode]._lifted is not None) == (mode == "lifted")
    q, worst = q0.copy(), 0.0
    for _ in range(200):
        v = controllers["lifted"].step(q)
        reference = controllers["dense"].step(q)
        assert controllers["lifted"].last.outcome is controllers["dense"].last.outcome is wbc.Outcome.OPTIMAL
        worst = max(worst, np.max(np.abs(v - reference)) / (1.0 + np.max(np.abs(reference))))
        q = chain32.integrate(q, v, 0.01)
    assert worst < 1e-7


@pytest.mark.parametrize("scale", [1e-9, 1e-6, 1e6, 1e9])
def test_the_lifted_command_does_not_depend_on_the_cost_scale(chain32, scale):
    q0 = initial_configuration(32)
    reference = stack(chain32, q0).step(q0)
    controller = stack(chain32, q0, scale=scale)
    v = controller.step(q0)
    assert controller.last.success and controller._lifted is not None
    assert np.max(np.abs(v - reference)) < 1e-6 * (1.0 + np.max(np.abs(reference)))


class NanRow(wbc.Task, TaskData):
    """A Python task (dense: one row over every coordinate) whose target is NaN while ``broken``."""

    dim = 1
    broken = False

    def compute(self, kin, dt, jacobian, target):
        jacobian.fill(1e-3)
        target.fill(np.nan if NanRow.broken else 0.0)

    def report(self, v, errors):
        pass


def reaching(robot: wbc.Robot, q0: np.ndarray, *tasks: wbc.Task) -> wbc.Controller:
    ee = wbc.FrameTask("ee", gain=0.5)
    ee.set_target(far_target(robot, q0))
    return wbc.Controller(robot, [ee, *tasks], [wbc.JointVelocityLimits()])


def test_a_nan_in_the_stack_gives_the_zero_command(chain32):
    q0 = initial_configuration(32)
    controller = reaching(chain32, q0, NanRow(), wbc.PostureTask(1e-3))
    assert controller._lifted is not None and controller._lifted.k == 7
    controller.step(q0)
    assert controller.last.success
    NanRow.broken = True
    try:
        v = controller.step(q0)
    finally:
        NanRow.broken = False
    assert controller.last.outcome is wbc.Outcome.ZERO and np.all(v == 0.0) and "NaN" in controller.last.status
    controller.step(q0)
    assert controller.last.success


def test_diagnostics_of_a_lifted_tick_are_about_v(chain32):
    q0 = initial_configuration(32)
    controller = stack(chain32, q0)
    v = controller.step(q0)
    assert v.shape == (32,) and controller.last.max_violation <= 1e-9
    assert set(controller.last.task_errors) == {"FrameTask(ee).position", "FrameTask(ee).orientation",
                                               "PostureTask"}
    names = controller.last.active_constraints
    assert names and all(name.startswith(("JointPositionLimits", "JointVelocityLimits")) for name in names)


class FalselyDiagonal(NanRow):
    """A dense row (never NaN) whose data declares diagonal rows."""

    def bind(self, robot):
        data = super().bind(robot)
        data.diagonal_rows = True
        return data


def test_a_row_declared_diagonal_but_dense_is_refused_not_misread(chain32):
    q0 = initial_configuration(32)
    controller = reaching(chain32, q0, FalselyDiagonal())
    assert controller._lifted is not None and controller._lifted.k == 6
    v = controller.step(q0)
    assert controller.last.outcome is wbc.Outcome.ZERO and np.all(v == 0.0)


# ------------------------------------------------------------- the certificate of a lifted answer
@pytest.fixture(scope="module")
def mobile_chain24(tmp_path_factory) -> wbc.Robot:
    """A 24-DOF chain on a planar base: the base coordinates have no posture row, so in the
    lifted QP only the damping holds them (tests/test_fuzz.py's chain24)."""
    folder = tmp_path_factory.mktemp("mobile-chain")
    (folder / "chain24.urdf").write_text(chain_urdf(24))
    (folder / "chain24.toml").write_text('name = "chain24"\nurdf = "chain24.urdf"\nend_effector = "ee"\n'
                                         '[base]\nkind = "planar"\njoints = ["base_x", "base_y", "base_yaw"]\n'
                                         'max_linear_speed = 0.8\nmax_yaw_rate = 1.0\n')
    return wbc.load_robot(folder / "chain24.urdf")


def weighted_far_apart(robot: wbc.Robot, q: np.ndarray) -> wbc.Controller:
    """The fuzz suite's case: posture weights 1 and 1e12 and a pose weight 1e12 (the damping
    floor then holds the base), every arm joint on its lower limit."""
    pose = wbc.FrameTask("ee", 1e12, 1e12, gain=1.0)
    target = robot.frame_pose(q, "ee")
    target[:3, 3] += (0.15, -0.06, 0.07)
    pose.set_target(target)
    return wbc.Controller(robot, [wbc.PostureTask(1.0, gain=1.0), pose, wbc.PostureTask(1e12, gain=1.0)],
                          [wbc.JointPositionLimits(gain=1.0)], dt=0.01)


def test_an_uncertified_lifted_answer_is_replaced_by_the_dense_optimum(mobile_chain24, monkeypatch):
    """DAQP stops on this lifted QP 0.2 rad/s from the optimum (its dual is ill-conditioned);
    the certificate declines that answer and the dense QP of the tick answers instead: the
    command is the minimiser written out in the test (quadprog) and the dense controller's."""
    robot = mobile_chain24
    q = robot.neutral()
    q[3:] = robot.model.lowerPositionLimit[3:]
    lifted = weighted_far_apart(robot, q)
    assert lifted._lifted is not None
    v = lifted.step(q)
    assert lifted.last.success and lifted._lifted.dense_ticks == 1
    reference = dense_minimiser(lifted, "quadprog")
    assert np.max(np.abs(v - reference)) < 1e-6 * np.max(np.abs(reference))
    monkeypatch.setattr(lifting, "LIFT_MIN_DOF", 10**6)
    dense = weighted_far_apart(robot, q)
    assert dense._lifted is None
    np.testing.assert_allclose(v, dense.step(q), rtol=0, atol=1e-9 * np.max(np.abs(reference)))


def test_ordinary_lifted_ticks_are_certified(chain32):
    """The benchmarks' stack along a closed loop with limits active: no tick needs the dense QP."""
    q = initial_configuration(32)
    controller = stack(chain32, q)
    for _ in range(60):
        q = chain32.integrate(q, controller.step(q), controller.dt)
        assert controller.last.success
    assert controller._lifted.dense_ticks == 0


def test_the_stationarity_certificate_is_zero_at_the_optimum_only(chain32):
    """``kernels.lifted_stationarity`` against the v-problem written out here: at its
    minimiser (no limit active) ~1e-15, a step of 1e-4 away from it well above the tolerance."""
    q0 = initial_configuration(32)
    controller = stack(chain32, q0, constraints=[])
    controller.step(q0)
    lifted, nv, k = controller.qp, 32, controller._lifted.k
    n = nv + k
    D, W = np.diag(lifted.H)[:nv], np.diag(lifted.H)[nv:]
    d, c_w = lifted.c[:nv], lifted.c[nv:]
    U = lifted.C[:, :nv]  # [U -I]: the only rows without limits
    v = np.linalg.solve(np.diag(D) + U.T @ np.diag(W) @ U, -(d + U.T @ c_w))
    lam = np.zeros(n + k)  # no bound or inequality active; the equality multipliers are not read
    x = np.concatenate([v, U @ v])
    scratch = np.zeros(2 * nv)
    assert wbc.runtime.kernels.lifted_stationarity(lifted.data, x, lam, scratch, nv, k, 0, 0) < 1e-12
    x[:nv] += 1e-4 * np.sign(np.arange(nv) % 3 - 1.0)
    assert wbc.runtime.kernels.lifted_stationarity(lifted.data, x, lam, scratch, nv, k, 0, 0) > 1e-5
