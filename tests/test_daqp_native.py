"""DAQP through its C API from compiled code (wbc.solvers.daqp.abi, wbc.solvers.daqp.native): the layout is
checked on the installed build, the answers are DAQP's Python binding's (an independent
code path into the same solver) and optimal by a second solver, and the controller's
commands are the same on both paths."""

import gc
import weakref
from pathlib import Path

import daqp
import numpy as np
import pytest

import wbc
from conftest import TASKS
from wbc.app.scenario import load_scenario
from wbc.qp.problem import QP
from wbc.runtime import kernels
from wbc.runtime.kernels import native_qp
from wbc.solvers import DaqpBackend
from wbc.solvers.daqp import abi as daqp_abi
from wbc.solvers.daqp import probe as daqp_probe
from wbc.solvers.daqp.native import NativeWorkspace
from wbc.tasks.task import TaskData


def random_qp(rng: np.random.Generator, n: int, n_ineq: int, n_eq: int) -> QP:
    """A strictly convex QP whose bounds hold x = 0 (feasible unless the equalities say otherwise)."""
    qp = QP(n, n_ineq, n_eq)
    fill_random(rng, qp)
    return qp


def fill_random(rng: np.random.Generator, qp: QP) -> None:
    n, p = qp.n, qp.n_ineq
    J = rng.standard_normal((n + 2, n))
    qp.H[...] = J.T @ J + 1e-3 * np.eye(n)
    qp.c[...] = 3.0 * rng.standard_normal(n)
    qp.C[...] = rng.standard_normal(qp.C.shape)
    qp.ub[...] = rng.uniform(0.1, 2.0, n)
    qp.lb[...] = -rng.uniform(0.1, 2.0, n)
    qp.h[...] = rng.uniform(0.0, 1.0, p)
    qp.b[...] = 0.0
    qp.sync_equalities()


def binding_answer(qp: QP) -> tuple[np.ndarray, int]:
    sense = np.zeros(qp.n + qp.n_ineq + qp.n_eq, dtype=np.int32)
    sense[qp.n + qp.n_ineq:] = daqp_abi.SENSE_EQUALITY
    x, _, exitflag, _ = daqp.solve(qp.H, qp.c, qp.C, qp.upper, qp.lower, sense)
    return x, exitflag


def assert_kkt(qp: QP, x: np.ndarray, lam: np.ndarray) -> None:
    """Optimality written out: ``H x + c + lam_bounds + C^T lam_rows = 0``, a positive
    multiplier only on a constraint at its upper bound, a negative one at its lower bound."""
    scale = 1.0 + np.max(np.abs(qp.c)) + np.max(np.abs(qp.H @ x))
    stationarity = qp.H @ x + qp.c + lam[:qp.n] + qp.C.T @ lam[qp.n:]
    assert np.max(np.abs(stationarity)) < 1e-9 * scale
    values = np.concatenate([x, qp.C @ x])
    assert np.all(np.abs(values - qp.upper)[lam > 1e-12] < 1e-9)
    assert np.all(np.abs(values - qp.lower)[lam < -1e-12] < 1e-9)


def test_the_installed_daqp_passes_the_layout_probe():
    version = daqp_abi.importlib.metadata.version("daqp")
    assert version.startswith(daqp_abi.SUPPORTED_VERSIONS), f"pyproject's daqp bound lets in {version}"
    assert daqp_probe.unavailable_reason() is None
    assert DaqpBackend().native


def test_the_probe_refuses_a_layout_the_kernels_do_not_share(monkeypatch):
    library = daqp_probe.native()
    monkeypatch.setattr(kernels, "DAQP_RESULT_EXITFLAG", kernels.DAQP_RESULT_EXITFLAG + 1)
    assert "result exit flag" in daqp_probe.probe(library)
    monkeypatch.undo()
    assert daqp_probe.probe(library) is None


def test_an_unknown_daqp_release_uses_the_binding(monkeypatch):
    daqp_abi._load.cache_clear()
    daqp_probe._probe_failure.cache_clear()
    monkeypatch.setattr(daqp_abi.importlib.metadata, "version", lambda name: "0.99.0")
    try:
        assert "daqp 0.99.0" in daqp_probe.unavailable_reason()
        backend = DaqpBackend()
        assert not backend.native
        qp = random_qp(np.random.default_rng(1), 5, 3, 1)
        solution = backend.solve(qp)
        assert solution.success and np.allclose(solution.x, binding_answer(qp)[0], atol=1e-10)
    finally:
        daqp_abi._load.cache_clear()
        daqp_probe._probe_failure.cache_clear()


@pytest.mark.parametrize("warm_start", [True, False])
def test_native_answers_are_the_bindings_and_optimal(rng, warm_start):
    """200 random QPs, 5 ticks each on one workspace (warm or cold): the binding's answer and
    exit status; the answer and multipliers satisfy the KKT conditions; the defect written
    is the QP's."""
    library = daqp_probe.native()
    infeasible = 0
    for _ in range(200):
        n, p, e = int(rng.integers(1, 12)), int(rng.integers(0, 6)), int(rng.integers(0, 3))
        qp = random_qp(rng, n, p, e)
        workspace = NativeWorkspace(library, qp, {}, warm_start=warm_start)
        for _tick in range(5):
            fill_random(rng, qp)
            exitflag, defect, elapsed = workspace.solve()
            reference, reference_flag = binding_answer(qp)
            assert (exitflag >= 1) == (reference_flag >= 1), (exitflag, reference_flag)
            if exitflag < 1:
                infeasible += 1
                workspace.reset()
                continue
            assert np.max(np.abs(workspace.x - reference)) < 1e-8
            assert defect == kernels.qp_defect(qp.data, workspace.x) and defect < 1e-9
            assert 0.0 < elapsed < 0.1
            assert_kkt(qp, workspace.x, workspace.lam)
    assert infeasible < 200  # the equalities with bounds make some infeasible: both paths must say so


@pytest.mark.parametrize("warm_start", [True, False])
def test_a_feasible_unconstrained_minimiser_is_the_answer_without_daqp(rng, warm_start):
    """A QP without equality rows whose minimiser -H^-1 c (numpy's solve, written out here)
    lies inside every bound and row is answered by it when DAQP's working set is empty: 0 DAQP
    iterations, multipliers 0, defect 0, the binding's answer. Pushed out of the box (c scaled
    up) DAQP answers (iterations > 0, a bound active, KKT); back inside, a warm DAQP answers once
    (its working set held the bounds), then the minimiser again. With an equality row DAQP answers."""
    library = daqp_probe.native()
    for _ in range(50):
        n, p = int(rng.integers(1, 10)), int(rng.integers(0, 5))
        qp = random_qp(rng, n, p, 0)
        qp.C[...] = 0.1 * rng.standard_normal(qp.C.shape)
        qp.h[...] = 10.0  # the rows far away: only the bounds can bind
        inside_c = qp.H @ rng.uniform(-0.05, 0.05, n)  # the minimiser -H^-1 c well inside the box
        workspace = NativeWorkspace(library, qp, {}, warm_start=warm_start)
        limits_were_active = False
        for c in (inside_c, 1000.0 * inside_c, inside_c, inside_c):
            qp.c[...] = c
            exitflag, defect, elapsed = workspace.solve()
            minimiser = np.linalg.solve(qp.H, -qp.c)
            inside = np.all(minimiser <= qp.ub) and np.all(minimiser >= qp.lb) and np.all(qp.C @ minimiser <= qp.h)
            assert exitflag == 1 and 0.0 < elapsed < 0.1
            np.testing.assert_allclose(workspace.x, binding_answer(qp)[0], rtol=0, atol=1e-9)
            assert_kkt(qp, workspace.x, workspace.lam)
            if not inside:
                assert workspace.iterations > 0 and np.abs(workspace.lam).max() > 0.0
            elif warm_start and limits_were_active:
                assert workspace.iterations > 0 and not workspace.lam.any()
            else:
                assert workspace.iterations == 0 and defect == 0.0
                np.testing.assert_allclose(workspace.x, minimiser, rtol=0, atol=1e-10)
                assert not workspace.lam.any()
            limits_were_active = bool(workspace.lam.any())
        assert workspace.iterations == 0  # the last pass: the minimiser again
    qp = random_qp(rng, 4, 0, 1)
    qp.A[...] = 0.0  # an equality row 0 = 0: every x satisfies it, but DAQP answers QPs with equality rows
    qp.sync_equalities()
    qp.c[...] = qp.H @ rng.uniform(-0.05, 0.05, 4)
    workspace = NativeWorkspace(library, qp, {}, warm_start=True)
    assert workspace.solve()[0] == 1 and workspace.iterations > 0


def test_the_last_working_set_answers_when_it_is_still_optimal(rng):
    """A warm workspace made with working_set_first whose last answer had active constraints
    tries them first as equalities (wbc.runtime.kernels.native_qp._working_set_answer): after a
    small change of c the active set is the same, the answer comes without DAQP (0 iterations)
    and is the binding's, with multipliers that meet the KKT conditions written out; DAQP's
    working set is unchanged. When c turns round (the multipliers change sign) DAQP answers
    (iterations > 0), as right."""
    library = daqp_probe.native()
    answered = 0
    for _ in range(80):
        n, p, e = int(rng.integers(2, 9)), int(rng.integers(0, 5)), int(rng.integers(0, 3))
        e = min(e, n - 1)
        qp = random_qp(rng, n, p, e)
        workspace = NativeWorkspace(library, qp, {}, warm_start=True, working_set_first=True)
        if workspace.solve()[0] != 1:
            continue
        active = workspace.working_set & kernels.DAQP_SENSE_ACTIVE
        if not active.any():
            continue
        before = workspace.working_set
        qp.c[...] += 1e-6 * rng.standard_normal(n)  # the same active set, other multipliers
        exitflag, defect, _ = workspace.solve()
        reference, reference_flag = binding_answer(qp)
        assert exitflag == 1 == reference_flag
        np.testing.assert_allclose(workspace.x, reference, rtol=0, atol=1e-9)
        assert_kkt(qp, workspace.x, workspace.lam)
        assert defect == kernels.qp_defect(qp.data, workspace.x) <= 1e-9
        if workspace.iterations == 0:
            answered += 1
            np.testing.assert_array_equal(workspace.working_set, before)
        qp.c[...] = -qp.c  # pulled the other way: the last set is no longer optimal
        exitflag, _, _ = workspace.solve()
        reference, reference_flag = binding_answer(qp)
        assert (exitflag == 1) == (reference_flag == 1)
        if exitflag == 1:
            np.testing.assert_allclose(workspace.x, reference, rtol=0, atol=1e-9)
            assert_kkt(qp, workspace.x, workspace.lam)
    assert answered >= 60  # (of at most 80: the set stays optimal after a 1e-6 change but near degenerate sets)


def _kernel_answer(qp: QP, sense: np.ndarray, tolerance: float = 1e-9) -> tuple[float, np.ndarray, np.ndarray]:
    n = qp.n
    x, lam, scratch = np.zeros(n), np.zeros(sense.size), np.zeros((4 * n + 7, n))
    defect = native_qp._working_set_answer(qp.data, sense.astype(np.int32), x, scratch[:n], lam, scratch[n:],
                                           tolerance)
    return defect, x, lam


def test_the_working_set_try_refuses_what_is_not_an_answer():
    """The try of a working set returns -1 (DAQP then solves) for a set whose multipliers have
    the wrong sign, whose minimiser violates another constraint, with two copies of one row
    (dependent: a zero pivot), with a bit it does not know (soft), or where H is only
    semidefinite on the set (the reduced Hessian singular); and the right set gives the
    binding's answer."""
    qp = QP(3, 2, 0)
    qp.H[...] = np.diag([1.0, 2.0, 3.0])
    qp.c[...] = [-4.0, 0.0, 0.0]  # the unconstrained minimiser x = (4, 0, 0)
    qp.C[...] = [[1.0, 0.0, 0.0], [1.0, 0.0, 0.0]]
    qp.ub[...], qp.lb[...] = 10.0, -10.0
    qp.h[...] = 1.0  # x0 <= 1 twice: the answer (1, 0, 0), multiplier 3 on one of the rows
    qp.sync_equalities()
    reference = binding_answer(qp)[0]
    np.testing.assert_allclose(reference, [1.0, 0.0, 0.0], atol=1e-12)
    A = kernels.DAQP_SENSE_ACTIVE
    defect, x, lam = _kernel_answer(qp, np.array([0, 0, 0, A, 0]))
    assert 0.0 <= defect <= 1e-12
    np.testing.assert_allclose(x, reference, rtol=0, atol=1e-12)
    np.testing.assert_allclose(lam, [0.0, 0.0, 0.0, 3.0, 0.0], rtol=0, atol=1e-12)
    assert _kernel_answer(qp, np.array([0, 0, 0, A, A]))[0] == -1.0  # the same row twice
    assert _kernel_answer(qp, np.array([0, 0, 0, A | kernels.DAQP_SENSE_LOWER, 0]))[0] == -1.0  # wrong side
    assert _kernel_answer(qp, np.array([A, 0, 0, 0, 0]))[0] == -1.0  # x0 <= 10 active: -mu < 0, and row 1 violated
    assert _kernel_answer(qp, np.array([0, 0, 0, A | 8, 0]))[0] == -1.0  # soft (DAQP's SOFT bit)
    qp.h[...] = [1.0, 0.5]
    assert _kernel_answer(qp, np.array([0, 0, 0, A, 0]))[0] == -1.0  # x0 = 1 violates x0 <= 0.5
    qp.H[2, 2] = 0.0
    assert _kernel_answer(qp, np.array([0, 0, 0, 0, A]))[0] == -1.0  # H only semidefinite


def test_the_working_set_try_takes_a_violation_up_to_daqps_primal_tolerance():
    """A minimiser of the working set that violates another row by 1e-7 (relative) is the answer
    within DAQP's default primal tolerance (1e-6, that of the levels of strict priorities) and
    not within 1e-9: the kernel's tolerance, and a workspace's try follows its own ``primal_tol``
    (0 iterations with the default; DAQP solves with ``primal_tol`` 1e-9)."""
    qp = QP(3, 2, 0)
    qp.H[...] = np.diag([1.0, 2.0, 3.0])
    qp.c[...] = [-4.0, 0.0, 0.0]  # the unconstrained minimiser x = (4, 0, 0)
    qp.C[...] = [[1.0, 0.0, 0.0], [2.0, 0.0, 0.0]]
    qp.ub[...], qp.lb[...] = 10.0, -10.0
    qp.h[...] = [1.0, 2.0 - 4e-7]  # x0 <= 1, and 2 x0 <= 2 - 4e-7: violated by 4e-7 / max(1, 2, 2) = 2e-7 at x0 = 1
    A = kernels.DAQP_SENSE_ACTIVE
    sense = np.array([0, 0, 0, A, 0])
    defect, x, _ = _kernel_answer(qp, sense, tolerance=1e-6)
    assert defect == pytest.approx(2e-7, rel=1e-6)
    np.testing.assert_allclose(x, [1.0, 0.0, 0.0], rtol=0, atol=1e-15)
    assert _kernel_answer(qp, sense, tolerance=1e-9)[0] == -1.0
    assert _kernel_answer(qp, sense, tolerance=1.9e-7)[0] == -1.0  # the bound is the defect itself
    library = daqp_probe.native()
    for settings, direct in (({}, True), ({"primal_tol": 1e-9}, False)):
        workspace = NativeWorkspace(library, qp, settings, warm_start=True, working_set_first=True)
        workspace.working_set = sense
        exitflag, defect, _ = workspace.solve()
        assert exitflag == 1 and (workspace.iterations == 0) == direct
        assert defect <= (1e-6 if direct else 1e-9)


def _vertex_qp(rng: np.random.Generator, n: int, lower_side: np.ndarray) -> tuple[QP, np.ndarray, np.ndarray,
                                                                                   np.ndarray]:
    """A QP whose answer x* is pinned by n active constraints -- some bounds, the rest rows
    (scaled 0.1..10, sides ``lower_side``) -- with multipliers lam* of their sides' signs (the
    KKT conditions written out: ``c = -H x* - A_W^T lam*``), two more rows with slack; and the
    working set (DAQP's states), x*, lam*."""
    bounds = int(rng.integers(0, n))
    qp = QP(n, n - bounds + 2, 0)
    fill_random(rng, qp)
    x_star = rng.uniform(-0.5, 0.5, n)
    qp.C[...] *= 10.0 ** rng.uniform(-1.0, 1.0, (qp.n_ineq, 1))
    values = np.concatenate([x_star, qp.C @ x_star])
    qp.upper[...], qp.lower[...] = values + 1.0, values - 1.0
    active = np.concatenate([rng.choice(n, bounds, replace=False), n + np.arange(n - bounds)])
    sense = np.zeros(qp.upper.size, dtype=np.int32)
    lam = np.zeros(qp.upper.size)
    for i, lower in zip(active, lower_side, strict=True):
        sense[i] = kernels.DAQP_SENSE_ACTIVE | (kernels.DAQP_SENSE_LOWER if lower else 0)
        (qp.lower if lower else qp.upper)[i] = values[i]
        lam[i] = rng.uniform(0.1, 2.0) * (-1.0 if lower else 1.0)
    qp.c[...] = -qp.H @ x_star - lam[:n] - qp.C.T @ lam[n:]
    return qp, sense, x_star, lam


def test_a_working_set_of_n_constraints_is_solved_by_one_lu(rng):
    """A working set that pins x (n independent active constraints, :func:`native_qp._working_set_answer`)
    gives x* and lam* of the KKT conditions written out, the binding's answer and its defect; a
    warm workspace then answers it without DAQP (0 iterations) after a small change of c."""
    library = daqp_probe.native()
    for n in (1, 2, 5, 8, 9):
        for _ in range(10):
            qp, sense, x_star, lam_star = _vertex_qp(rng, n, rng.random(n) < 0.5)
            defect, x, lam = _kernel_answer(qp, sense)
            assert 0.0 <= defect == kernels.qp_defect(qp.data, x) <= 1e-9
            np.testing.assert_allclose(x, x_star, rtol=0, atol=1e-9)
            np.testing.assert_allclose(lam, lam_star, rtol=1e-8, atol=1e-9)
            assert_kkt(qp, x, lam)
            reference, flag = binding_answer(qp)
            assert flag == 1
            np.testing.assert_allclose(x, reference, rtol=0, atol=1e-8)
            workspace = NativeWorkspace(library, qp, {}, warm_start=True, working_set_first=True)
            assert workspace.solve()[0] == 1
            if np.array_equal(workspace.working_set & kernels.DAQP_SENSE_ACTIVE, sense & kernels.DAQP_SENSE_ACTIVE):
                qp.c[...] += 1e-7 * rng.standard_normal(n)  # the same vertex, other multipliers
                assert workspace.solve()[0] == 1 and workspace.iterations == 0
                np.testing.assert_allclose(workspace.x, binding_answer(qp)[0], rtol=0, atol=1e-8)
                assert_kkt(qp, workspace.x, workspace.lam)


def test_a_working_set_of_fewer_than_n_constraints_gives_the_kkt_point(rng):
    """A working set of k < n constraints (bounds, rows on either side, equality rows; the
    null-space method of :func:`native_qp._working_set_answer`) gives the x* and lam* of the KKT
    conditions written out (``c = -H x* - A_W^T lam*``, the other constraints slack) and
    quadprog's answer (a second solver, through qpsolvers); with one multiplier's sign turned
    round it refuses (-1)."""
    qpsolvers = pytest.importorskip("qpsolvers")
    for n in (2, 5, 8, 9):
        for _ in range(10):
            k, e = int(rng.integers(0, n)), int(rng.integers(0, 2))
            e = min(e, k)
            bounds = int(rng.integers(0, k - e + 1))
            qp = QP(n, k - e - bounds + 2, e)
            fill_random(rng, qp)
            qp.C[...] *= 10.0 ** rng.uniform(-1.0, 1.0, (qp.C.shape[0], 1))
            qp.sync_equalities()
            x_star = rng.uniform(-0.5, 0.5, n)
            values = np.concatenate([x_star, qp.C @ x_star])
            qp.upper[...], qp.lower[...] = values + 1.0, values - 1.0
            m = qp.upper.size
            active = [*rng.choice(n, bounds, replace=False), *range(n, n + k - e - bounds), *range(m - e, m)]
            sense = np.zeros(m, dtype=np.int32)
            lam_star = np.zeros(m)
            for i in active:
                equality, lower = i >= m - e, bool(rng.random() < 0.5)
                sense[i] = kernels.DAQP_SENSE_ACTIVE | (kernels.DAQP_SENSE_IMMUTABLE if equality else 0)
                if equality:
                    qp.upper[i] = qp.lower[i] = values[i]
                    lam_star[i] = rng.uniform(-2.0, 2.0)
                else:
                    sense[i] |= kernels.DAQP_SENSE_LOWER if lower else 0
                    (qp.lower if lower else qp.upper)[i] = values[i]
                    lam_star[i] = rng.uniform(0.1, 2.0) * (-1.0 if lower else 1.0)
            qp.c[...] = -qp.H @ x_star - lam_star[:n] - qp.C.T @ lam_star[n:]
            defect, x, lam = _kernel_answer(qp, sense)
            assert 0.0 <= defect == kernels.qp_defect(qp.data, x) <= 1e-9
            np.testing.assert_allclose(x, x_star, rtol=0, atol=1e-9)
            np.testing.assert_allclose(lam, lam_star, rtol=1e-7, atol=1e-8)
            assert_kkt(qp, x, lam)
            p = qp.n_ineq
            reference = qpsolvers.solve_qp(qp.H, qp.c, np.vstack([qp.C[:p], -qp.C[:p]]),
                                           np.concatenate([qp.upper[n:n + p], -qp.lower[n:n + p]]),
                                           qp.C[p:], qp.upper[n + p:], qp.lower[:n], qp.upper[:n], solver="quadprog")
            np.testing.assert_allclose(x, reference, rtol=0, atol=1e-7)
            inequalities = [i for i in active if i < m - e]
            if inequalities:
                i = inequalities[0]
                flipped = sense.copy()
                flipped[i] ^= kernels.DAQP_SENSE_LOWER  # the other side, at the same value: the sign is wrong
                qp.upper[i] = qp.lower[i] = values[i]
                assert _kernel_answer(qp, flipped)[0] == -1.0


def test_a_working_set_of_n_constraints_refuses_what_is_not_an_answer(rng):
    """The LU try of a pinning working set returns -1 (DAQP then solves) when a multiplier has
    the wrong sign (the set marked on the other side), another row is violated at the vertex,
    the rows are dependent (a copy of another, a combination of two, a zero row; nearly so: a
    pivot below WORKING_SET_LU_PIVOT, even at an optimal vertex), or a state holds a bit it does
    not know."""
    low = kernels.DAQP_SENSE_LOWER
    for n in (2, 4, 8):
        qp, sense, x_star, _ = _vertex_qp(rng, n, np.zeros(n, dtype=bool))
        assert _kernel_answer(qp, sense)[0] >= 0.0
        flipped = sense.copy()
        i = int(np.flatnonzero(sense)[0])
        flipped[i] |= low
        qp.lower[i] = qp.upper[i]
        assert _kernel_answer(qp, flipped)[0] == -1.0  # lam* > 0 on a lower side
        qp.lower[i] = qp.upper[i] - 1.0
        slack = qp.upper.size - 1  # a row with slack, moved below its value at x*
        qp.upper[slack] = qp.lower[slack] + 0.5
        assert _kernel_answer(qp, sense)[0] == -1.0
        qp.upper[slack] = qp.lower[slack] + 2.0
        assert _kernel_answer(qp, sense)[0] >= 0.0
        rows = np.flatnonzero(sense[n:]) + n  # the active rows of C
        full = np.vstack([np.eye(n), qp.C])  # (the constraints' rows: bounds, then C)
        others = [i for i in np.flatnonzero(sense) if i not in rows[:2]]  # (a third active constraint)
        for replacement in (full[rows[0]] * 2.0, full[rows[0]] - 3.0 * full[others[0]] if others else None,
                            0.0 * full[0]):
            if len(rows) < 2 or replacement is None:
                continue
            C = qp.C.copy()
            qp.C[rows[1] - n] = replacement
            qp.sync_equalities()
            value = qp.C[rows[1] - n] @ x_star
            qp.upper[rows[1]], qp.lower[rows[1]] = value, value - 1.0
            assert _kernel_answer(qp, sense)[0] == -1.0  # dependent rows
            qp.C[...] = C
        unknown = sense.copy()
        unknown[int(np.flatnonzero(sense)[-1])] |= 8  # DAQP's SOFT bit
        assert _kernel_answer(qp, unknown)[0] == -1.0
        if len(rows) >= 2:  # nearly dependent rows: refused by the pivot even where the vertex is optimal
            qp, sense, x_star, lam_star = _vertex_qp(rng, n, np.zeros(n, dtype=bool))
            rows = np.flatnonzero(sense[n:]) + n
            qp.C[rows[1] - n] = qp.C[rows[0] - n] + 1e-8 * rng.standard_normal(n)
            qp.sync_equalities()
            qp.upper[rows[1]] = qp.C[rows[1] - n] @ x_star
            qp.lower[rows[1]] = qp.upper[rows[1]] - 1.0
            qp.c[...] = -qp.H @ x_star - lam_star[:n] - qp.C.T @ lam_star[n:]
            assert _kernel_answer(qp, sense)[0] == -1.0


def test_settings_reach_the_c_solver():
    rng = np.random.default_rng(3)
    qp = random_qp(rng, 10, 8, 0)
    qp.c[...] = 50.0 * rng.standard_normal(10)  # far outside the bounds: many active-set changes
    capped = DaqpBackend({"iter_limit": 1, "warm_start": False})
    assert capped.native
    solution = capped.solve(qp)
    assert not solution.success and solution.status == "iteration limit"
    assert DaqpBackend({"warm_start": False}).solve(qp).success


def test_a_warm_start_does_not_change_the_answer_and_saves_iterations():
    """A slowly drifting QP with many active bounds and rows, like a control loop's: the warm
    workspace gives the cold one's answers in fewer DAQP iterations."""
    rng = np.random.default_rng(7)
    base = random_qp(rng, 12, 6, 0)
    base.c[...] = 20.0 * rng.standard_normal(12)  # the unconstrained optimum far outside the box
    answers, iterations = {}, {}
    for warm in (True, False):
        qp = base.copy()
        workspace = NativeWorkspace(daqp_probe.native(), qp, {}, warm_start=warm)
        answers[warm], iterations[warm] = [], 0
        for k in range(100):
            qp.c[...] = base.c + np.sin(0.05 * k + np.arange(12))
            exitflag, _, _ = workspace.solve()
            assert exitflag == 1
            answers[warm].append(workspace.x.copy())
            iterations[warm] += workspace.iterations
    assert np.max(np.abs(np.array(answers[True]) - np.array(answers[False]))) < 1e-9
    assert iterations[True] < 0.5 * iterations[False]


@pytest.mark.parametrize("scenario_file", sorted(p.name for p in TASKS.glob("*.toml")))
def test_controller_commands_match_the_binding_path(scenario_file, monkeypatch):
    """Every shipped scenario, 150 closed-loop ticks: the native path (solve inside the tick
    program, or alone for the reduced form) and DAQP's Python binding give the same commands."""
    scenario = load_scenario(TASKS / scenario_file)

    def run() -> tuple[np.ndarray, list, wbc.Controller]:
        controller = scenario.make_controller("daqp")
        q, out, outcomes = scenario.q0.copy(), [], []
        for k in range(150):
            if scenario.reference_task is not None:
                scenario.reference_task.set_target(*scenario.reference(k * scenario.dt))
            out.append(controller.step(q))
            outcomes.append(controller.last.outcome)
            q = scenario.robot.integrate(q, out[-1], scenario.dt)
        return np.array(out), outcomes, controller

    native, native_outcomes, controller = run()
    assert controller.solver.native and controller._solve_in_program == (not controller.reduced)
    monkeypatch.setattr(daqp_probe, "native", lambda: None)
    binding, binding_outcomes, controller = run()
    assert not controller.solver.native and not controller._solve_in_program
    assert native_outcomes == binding_outcomes
    assert np.max(np.abs(native - binding)) < 1e-9


class SometimesNan(wbc.Task, TaskData):
    """A task whose target is NaN while ``broken``."""

    dim = 1
    broken = False

    def compute(self, kin, dt, jacobian, target):
        jacobian.fill(1.0)
        target.fill(np.nan if SometimesNan.broken else 0.0)

    def report(self, v, errors):
        pass


def test_a_nan_in_the_qp_skips_the_native_solve(youbot):
    task = wbc.FrameTask("ee", gain=0.5)
    home = youbot.neutral()
    task.set_target(youbot.frame_pose(home, "ee"))
    controller = wbc.Controller(youbot, [task, SometimesNan()], [wbc.JointVelocityLimits()])
    controller.step(home)
    assert controller.last.outcome is wbc.Outcome.OPTIMAL
    SometimesNan.broken = True
    try:
        v = controller.step(home)
    finally:
        SometimesNan.broken = False
    assert controller.last.outcome is wbc.Outcome.ZERO and np.all(v == 0.0)
    assert controller.solver._bound.control[kernels.DAQP_CONTROL_EXITFLAG] == kernels.DAQP_SKIPPED
    controller.step(home)
    assert controller.last.outcome is wbc.Outcome.OPTIMAL


def test_an_infeasible_tick_resets_the_workspace_and_the_next_one_solves(youbot):
    """Conflicting hard rows: DAQP fails, the fallback answers; the workspace starts cold."""
    qp = random_qp(np.random.default_rng(5), 4, 2, 0)
    backend = DaqpBackend()
    assert backend.solve(qp).success
    qp.C[1] = -qp.C[0]
    qp.h[...] = (-1.0, -1.0)  # C0 x <= -1 and -C0 x <= -1: infeasible
    failed = backend.solve(qp)
    assert not failed.success and failed.status == "infeasible"
    qp.h[...] = 1.0
    solution = backend.solve(qp)
    assert solution.success and np.allclose(solution.x, binding_answer(qp)[0], atol=1e-9)


def test_workspaces_are_freed_with_their_controller(youbot):
    task = wbc.FrameTask("ee")
    task.set_target(youbot.frame_pose(youbot.neutral(), "ee"))
    controller = wbc.Controller(youbot, [task], [wbc.JointVelocityLimits()])
    controller.step(youbot.neutral())
    finalizer = controller.solver._bound._finalizer
    workspace = weakref.ref(controller.solver._bound)
    assert finalizer.alive
    del controller
    gc.collect()
    assert workspace() is None and not finalizer.alive


def test_reassigning_the_solver_rebuilds_the_program(youbot):
    task = wbc.FrameTask("ee", gain=0.5)
    home = youbot.neutral()
    target = youbot.frame_pose(home, "ee")
    target[:3, 3] += (0.2, 0.1, 0.0)
    task.set_target(target)
    controller = wbc.Controller(youbot, [task], [wbc.JointVelocityLimits()])
    v_daqp = controller.step(home)
    controller.solver = wbc.solvers.make_solver("proxqp")
    assert not controller._solve_in_program
    assert np.allclose(controller.step(home), v_daqp, atol=1e-6)
    with pytest.raises(wbc.InvalidInputError, match="QPSolver"):
        controller.solver = "daqp"


def test_the_kernel_constants_are_the_ctypes_layout():
    """Written out from DAQP 0.11's types.h: x86-64 / AArch64 (LP64) sizes and offsets."""
    assert (daqp_abi.words(daqp_abi.Problem), daqp_abi.words(daqp_abi.Workspace),
            daqp_abi.words(daqp_abi.Result)) == (80 // 8, 328 // 8, 64 // 8)
    assert daqp_abi.Result.exitflag.offset == 32 and daqp_abi.Result.iter.offset == 36
    assert daqp_abi.Workspace.sense.offset == 64 and daqp_abi.Workspace.settings.offset == 224
    assert Path(daqp.__file__).exists()


def test_qps_of_one_shape_share_one_workspace_and_its_warm_start():
    """Recorded QPs (other objects than the controller's) are copied into one workspace of
    their shape: no set-up per solve, and the binding's answers."""
    rng = np.random.default_rng(11)
    backend = DaqpBackend()
    qps = [random_qp(rng, 6, 4, 1) for _ in range(30)]
    for qp in qps:
        solution = backend.solve(qp)
        reference, flag = binding_answer(qp)
        assert solution.success == (flag >= 1)
        if solution.success:
            assert np.max(np.abs(solution.x - reference)) < 1e-8
    workspace = backend._workspace
    assert workspace is not None and all(workspace.qp is not qp for qp in qps)
    backend.solve(random_qp(rng, 5, 4, 1))  # another shape: another workspace
    assert backend._workspace is not workspace
