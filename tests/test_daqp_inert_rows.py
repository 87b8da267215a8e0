"""The compiled DAQP solve leaves out the rows every x satisfies (wbc.runtime.kernels._inert_rows):
answers against a second solve given only the live rows, KKT conditions written out on the whole
QP, the warm start in the QP's row order, the inert rows never reaching DAQP."""

import daqp
import numpy as np
import pytest

import wbc
from test_daqp_native import assert_kkt, fill_random
from wbc.qp.problem import QP
from wbc.runtime import kernels
from wbc.solvers.daqp import abi as daqp_abi
from wbc.solvers.daqp import probe as daqp_probe
from wbc.solvers.daqp.native import NativeWorkspace

#: DAQP's own mark of a zero row it was given (constants.h DAQP_ZERO_ROW)
DAQP_ZERO_ROW = 2048


def make_inert(rng: np.random.Generator, qp: QP) -> np.ndarray:
    """Zero some rows with bounds that hold 0 (about half the inequality rows -- as
    CollisionAvoidance's: upper 1, lower -inf, or a two-sided range -- and some equality rows);
    the general rows' mask of those made inert."""
    n, p = qp.n, qp.n_ineq
    inert = rng.random(qp.C.shape[0]) < 0.5
    for i in np.flatnonzero(inert):
        qp.C[i] = 0.0
        if i < p and rng.random() < 0.5:
            qp.lower[n + i] = -rng.uniform(0.0, 1.0)
        elif i < p:
            qp.upper[n + i] = 1.0
    return inert


def live_answer(qp: QP, inert: np.ndarray) -> tuple[np.ndarray, int]:
    """DAQP's binding (its own workspace, another code path) on the QP without the inert rows."""
    n = qp.n
    keep = np.concatenate([np.ones(n, dtype=bool), ~inert])
    sense = np.zeros(qp.n + qp.n_ineq + qp.n_eq, dtype=np.int32)
    sense[n + qp.n_ineq:] = daqp_abi.SENSE_EQUALITY
    x, _, exitflag, _ = daqp.solve(qp.H, qp.c, qp.C[~inert], qp.upper[keep], qp.lower[keep], sense[keep])
    return x, exitflag


@pytest.mark.parametrize(("warm_start", "working_set_first"), [(True, False), (False, False), (True, True)])
def test_answers_are_those_of_the_live_rows_alone(rng, warm_start, working_set_first):
    """Random QPs with inert rows that change from tick to tick, 6 ticks each on one workspace:
    the answer is that of DAQP's binding given only the live rows, the same exit status, the
    multipliers of the inert rows 0 and the KKT conditions of the whole QP hold; the warm
    start never holds an inert row active (nor DAQP's mark of a zero row it was given)."""
    library = daqp_probe.native()
    solved = 0
    for _ in range(150):
        n, p, e = int(rng.integers(1, 10)), int(rng.integers(1, 12)), int(rng.integers(0, 3))
        e = min(e, n - 1)
        qp = QP(n, p, e)
        workspace = NativeWorkspace(library, qp, {}, warm_start=warm_start, working_set_first=working_set_first)
        for _tick in range(6):
            fill_random(rng, qp)
            inert = make_inert(rng, qp)
            exitflag, defect, _ = workspace.solve()
            reference, reference_flag = live_answer(qp, inert)
            assert (exitflag >= 1) == (reference_flag >= 1), (exitflag, reference_flag)
            rows = slice(n, None)
            assert workspace.problem.m == n + p + e and workspace.work.m == n + p + e  # restored after the solve
            if exitflag < 1:
                workspace.reset()
                continue
            solved += 1
            np.testing.assert_allclose(workspace.x, reference, rtol=0, atol=1e-8)
            assert defect == kernels.qp_defect(qp.data, workspace.x) <= 1e-9
            assert np.all(workspace.lam[rows][inert] == 0.0)
            assert_kkt(qp, workspace.x, workspace.lam)
            if warm_start:
                states = workspace.working_set[rows]
                inequality = np.arange(p + e) < p
                assert not np.any(states[inert & inequality] & kernels.DAQP_SENSE_ACTIVE)
                assert not np.any(states[inert] & DAQP_ZERO_ROW)  # DAQP never saw them
                assert np.all(states[~inequality] & daqp_abi.SENSE_EQUALITY == daqp_abi.SENSE_EQUALITY)
    assert solved >= 300


def test_inert_rows_leave_the_unconstrained_first_try_open(rng):
    """A warm workspace whose QP has inert rows and whose unconstrained minimiser meets every
    live row answers without DAQP (0 iterations) on the next solve: the inert rows reached
    neither DAQP's working set nor its zero-row marks (which would count as active states)."""
    library = daqp_probe.native()
    qp = QP(4, 6)
    fill_random(rng, qp)
    qp.C[3:] = 0.0  # inert: 0 <= h
    qp.h[...] = 1.0
    qp.lb[...], qp.ub[...] = -1e3, 1e3
    qp.C[:3] = 0.0
    qp.C[0, 0] = 1.0
    qp.h[0] = np.linalg.solve(qp.H, -qp.c)[0] - 0.1  # the first solve meets row 0
    workspace = NativeWorkspace(library, qp, {}, warm_start=True)
    assert workspace.solve()[0] == 1 and workspace.iterations > 0
    assert workspace.lam[qp.n] > 0.0
    qp.h[0] += 1.0  # row 0 loose: the unconstrained minimiser is feasible
    assert workspace.solve()[0] == 1 and workspace.iterations > 0  # DAQP drops row 0 from its set
    assert not np.any(workspace.working_set & ~kernels.DAQP_SENSE_LOWER)
    assert workspace.solve()[0] == 1 and workspace.iterations == 0  # the first try answers
    np.testing.assert_allclose(workspace.x, np.linalg.solve(qp.H, -qp.c), rtol=0, atol=1e-12)


def test_collision_commands_match_another_solver():
    """youbot_circle's stack with CollisionAvoidance (self-collision and a sphere the arm passes
    close to; most rows inert every tick) on the native DAQP tick against quadprog given every
    row: the same commands along a closed loop."""
    robot = wbc.load_robot("youbot")
    q0 = robot.neutral()
    ee = robot.frame_pose(q0, "ee")[:3, 3]
    sphere = wbc.Sphere(ee + (0.15, 0.0, -0.05), 0.05)

    def controller(solver):
        avoidance = wbc.CollisionAvoidance([sphere], self_collision=True)
        task = wbc.FrameTask("ee", position_cost=1.0, orientation_cost=0.0, gain=0.5, max_speed=0.5)
        pose = robot.frame_pose(q0, "ee")
        pose[:3, 3] = ee + (0.3, 0.0, -0.1)
        task.set_target(pose)
        limits = [wbc.JointPositionLimits(), wbc.JointVelocityLimits()]
        return wbc.Controller(robot, [task, wbc.PostureTask(cost=1e-3, gain=0.05)],
                              [*limits, avoidance], solver=solver), avoidance

    (native, avoidance), (other, _) = controller("daqp"), controller("quadprog")
    data = native.data(avoidance)
    q, inert_ticks = q0, 0
    for _ in range(150):
        v = native.step(q)
        np.testing.assert_allclose(v, other.step(q), rtol=0, atol=1e-7)
        inert_ticks += len(data.active_labels()) + data.corners < data.n_inequalities
        q = robot.integrate(q, v, 0.01)
    assert inert_ticks == 150
