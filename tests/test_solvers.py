"""Every installed QP solver returns the same command on QPs recorded from real ticks."""

import os
import subprocess
import sys

import numpy as np
import pytest

import wbc
from conftest import NEUTRAL, TASKS
from wbc.app.scenario import load_scenario
from wbc.qp.problem import QP
from wbc.solvers import make_solver

AGREEMENT = 1e-6


def record_qps(path, every=40):
    scenario = load_scenario(path)
    controller = scenario.make_controller("daqp")
    q, qps = scenario.q0.copy(), []
    for k in range(scenario.ticks):
        scenario.reference_task.set_target(*scenario.reference(k * scenario.dt))
        v = controller.step(q)
        if k % every == 0:
            qps.append((controller.qp.copy(), v.copy(), len(controller.last.active_constraints)))
        q = scenario.robot.integrate(q, v, scenario.dt)
    return qps


@pytest.fixture(scope="module")
def recorded():
    return record_qps(TASKS / "youbot_circle.toml") + record_qps(TASKS / "youbot_reach.toml")


def test_recorded_qps_exercise_active_constraints(recorded):
    assert len(recorded) >= 50
    assert sum(active > 0 for _, _, active in recorded) >= 5


def test_every_installed_solver_is_in_the_run():
    assert "daqp" in wbc.available_solvers()
    assert {"proxqp", "osqp"} <= set(wbc.available_solvers())


def _kkt_check(qp, x):
    """x is feasible (1e-7) for the recorded QP; cheap sanity check independent of any solver."""
    assert np.all(x <= qp.ub + 1e-7) and np.all(x >= qp.lb - 1e-7)
    if qp.n_ineq:
        assert np.all(qp.G @ x <= qp.h + 1e-7)


def _cost(qp, x):
    """The recorded QP's objective 1/2 x'Hx + c'x."""
    return 0.5 * x @ qp.H @ x + qp.c @ x


@pytest.mark.parametrize("name", wbc.available_solvers())
def test_solver_agrees_with_daqp_on_recorded_ticks(recorded, name):
    solver = make_solver(name)
    for qp, v_daqp, _ in recorded:
        solution = solver.solve(qp)
        assert solution.success, f"{name}: {solution.status}"
        _kkt_check(qp, solution.x)
        np.testing.assert_allclose(solution.x, v_daqp, rtol=0, atol=AGREEMENT, err_msg=name)


def test_reference_solutions_are_optimal(recorded):
    """daqp's answers satisfy first-order optimality, checked by projected gradient."""
    for qp, v, _ in recorded:
        _kkt_check(qp, v)
        gradient = qp.H @ v + qp.c
        # any feasible descent direction must be blocked: a small projected step cannot lower the cost
        for step in (1e-4, 1e-2):
            trial = np.clip(v - step * gradient, qp.lb, qp.ub)
            if qp.n_ineq and np.any(qp.G @ trial > qp.h + 1e-12):
                continue
            assert _cost(qp, trial) >= _cost(qp, v) - 1e-12


@pytest.mark.parametrize("name", wbc.available_solvers())
def test_every_installed_solver_runs_the_controller_by_name(youbot, name):
    task = wbc.FrameTask("ee", 1.0, 0.5, gain=0.5)
    q = np.array([0, 0, 0, 0, 0.5, 1.0, 1.2, 0.0])
    target = youbot.frame_pose(q, "ee")
    target[:3, 3] += [0.05, -0.03, 0.02]
    task.set_target(target)
    controller = wbc.Controller(youbot, [task], [wbc.JointPositionLimits(), wbc.JointVelocityLimits()], solver=name)
    for _ in range(100):
        q = youbot.integrate(q, controller.step(q), controller.dt)
    assert controller.last.solver == name
    assert controller.last.task_errors["FrameTask(ee).position"] < 1e-4


def _quiet_qps():
    """Unconstrained optimum (nothing active), an active row, and an infeasible QP."""
    free, active, infeasible = QP(3, 1, 0), QP(3, 1, 0), QP(3, 1, 0)
    for qp, c, h in ((free, [0.1, -0.2, 0.05], 5.0), (active, [1.0, -2.0, 0.5], 0.2), (infeasible, [0.0] * 3, -9.0)):
        qp.H[:] = np.eye(3)
        qp.c[:] = c
        qp.lb[:], qp.ub[:] = -1.0, 1.0
        qp.G[:], qp.h[:] = [[1.0, 1.0, 1.0]], h
    return free, active, infeasible


@pytest.mark.parametrize("name", wbc.available_solvers())
def test_solvers_print_nothing(capfd, name):
    """A library in a control loop is silent, down to the file descriptors (C printf)."""
    solver = make_solver(name)
    for _ in range(3):
        for qp in _quiet_qps():
            solver.solve(qp)
    out, err = capfd.readouterr()
    assert out == "" and err == ""


QUIET_PROBE = r"""
import sys

import numpy as np
import wbc

name = sys.argv[1]
robot = wbc.load_robot("youbot")
ee = wbc.FrameTask("ee", position_cost=1.0, orientation_cost=0.5, gain=0.5)
controller = wbc.Controller(robot, [ee, wbc.PostureTask(cost=1e-3, gain=0.05)],
                            [wbc.JointPositionLimits(), wbc.JointVelocityLimits(), wbc.MecanumWheelLimits()],
                            solver=name, dt=0.01)
q = np.array([0, 0, 0, 0, 0.5, 1.0, 1.2, 0.0])
target = robot.frame_pose(q, "ee")
target[:3, 3] += [1.0, 0.5, 0.6]  # far and partly out of reach: speed limits active
ee.set_target(target)
for _ in range(20):
    q = robot.integrate(q, controller.step(q), controller.dt)
"""


@pytest.mark.parametrize("name", wbc.available_solvers())
def test_a_fresh_process_prints_nothing_with_any_backend(name):
    """From ``import wbc`` to the last tick, nothing reaches fd 1 or 2 in a new process, where a
    backend's first use happens (highspy 1.16 prints a banner on stdout at its first Highs()):
    wbc runs that first use silenced when the backend is built (wbc.core.quiet)."""
    # the kernels compiled beforehand: a cold numba cache is announced on stderr (once after an install)
    subprocess.run([sys.executable, "-c", "from wbc.app.cli import main; main(['warmup'])"], capture_output=True,
                   check=True, timeout=600)
    result = subprocess.run([sys.executable, "-c", QUIET_PROBE, name], capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr
    assert result.stdout == "" and result.stderr == ""


CRASH_PROBE = r"""
import sys

import numpy as np
from wbc.qp.problem import QP
from wbc.solvers import make_solver

solver = make_solver(sys.argv[1])
rng = np.random.default_rng(0)
for ratio in 10.0 ** np.arange(12, -13, -3):
    for rows in (0, 3, 12):
        qp = QP(8, rows, 0)
        qp.H[:] = np.diag([1e11, 1e-3, 1.0, 1.0, 1.0, 1.0, 0.0, 1e-12])  # singular, condition 1e23
        qp.c[:] = ratio * rng.normal(size=8)
        qp.lb[:], qp.ub[:] = -1.0, 1.0
        qp.lb[6] = qp.ub[6] = 0.0  # a fixed variable
        if rows:
            G = rng.normal(size=(rows, 8))
            G[rows // 2:] = G[: rows - rows // 2]  # duplicated rows: degenerate
            qp.G[:], qp.h[:] = G, G @ rng.choice([-1.0, 1.0], 8)  # many rows through one vertex
        solver.solve(qp)
print("survived")
"""


SLOW_ON_CRASH_PROBE = {"proxqp"}  # runs to its iteration limit on these QPs: 5-8 s


@pytest.mark.parametrize("name", [pytest.param(name, marks=pytest.mark.slow) if name in SLOW_ON_CRASH_PROBE else name
                                  for name in wbc.available_solvers()])
def test_no_backend_kills_the_process_on_ill_conditioned_qps(name):
    """Backends abort in C (HiGHS has been reported to abort with malloc(): invalid size):
    run ill-conditioned / degenerate QPs in a child process with wbc's default settings."""
    child = subprocess.run([sys.executable, "-c", CRASH_PROBE, name], capture_output=True, text=True, timeout=300,
                           cwd=NEUTRAL)
    assert child.returncode == 0, f"{name} killed the process ({child.returncode}): {child.stderr[-2000:]}"
    assert child.stdout.strip().endswith("survived")


def test_a_daqp_that_does_not_import_is_an_unknown_solver(tmp_path):
    """A daqp package that is there but fails to import (its shared library missing) is refused by
    name, as qpsolvers refuses it -- not an ImportError from inside the backend."""
    (tmp_path / "daqp").mkdir()
    (tmp_path / "daqp" / "__init__.py").write_text('raise ImportError("libdaqp.so: cannot open shared object file")\n')
    code = ("import wbc\n"
            "try:\n    wbc.solvers.make_solver('daqp')\n"
            "except wbc.UnknownSolverError as error:\n    print('refused:', error)\n")
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300,
                            env={**os.environ, "PYTHONPATH": os.pathsep.join([str(tmp_path), *sys.path])})
    assert result.returncode == 0, result.stderr
    assert result.stdout.startswith("refused: unknown or uninstalled QP solver 'daqp'"), result.stdout
