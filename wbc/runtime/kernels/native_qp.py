"""DAQP called through its C API from compiled code (see :mod:`wbc.solvers.daqp.native`).

The C functions are called through their addresses, passed in as int operands
(:class:`wbc.solvers.daqp.abi.Entry`), by three small intrinsics that emit an indirect call: the
machine code then holds no address of this process, so numba can cache it like every
other kernel. Pointers travel as int64 (the x86-64 and AArch64 ABIs pass both in the same
registers); the structures are float64 arrays that wbc owns (``wbc.solvers.daqp.abi.struct_in``).
"""

from __future__ import annotations

import math

import numpy as np
from llvmlite import ir
from numba import carray, njit, types
from numba.extending import intrinsic

from . import (
    DAQP_CONTROL_ACCEPTED_TIME,
    DAQP_CONTROL_DEFECT,
    DAQP_CONTROL_EXITFLAG,
    DAQP_CONTROL_ITERATIONS,
    DAQP_CONTROL_MASK,
    DAQP_CONTROL_SIZE,
    DAQP_CONTROL_TIME,
    DAQP_OPTIMAL,
    DAQP_PROBLEM_WORDS,
    DAQP_RESULT_EXITFLAG,
    DAQP_RESULT_ITERATIONS,
    DAQP_RESULT_WORDS,
    DAQP_SENSE_ACTIVE,
    DAQP_SENSE_IMMUTABLE,
    DAQP_SENSE_LOWER,
    DAQP_SKIPPED,
    DAQP_WORKSPACE_WORDS,
    prepare_cache,
)
from ._clock import now_ns
from ._inert_rows import _int32_at, leave_out, restore
from ._lazy import declared
from .assembly import _minimiser, qp_defect
from .ops import FLAG_ACCEPTED, FLAG_FOUND_NAN, FLAG_STOPPED, FLAGS_OPERAND, Op

CACHE = prepare_cache()  # before the first @njit below compiles; False: no writable cache (see wbc.runtime.kernels)

#: the largest relative violation (:func:`wbc.runtime.kernels.qp_defect`) of a working set's
#: minimiser taken as the QP's answer (:func:`_working_set_answer`: the rows it holds are met up
#: to rounding; the others may be violated by as much, as on near-dependent rows DAQP's own
#: answer is); far below DAQP's primal tolerance and the controller's answer check (1e-6), so
#: DAQP, warm-started from the same set, would stop at the same point
WORKING_SET_DEFECT = 1e-9
#: the smallest pivot of ``S = A_W H^-1 A_W^T``, relative to its diagonal, of a working set
#: solved directly (:func:`_working_set_answer`): below it the rows are taken as dependent
WORKING_SET_PIVOT = 1e-10
#: the smallest pivot of the LU factorisation of a working set of n constraints (:func:`_vertex_answer`;
#: its rows scaled to largest entry 1): below it the rows are taken as dependent. The square root of
#: :data:`WORKING_SET_PIVOT`: S's pivots are the squares of those of A_W (with H = I and orthogonal
#: factorisations; LU's are of the same size)
WORKING_SET_LU_PIVOT = 1e-5

_I8P = ir.IntType(8).as_pointer()
_I32 = ir.IntType(32)


@intrinsic
def _update_ldp(typingctx, function, mask, workspace, problem):
    """``int daqp_update_ldp(int mask, DAQPWorkspace*, DAQPProblem*)`` at address ``function``."""
    signature = types.int32(types.int64, types.int32, types.int64, types.int64)

    def codegen(context, builder, signature, args):
        callee = builder.inttoptr(args[0], ir.FunctionType(_I32, [_I32, _I8P, _I8P]).as_pointer())
        return builder.call(callee, [args[1], builder.inttoptr(args[2], _I8P), builder.inttoptr(args[3], _I8P)])

    return signature, codegen


@intrinsic
def _solve(typingctx, function, result, workspace):
    """``void daqp_solve(DAQPResult*, DAQPWorkspace*)`` at address ``function``."""
    signature = types.void(types.int64, types.int64, types.int64)

    def codegen(context, builder, signature, args):
        callee = builder.inttoptr(args[0], ir.FunctionType(ir.VoidType(), [_I8P, _I8P]).as_pointer())
        builder.call(callee, [builder.inttoptr(args[1], _I8P), builder.inttoptr(args[2], _I8P)])
        return context.get_dummy_value()

    return signature, codegen


@njit(inline="always")
def _sense_at(problem: np.ndarray, sense_word: int, m: int) -> np.ndarray:
    """DAQP's constraint states -- the array its problem points to (word ``sense_word`` of
    ``problem``), the next solve's warm start -- as an int32 array of ``m`` (empty when unset)."""
    address = problem.view(np.int64)[sense_word]
    return carray(_int32_at(address), (m if address != 0 else 0,))


@njit(inline="always")
def _no_active_constraint(sense: np.ndarray) -> bool:
    """Whether DAQP's working set ``sense`` holds no active constraint (the last answer met no
    limit): every state without a bit but the side (no equality row, soft or binary constraint)."""
    for i in range(sense.shape[0]):
        if sense[i] & ~DAQP_SENSE_LOWER:
            return False
    return True


@njit(inline="always")
def _unconstrained_answer(data: np.ndarray, x: np.ndarray, factor: np.ndarray, lam: np.ndarray) -> bool:
    """``x = -H^-1 c`` (:func:`wbc.runtime.kernels.assembly._minimiser`) for the QP stored in ``data``
    (:func:`wbc.runtime.kernels.qp_defect`'s layout) when that satisfies every bound and row exactly
    (defect 0): then it is the QP's minimiser (H positive definite: the unconstrained minimiser,
    feasible, is the constrained one), no constraint is active and every multiplier is 0
    (``lam``). False otherwise (x then holds scratch)."""
    n = x.shape[0]
    if not _minimiser(data[:n * n + n].reshape((n + 1, n)), factor, x) or qp_defect(data, x) != 0.0:
        return False
    for i in range(lam.shape[0]):
        lam[i] = 0.0
    return True


@njit(inline="always")
def _reciprocal_cholesky(A: np.ndarray, factor: np.ndarray, size: int, relative: float) -> bool:
    """:func:`wbc.runtime.kernels.cholesky` (``A = L L^T``, False on a pivot not above ``relative``
    times its diagonal entry) with ``1 / L_jj`` on ``factor``'s diagonal: the solves
    :func:`_forward` and :func:`_back` then multiply where they would divide. Inlined into the
    working-set try, on its contiguous arrays."""
    for j in range(size):
        pivot = A[j, j]
        for p in range(j):
            pivot -= factor[j, p] * factor[j, p]
        if not pivot > 0.0 or pivot <= relative * A[j, j]:
            return False
        inverse = 1.0 / math.sqrt(pivot)
        factor[j, j] = inverse
        for a in range(j + 1, size):
            total = A[a, j]
            for p in range(j):
                total -= factor[a, p] * factor[j, p]
            factor[a, j] = total * inverse
    return True


@njit(inline="always")
def _forward(factor: np.ndarray, size: int, b: np.ndarray) -> None:
    """``b = L^-1 b`` in place (L from :func:`_reciprocal_cholesky`: its diagonal's reciprocals)."""
    for a in range(size):
        total = b[a]
        for p in range(a):
            total -= factor[a, p] * b[p]
        b[a] = total * factor[a, a]


@njit(inline="always")
def _back(factor: np.ndarray, size: int, b: np.ndarray) -> None:
    """``b = L^-T b`` in place (L from :func:`_reciprocal_cholesky`: its diagonal's reciprocals)."""
    for a in range(size - 1, -1, -1):
        total = b[a]
        for p in range(a + 1, size):
            total -= factor[p, a] * b[p]
        b[a] = total * factor[a, a]


@njit(cache=CACHE, nogil=True)
def _vertex_answer(data: np.ndarray, sense: np.ndarray, x: np.ndarray, lam: np.ndarray, lu: np.ndarray,
                   kkt: np.ndarray) -> float:
    """:func:`_working_set_answer` of a working set of n constraints (``A_W``: n x n), which pins x:
    ``x = A_W^-1 b_W`` and the multipliers from stationarity ``H x + c + A_W^T lam_W = 0``, both by
    one LU factorisation with partial pivoting of ``A_W`` -- no Cholesky of H nor of S. Each row
    ``a_i`` (and ``b_i``) is first divided by its largest entry ``s_i``: ``A_W = D^-1 Â``, so
    ``x = Â^-1 D b_W`` and ``lam_W = -D Â^-T (H x + c)``; a pivot of ``Â`` at most
    :data:`WORKING_SET_LU_PIVOT` (dependent rows, a zero row) gives -1. The same checks as the
    general case accept x: multipliers of their sides' signs and a defect at most
    :data:`WORKING_SET_DEFECT` -- KKT conditions of a convex QP, x a vertex of its feasible set.

    ``lu`` (n x n scratch): ``Â`` and its factors ``L U`` (rows swapped as pivoted; U's diagonal
    holds the reciprocals of its pivots: the solves multiply); ``kkt`` (4 x n
    scratch at least): row 0 the row scales ``1 / s_i``, 1 each row's constraint index, 2 ``D b_W``
    then ``L^-1 D b_W``, 3 ``-(H x + c)`` then ``D^-1 lam_W``, all in ``lu``'s row order.
    """
    n, m = x.shape[0], lam.shape[0]
    start = n * n + n
    H, c = data[:n * n].reshape((n, n)), data[n * n:start]
    C = data[start:start + (m - n) * n].reshape((m - n, n))
    upper = data[start + (m - n) * n:start + (m - n) * n + m]
    lower = data[start + (m - n) * n + m:start + (m - n) * n + 2 * m]
    A, scale, index, b, y = lu, kkt[0], kkt[1], kkt[2], kkt[3]
    j = 0
    for i in range(m):
        state = sense[i]
        if state & DAQP_SENSE_ACTIVE:
            row = A[j]
            largest = 0.0
            for a in range(n):
                row[a] = C[i - n, a] if i >= n else (1.0 if a == i else 0.0)
                largest = max(largest, abs(row[a]))
            if not largest > 0.0:
                return -1.0
            inverse = 1.0 / largest
            for a in range(n):
                row[a] *= inverse
            b[j] = (lower[i] if state & DAQP_SENSE_LOWER else upper[i]) * inverse
            scale[j] = inverse
            index[j] = i
            j += 1
    for col in range(n):  # Â = P^T L U in place (unit L below the diagonal), the rows swapped along
        pivot, best = col, abs(A[col, col])
        for r in range(col + 1, n):
            if abs(A[r, col]) > best:
                pivot, best = r, abs(A[r, col])
        if not best > WORKING_SET_LU_PIVOT:
            return -1.0
        if pivot != col:
            for a in range(n):
                A[col, a], A[pivot, a] = A[pivot, a], A[col, a]
            b[col], b[pivot] = b[pivot], b[col]
            scale[col], scale[pivot] = scale[pivot], scale[col]
            index[col], index[pivot] = index[pivot], index[col]
        inverse = 1.0 / A[col, col]
        A[col, col] = inverse
        for r in range(col + 1, n):
            factor = A[r, col] * inverse
            A[r, col] = factor
            for a in range(col + 1, n):
                A[r, a] -= factor * A[col, a]
    for a in range(n):  # x = U^-1 L^-1 (D b_W)
        total = b[a]
        for p in range(a):
            total -= A[a, p] * b[p]
        b[a] = total
    for a in range(n - 1, -1, -1):
        total = b[a]
        for p in range(a + 1, n):
            total -= A[a, p] * x[p]
        x[a] = total * A[a, a]
    for a in range(n):  # y = -(H x + c), then Â^-T y = L^-T U^-T y = D^-1 lam_W
        total = c[a]
        for p in range(n):
            total += H[a, p] * x[p]
        y[a] = -total
    for a in range(n):
        total = y[a]
        for p in range(a):
            total -= A[p, a] * y[p]
        y[a] = total * A[a, a]
    for a in range(n - 1, -1, -1):
        total = y[a]
        for p in range(a + 1, n):
            total -= A[p, a] * y[p]
        y[a] = total
    for i in range(m):
        lam[i] = 0.0
    for j in range(n):  # the multipliers: the sign of their side (lam then holds scratch when not)
        i = int(index[j])
        mu = y[j] * scale[j]
        if not sense[i] & DAQP_SENSE_IMMUTABLE and (mu > 0.0 if sense[i] & DAQP_SENSE_LOWER else mu < 0.0):
            return -1.0
        lam[i] = mu
    defect = qp_defect(data, x)
    if defect > WORKING_SET_DEFECT:
        return -1.0
    return defect


@njit(cache=CACHE, nogil=True)
def _working_set_answer(data: np.ndarray, sense: np.ndarray, x: np.ndarray, factor: np.ndarray, lam: np.ndarray,
                        kkt: np.ndarray) -> float:
    """The minimiser of the QP in ``data`` (:func:`wbc.runtime.kernels.qp_defect`'s layout) with
    the constraints of DAQP's working set ``sense`` (the last answer's active constraints) held as
    equalities, when it meets every optimality condition of the QP: then it is the QP's answer
    (``x``, multipliers ``lam``) and its defect is returned; else -1 (x and lam hold scratch).

    With ``H = L L^T`` (``factor``), ``x0 = -H^-1 c`` and the k active constraints ``A_W x = b_W``
    (a bound: a row of I; ``b`` the side DAQP marks: upper unless its LOWER bit is set), the
    equality-constrained minimiser is ``x = x0 - H^-1 A_W^T mu``, ``S mu = A_W x0 - b_W``,
    ``S = A_W H^-1 A_W^T = Y Y^T`` with ``Y^T = L^-1 A_W^T``. It is the QP's answer when it is
    primal feasible (defect at most :data:`WORKING_SET_DEFECT`) and dual feasible (``mu >= 0``
    on an upper side, ``<= 0`` on a lower side -- DAQP's sign convention for ``lam`` -- any
    sign on an equality row): the KKT conditions of a strictly convex QP, which have one
    solution. -1 also when H is not positive definite, a state holds another bit (soft,
    binary, ...), the set holds more than n constraints or dependent ones (a pivot of S below
    :data:`WORKING_SET_PIVOT` times its diagonal): DAQP then solves. A set of exactly n
    constraints pins x: :func:`_vertex_answer` solves it without H's factor (``factor`` holds its LU).

    ``kkt`` ((2n + 2) x n scratch): rows 0..k-1 Y, rows n..2n-1 S and its Cholesky factor, row
    2n mu, 2n + 1 the step ``x0 - x``. The factors hold the reciprocals of their diagonals
    (:func:`_reciprocal_cholesky`).
    """
    n, m = x.shape[0], lam.shape[0]
    k = 0  # the active constraints
    for i in range(sense.shape[0]):
        state = sense[i]
        if state & ~(DAQP_SENSE_ACTIVE | DAQP_SENSE_LOWER | DAQP_SENSE_IMMUTABLE):
            return -1.0  # a soft or binary constraint, or a state this kernel does not know
        if state & DAQP_SENSE_ACTIVE:
            k += 1
    if k > n:
        return -1.0
    if k == n:
        return _vertex_answer(data, sense, x, lam, factor, kkt)
    Hc = data[:n * n + n].reshape((n + 1, n))  # x0 = -H^-1 c
    if not _reciprocal_cholesky(Hc, factor, n, 0.0):
        return -1.0
    for a in range(n):
        x[a] = -Hc[n, a]
    _forward(factor, n, x)
    _back(factor, n, x)
    start = n * n + n
    C = data[start:start + (m - n) * n].reshape((m - n, n))
    upper = data[start + (m - n) * n:start + (m - n) * n + m]
    lower = data[start + (m - n) * n + m:start + (m - n) * n + 2 * m]
    mu, z = kkt[2 * n], kkt[2 * n + 1]
    k = 0  # the active constraints: a_i in row k of kkt, a_i x0 - b_i in mu
    for i in range(sense.shape[0]):
        state = sense[i]
        if state & DAQP_SENSE_ACTIVE:
            y = kkt[k]
            value = 0.0
            for a in range(n):
                y[a] = C[i - n, a] if i >= n else (1.0 if a == i else 0.0)
                value += y[a] * x[a]
            mu[k] = value - (lower[i] if state & DAQP_SENSE_LOWER else upper[i])
            k += 1
    S = kkt[n:2 * n]  # S = Y Y^T, Y^T = L^-1 A_W^T (its lower triangle), then its factor G in place
    for j in range(k):
        _forward(factor, n, kkt[j])
        for r in range(j + 1):
            total = 0.0
            for a in range(n):
                total += kkt[j, a] * kkt[r, a]
            S[j, r] = total
    if not _reciprocal_cholesky(S, S, k, WORKING_SET_PIVOT):
        return -1.0
    _forward(S, k, mu)  # mu = S^-1 (A_W x0 - b_W)
    _back(S, k, mu)
    j = 0  # the multipliers: the sign of their side (lam then holds scratch when not)
    for i in range(m):
        lam[i] = 0.0
        if sense[i] & DAQP_SENSE_ACTIVE:
            if not sense[i] & DAQP_SENSE_IMMUTABLE and (mu[j] > 0.0 if sense[i] & DAQP_SENSE_LOWER else mu[j] < 0.0):
                return -1.0
            lam[i] = mu[j]
            j += 1
    for a in range(n):  # x = x0 - L^-T Y^T mu
        total = 0.0
        for j in range(k):
            total += kkt[j, a] * mu[j]
        z[a] = total
    _back(factor, n, z)
    for a in range(n):
        x[a] -= z[a]
    defect = qp_defect(data, x)
    if defect > WORKING_SET_DEFECT:
        return -1.0
    return defect


@njit(inline="always")
def _answered(control: np.ndarray, defect: float, start: int, clock_gettime: int, clock_id: int) -> None:
    """``control`` of an answer found without DAQP: exit flag 1, ``defect``, 0 iterations, the time since ``start``."""
    control[DAQP_CONTROL_EXITFLAG] = DAQP_OPTIMAL
    control[DAQP_CONTROL_DEFECT] = defect
    control[DAQP_CONTROL_ITERATIONS] = 0
    control[DAQP_CONTROL_TIME] = (now_ns(clock_gettime, clock_id) - start) * 1e-9


@njit(inline="always")
def _daqp(problem: np.ndarray, workspace: np.ndarray, result: np.ndarray, control: np.ndarray, data: np.ndarray,
          x: np.ndarray, lam: np.ndarray, update_ldp: int, solve: int, clock_gettime: int, clock_id: int,
          steady_mask: int, sense_word: int, start: int) -> None:
    """DAQP's solve: ``daqp_update_ldp(control[MASK])`` re-forms R^-1 (hence M = A R^-1, v, d)
    from the fresh buffers, ``daqp_solve`` writes x and lam (``result`` points to both); the
    answer is then checked: its defect (:func:`wbc.runtime.kernels.qp_defect`, relative
    violation of the bounds and rows) is written, inf when x is not finite; and the time
    since ``start``. The next tick's mask is ``steady_mask``. DAQP is not given the trailing
    rows that every x satisfies (:mod:`._inert_rows`); the answer is checked against every row."""
    flags = result.view(np.int32)
    given = leave_out(problem, x.shape[0], lam.shape[0])
    flag = _update_ldp(update_ldp, np.int32(control[DAQP_CONTROL_MASK]), workspace.ctypes.data,
                       problem.ctypes.data)
    control[DAQP_CONTROL_MASK] = steady_mask
    iterations = 0
    defect = math.inf
    if flag >= 0:
        _solve(solve, result.ctypes.data, workspace.ctypes.data)
        flag = flags[DAQP_RESULT_EXITFLAG]
        iterations = flags[DAQP_RESULT_ITERATIONS]
        if flag >= 1:
            defect = qp_defect(data, x)  # inf when x is not finite
    restore(problem, workspace, lam, given, sense_word)
    control[DAQP_CONTROL_EXITFLAG] = flag
    control[DAQP_CONTROL_DEFECT] = defect
    control[DAQP_CONTROL_ITERATIONS] = iterations
    control[DAQP_CONTROL_TIME] = (now_ns(clock_gettime, clock_id) - start) * 1e-9


@declared("void(float64[::1], float64[::1], float64[::1], float64[::1], float64[::1], float64[::1], float64[:, ::1], "
          "float64[::1], int64, int64, int64, int64, int64, int64, int64)", cache=CACHE, nogil=True)
def daqp_solve(problem: np.ndarray, workspace: np.ndarray, result: np.ndarray, control: np.ndarray,
               data: np.ndarray, x: np.ndarray, factor: np.ndarray, lam: np.ndarray, update_ldp: int, solve: int,
               clock_gettime: int, clock_id: int, steady_mask: int, unconstrained_first: int, sense_word: int) -> None:
    """One DAQP solve of the QP whose buffers ``problem`` points to (``data``: the same QP's
    flat buffer, :class:`wbc.qp.problem.QP`), writing ``control`` (layout ``DAQP_CONTROL_*``).

    With ``unconstrained_first`` (a QP without equality rows) and no active constraint in DAQP's
    working set (the last answer met no limit), the unconstrained minimiser ``-H^-1 c`` is tried
    first (:func:`_unconstrained_answer`, ``factor``: n x n scratch): when it satisfies every
    bound and row it is the answer (exit flag 1, defect 0, 0 iterations, multipliers ``lam`` 0),
    DAQP is not called and its working set stays empty. Otherwise DAQP solves (:func:`_daqp`).
    """
    start = now_ns(clock_gettime, clock_id)
    if (unconstrained_first and _no_active_constraint(_sense_at(problem, sense_word, lam.shape[0]))
            and _unconstrained_answer(data, x, factor, lam)):
        _answered(control, 0.0, start, clock_gettime, clock_id)
    else:
        _daqp(problem, workspace, result, control, data, x, lam, update_ldp, solve, clock_gettime, clock_id,
              steady_mask, sense_word, start)


@declared("void(float64[::1], float64[::1], float64[::1], float64[::1], float64[::1], float64[::1], float64[:, ::1], "
          "float64[::1], int64, int64, int64, int64, int64, int64)", cache=CACHE, nogil=True)
def daqp_solve_working_set(problem: np.ndarray, workspace: np.ndarray, result: np.ndarray, control: np.ndarray,
                           data: np.ndarray, x: np.ndarray, scratch: np.ndarray, lam: np.ndarray, update_ldp: int,
                           solve: int, clock_gettime: int, clock_id: int, steady_mask: int, sense_word: int) -> None:
    """:func:`daqp_solve` trying DAQP's working set first: the minimiser with the last answer's
    active constraints held as equalities (:func:`_working_set_answer`; ``scratch``: (3n + 2) x n,
    H's Cholesky factor in its first n rows) is the answer when it meets every optimality
    condition of the QP (exit flag 1, 0 iterations, its multipliers in ``lam``); DAQP is then not
    called and its working set stays as it was. With no active constraint that is the
    unconstrained minimiser, taken when it meets every bound and row exactly. Otherwise DAQP
    solves (:func:`_daqp`), from that working set.
    """
    start = now_ns(clock_gettime, clock_id)
    n = x.shape[0]
    sense = _sense_at(problem, sense_word, lam.shape[0])
    if _no_active_constraint(sense):
        defect = 0.0 if _unconstrained_answer(data, x, scratch[:n], lam) else -1.0
    else:
        defect = _working_set_answer(data, sense, x, scratch[:n], lam, scratch[n:])
    if defect >= 0.0:
        _answered(control, defect, start, clock_gettime, clock_id)
    else:
        _daqp(problem, workspace, result, control, data, x, lam, update_ldp, solve, clock_gettime, clock_id,
              steady_mask, sense_word, start)


# ------------------------------------------------------- tick-program ops


@njit(inline="always")
def _daqp_solve(problem: np.ndarray, workspace: np.ndarray, result: np.ndarray, control: np.ndarray,
                data: np.ndarray, x: np.ndarray, factor: np.ndarray, lam: np.ndarray, n: int, size: int, m: int,
                update_ldp: int, solve: int, clock_gettime: int, clock_id: int, steady_mask: int,
                unconstrained_first: int, sense_word: int, flags: np.ndarray, dt: float) -> None:
    if flags[FLAG_FOUND_NAN] or flags[FLAG_STOPPED]:
        control[DAQP_CONTROL_EXITFLAG] = DAQP_SKIPPED
    else:
        daqp_solve(problem, workspace, result, control, data, x, factor, lam, update_ldp, solve, clock_gettime,
                   clock_id, steady_mask, unconstrained_first, sense_word)


#: the QP operands of the DAQP ops and their checks
_QP_OPERANDS = (("problem", (DAQP_PROBLEM_WORDS,)), ("workspace", (DAQP_WORKSPACE_WORDS,)),
                ("result", (DAQP_RESULT_WORDS,)), ("control", (DAQP_CONTROL_SIZE,)), ("data", ("size",)), ("x", ("n",)))
_DAQP_OPERANDS = (("n", None), ("size", None), ("m", None), ("update_ldp", None), ("solve", None),
                  ("clock_gettime", None), ("clock_id", None), ("steady_mask", None))
_DAQP_CHECKS = ("1 <= n", "n * n + 3 * n <= size", "(size - n * n - 3 * n) % (n + 2) == 0",
                "m == n + (size - n * n - 3 * n) // (n + 2)", "update_ldp != 0", "solve != 0", "clock_gettime != 0",
                f"0 <= sense_word < {DAQP_PROBLEM_WORDS}")

#: the compiled DAQP solve (wbc.solvers.daqp.native); skipped (exit flag DAQP_SKIPPED) when a NaN screen
#: before it found a NaN, or a BAND row stopped
DAQP_SOLVE = Op("DAQP_SOLVE", _daqp_solve, (
    *_QP_OPERANDS, ("factor", ("n", "n")), ("lam", ("m",)), *_DAQP_OPERANDS, ("unconstrained_first", None),
    ("sense_word", None), FLAGS_OPERAND), checks=_DAQP_CHECKS)


@njit(inline="always")
def _daqp_solve_working_set(problem: np.ndarray, workspace: np.ndarray, result: np.ndarray, control: np.ndarray,
                            data: np.ndarray, x: np.ndarray, scratch: np.ndarray, lam: np.ndarray, n: int, size: int,
                            m: int, update_ldp: int, solve: int, clock_gettime: int, clock_id: int, steady_mask: int,
                            sense_word: int, flags: np.ndarray, dt: float) -> None:
    if flags[FLAG_FOUND_NAN] or flags[FLAG_STOPPED]:
        control[DAQP_CONTROL_EXITFLAG] = DAQP_SKIPPED
    else:
        daqp_solve_working_set(problem, workspace, result, control, data, x, scratch, lam, update_ldp, solve,
                               clock_gettime, clock_id, steady_mask, sense_word)


#: DAQP_SOLVE trying the last working set first (daqp_solve_working_set): the lower levels of strict
#: priorities, whose band rows are active tick after tick
DAQP_SOLVE_WORKING_SET = Op("DAQP_SOLVE_WORKING_SET", _daqp_solve_working_set, (
    *_QP_OPERANDS, ("scratch", ("3 * n + 2", "n")), ("lam", ("m",)), *_DAQP_OPERANDS, ("sense_word", None),
    FLAGS_OPERAND), checks=_DAQP_CHECKS)


@njit(inline="always")
def _daqp_accept(control: np.ndarray, tolerance: np.ndarray, flags: np.ndarray, dt: float) -> None:
    if control[DAQP_CONTROL_EXITFLAG] >= 1.0 and control[DAQP_CONTROL_DEFECT] <= tolerance[0]:
        flags[FLAG_ACCEPTED] = 1
        control[DAQP_CONTROL_ACCEPTED_TIME] = control[DAQP_CONTROL_TIME]


#: the controller's check of a DAQP_SOLVE's answer (``control``, its control vector): the program's flag
#: FLAG_ACCEPTED when DAQP solved (exit flag >= 1) and the answer's defect is at most ``tolerance[0]``;
#: the solve time of an accepted answer is kept in ``control[DAQP_CONTROL_ACCEPTED_TIME]``
DAQP_ACCEPT = Op("DAQP_ACCEPT", _daqp_accept, (
    ("control", (DAQP_CONTROL_SIZE,)), ("tolerance", (1,)), FLAGS_OPERAND))
