"""The compiled DAQP solve leaves out the trailing rows every x satisfies (wbc.runtime.kernels._inert_rows):
answers against a second solve given only the live rows, KKT conditions written out on the whole
QP, the warm start in the QP's row order, the inert rows never reaching DAQP."""

import daqp
import numpy as np
import pytest

import wbc
from test_daqp_native import assert_kkt, fill_random
from wbc.qp.problem import QP
from wbc.runtime import kernels
from wbc.solvers import DaqpBackend
from wbc.solvers.daqp import abi as daqp_abi
from wbc.solvers.daqp import probe as daqp_probe
from wbc.solvers.daqp.native import NativeWorkspace


def make_inert(rng: np.random.Generator, qp: QP) -> np.ndarray:
    """Zero some rows with bounds that hold 0 (inequality rows as CollisionAvoidance's: upper 1,
    lower -inf; or a two-sided range holding 0; equality rows b = 0): scattered ones, and often a
    trailing run of rows; the general rows' mask of those made inert."""
    n, p = qp.n, qp.n_ineq
    inert = rng.random(qp.C.shape[0]) < 0.3
    if rng.random() < 0.7:
        inert[qp.C.shape[0] - int(rng.integers(1, qp.C.shape[0] + 1)):] = True
    for i in np.flatnonzero(inert):
        qp.C[i] = 0.0
        if i < p and rng.random() < 0.5:
            qp.lower[n + i] = -rng.uniform(0.0, 1.0)
        elif i < p:
            qp.upper[n + i] = 1.0
    return inert


def trailing(inert: np.ndarray) -> np.ndarray:
    """The mask of the trailing run of inert rows (those DAQP is not given)."""
    live = np.flatnonzero(~inert)
    mask = np.zeros_like(inert)
    mask[live[-1] + 1 if live.size else 0:] = True
    return mask


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
    start never holds a trailing inert row (left out) active, nor, after a tick DAQP solved,
    DAQP's mark of a zero row it was given, and the equality rows keep their state."""
    library = daqp_probe.native()
    solved = left_out_count = 0
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
                states, left_out = workspace.working_set[rows], trailing(inert)
                inequality = np.arange(p + e) < p
                left_out_count += left_out.sum()
                marked = states & kernels.DAQP_SENSE_ZERO_ROW != 0  # DAQP's mark of a zero row it was given
                assert not np.any(states[left_out & inequality] & kernels.DAQP_SENSE_ACTIVE)
                assert not np.any(states[marked] & kernels.DAQP_SENSE_ACTIVE)
                if workspace.iterations > 0:  # DAQP solved this tick: it never saw the rows left out
                    assert not np.any(marked[left_out])
                # (when a first try answered, a mark of an earlier tick stays until DAQP's next update re-reads
                # the row: tests/test_daqp_inert_rows.py::test_a_zero_row_before_a_live_row_leaves_the_first_tries_open)
                equality = ~inequality & ~marked
                assert np.all(states[equality] & daqp_abi.SENSE_EQUALITY == daqp_abi.SENSE_EQUALITY)
    assert solved >= 300
    assert left_out_count > 300 or not warm_start


def test_inert_rows_leave_the_unconstrained_first_try_open(rng):
    """A warm workspace whose QP has inert rows and whose unconstrained minimiser meets every
    live row answers without DAQP (0 iterations) on the next solve: the trailing inert rows
    reached neither DAQP's working set nor its zero-row marks."""
    library = daqp_probe.native()
    qp = QP(4, 6)
    fill_random(rng, qp)
    qp.C[3:] = 0.0  # trailing inert rows: 0 <= h
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


@pytest.mark.parametrize("working_set_first", [False, True])
def test_a_zero_row_before_a_live_row_leaves_the_first_tries_open(rng, working_set_first):
    """A zero row before a live row reaches DAQP, which marks it (DAQP_SENSE_ZERO_ROW, with its
    immutable bit) in its warm working set: the mark is not an active constraint. The unconstrained
    minimiser answers without DAQP once it meets every row; with working_set_first, a set of one
    live row answers the next tick by the try (the answer and multipliers of the KKT conditions).
    A zero row whose bounds exclude 0 is caught by the answer check (DAQP then solves: infeasible)."""
    library = daqp_probe.native()
    qp = QP(4, 3)
    fill_random(rng, qp)
    qp.lb[...], qp.ub[...] = -1e3, 1e3
    qp.C[:2] = 0.0  # rows 0, 1 zero (0 <= h), row 2 live: DAQP is given all three
    qp.h[:2] = 1.0
    qp.C[2] = 0.0
    qp.C[2, 1] = 1.0
    free = np.linalg.solve(qp.H, -qp.c)
    qp.h[2] = free[1] - 0.1  # the first solve meets row 2
    workspace = NativeWorkspace(library, qp, {}, warm_start=True, working_set_first=working_set_first)
    assert workspace.solve()[0] == 1 and workspace.iterations > 0 and workspace.lam[qp.n + 2] > 0.0
    marks = workspace.working_set[qp.n:qp.n + 2]
    assert np.all(marks & kernels.DAQP_SENSE_ZERO_ROW)  # what DAQP 0.11 does with a zero row it is given
    if working_set_first:  # the same set, another cost: the try answers
        qp.c[...] += 1e-3 * rng.standard_normal(qp.n)
        assert workspace.solve()[0] == 1 and workspace.iterations == 0
        assert_kkt(qp, workspace.x, workspace.lam)
        assert workspace.x[1] == pytest.approx(qp.h[2], abs=1e-12)
    qp.h[2] += 1.0  # row 2 loose: the unconstrained minimiser is feasible
    free = np.linalg.solve(qp.H, -qp.c)
    assert workspace.solve()[0] == 1 and workspace.iterations > 0  # DAQP drops row 2 from its set
    assert workspace.working_set[qp.n + 2] & kernels.DAQP_SENSE_ACTIVE == 0
    assert np.all(workspace.working_set[qp.n:qp.n + 2] & kernels.DAQP_SENSE_ZERO_ROW)  # the marks stay
    assert workspace.solve()[0] == 1 and workspace.iterations == 0  # the first try answers
    np.testing.assert_allclose(workspace.x, free, rtol=0, atol=1e-12)
    assert not workspace.lam.any()
    qp.h[0] = -1.0  # zero row 0 now asks 0 <= -1: no x meets it
    exitflag, defect, _ = workspace.solve()
    assert exitflag < 1 or defect > 0.0  # never accepted


def test_collision_commands_match_another_solver():
    """youbot_circle's stack with CollisionAvoidance (self-collision and a sphere the arm passes
    close to; most rows inert every tick) on the native DAQP tick against quadprog given every
    row: the same commands along a closed loop (the constraint's rows are the QP's last)."""
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


def _row_zero_then_binding() -> tuple[QP, list[tuple[float, float]]]:
    """min 1/2 |x - (1, 1)|^2, x <= 0.8, with row 0 (x0 + x1 <= h0) zero, then binding; row 1 live after it."""
    qp = QP(2, 2)
    qp.H[...] = np.eye(2)
    qp.c[...] = (-1.0, -1.0)
    qp.lb[...], qp.ub[...] = -10.0, 0.8  # the bounds bind while row 0 is zero: DAQP solves
    qp.C[1] = (1.0, -1.0)
    qp.h[1] = 5.0
    return qp, [(0.0, 1.0), (1.0, 0.5), (0.0, 1.0), (1.0, 0.5)]  # (row 0's coefficient, h0) per solve


@pytest.mark.parametrize("native", [True, False])
def test_a_row_that_was_zero_binds_again_on_a_warm_workspace(native, monkeypatch):
    """A zero row DAQP was given (not trailing: a live row follows) is marked by DAQP as
    ignored; when it is nonzero again the warm update must bring it back (UPDATE_M, also in the
    binding's update): the answer is the projection onto x0 + x1 <= 0.5, not (0.8, 0.8). The
    native workspace and DaqpBackend on DAQP's binding."""
    if not native:
        daqp_abi._load.cache_clear()
        daqp_probe._probe_failure.cache_clear()
        monkeypatch.setattr(daqp_abi.importlib.metadata, "version", lambda name: "0.99.0")
    try:
        qp, ticks = _row_zero_then_binding()
        backend = DaqpBackend()
        assert backend.native == native
        for coefficient, h0 in ticks:
            qp.C[0] = coefficient
            qp.h[0] = h0
            solution = backend.solve(qp)
            assert solution.success
            expected = (0.25, 0.25) if coefficient else (0.8, 0.8)
            np.testing.assert_allclose(solution.x, expected, rtol=0, atol=1e-12)
    finally:
        daqp_abi._load.cache_clear()
        daqp_probe._probe_failure.cache_clear()
