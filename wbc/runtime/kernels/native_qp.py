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
from numba import njit, types, uint64
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
    DAQP_SENSE_ZERO_ROW,
    DAQP_SETTINGS_PRIMAL_TOL,
    DAQP_SETTINGS_WORDS,
    DAQP_SKIPPED,
    DAQP_WORKSPACE_WORDS,
    prepare_cache,
)
from ._clock import now_ns
from ._inert_rows import _int32_at, extent, inactive_after, leave_out, restore, sense_at
from ._lazy import declared
from .assembly import _minimiser, leading_defect
from .ops import FLAG_ACCEPTED, FLAG_FOUND_NAN, FLAG_STOPPED, FLAGS_OPERAND, Op

CACHE = prepare_cache()  # before the first @njit below compiles; False: no writable cache (see wbc.runtime.kernels)

#: the smallest pivot of the LU factorisation of a working set's rows (:func:`_working_set_answer`;
#: the rows scaled to largest entry 1): below it the rows are taken as dependent and DAQP solves
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
def _no_active_constraint(sense: np.ndarray) -> bool:
    """Whether DAQP's working set ``sense`` holds no active constraint (the last answer met no
    limit): every state without a bit but the side (no equality row, soft or binary constraint),
    or DAQP's mark of a row it was given as zero (``DAQP_SENSE_ZERO_ROW``, e.g. an inert row of
    CollisionAvoidance before a live row): a zero row constrains nothing -- whether its bounds
    hold 0 is the answer check's."""
    for i in range(sense.shape[0]):
        state = sense[i]
        if state & ~DAQP_SENSE_LOWER and not state & DAQP_SENSE_ZERO_ROW:
            return False
    return True


@njit(inline="always")
def _unconstrained_answer(data: np.ndarray, x: np.ndarray, factor: np.ndarray, lam: np.ndarray, given: int) -> bool:
    """``x = -H^-1 c`` (:func:`wbc.runtime.kernels.assembly._minimiser`) for the QP stored in ``data``
    (:func:`wbc.runtime.kernels.qp_defect`'s layout) when that satisfies every bound and row exactly
    (defect 0; the first ``given`` checked, the rest inert: :func:`._inert_rows.extent`): then it is
    the QP's minimiser (H positive definite: the unconstrained minimiser, feasible, is the
    constrained one), no constraint is active and every multiplier is 0 (``lam``). False otherwise
    (x then holds scratch)."""
    n = x.shape[0]
    if not _minimiser(data[:n * n + n].reshape((n + 1, n)), factor, x) or leading_defect(data, x, given) != 0.0:
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


@njit(inline="always")
def _unit_lower_back(lu: np.ndarray, k: int, b: np.ndarray) -> None:
    """``b = L1^-T b`` in place for its first ``k`` entries, ``L1`` the unit lower triangle of
    ``lu``'s first k rows (:func:`_working_set_answer`'s LU of the active rows)."""
    for aa in range(k - 1, -1, -1):
        a = uint64(aa)  # (unsigned: no negative-index fix-up)
        total = b[a]
        for pp in range(aa + 1, k):
            p = uint64(pp)
            total -= lu[p, a] * b[p]
        b[a] = total


@njit(cache=CACHE, nogil=True)
def _working_set_answer(data: np.ndarray, sense: np.ndarray, x: np.ndarray, lu: np.ndarray, lam: np.ndarray,
                        kkt: np.ndarray, tolerance: float) -> float:
    """The minimiser of the QP in ``data`` (:func:`wbc.runtime.kernels.qp_defect`'s layout) with
    the constraints of DAQP's working set ``sense`` (the last answer's active constraints) held as
    equalities, when it meets every optimality condition of the QP: then it is the QP's answer
    (``x``, multipliers ``lam``) and its defect is returned; else -1 (x and lam hold scratch).

    A null-space method on one LU factorisation of the k active constraints ``A_W x = b_W`` (a
    bound: a row of I; ``b`` the side DAQP marks: upper unless its LOWER bit is set). Each row
    ``a_i`` (and ``b_i``) is first divided by its largest entry ``s_i``: ``Â = D A_W``,
    ``D = diag(1 / s_i)``. With ``Â^T = P L U`` (partial pivoting over the n variables; ``L = [L1; L2]``,
    L1 k x k unit lower, U k x k upper) and ``y = P^T x = (y1, y2)``, the constraints read
    ``L1^T y1 + L2^T y2 = w``, ``w = U^-T D b_W``: ``x = x_p + Z y2`` with ``x_p = P (L1^-T w, 0)``
    and the null space ``Z = P (-L1^-T L2^T; I)``. ``y2`` minimises the cost on it:
    ``(Z^T H Z) y2 = -Z^T (H x_p + c)`` (Cholesky of the reduced Hessian, n - k square); the
    multipliers come from the first k rows of stationarity ``H x + c + A_W^T lam_W = 0``:
    ``L1 U (D^-1 lam_W) = -(P^T (H x + c))_1`` (the other n - k rows are ``Z^T (H x + c) = 0``,
    met by y2). A set of n constraints pins x (no reduced problem); none gives ``-H^-1 c``.

    x is the QP's answer when it is primal feasible (defect at most ``tolerance``: the primal
    tolerance of the DAQP workspace the try stands in for, 1e-6 in the levels of strict
    priorities -- DAQP, warm-started from the same set, stopped there too: on a reach, the try's
    x was DAQP's to 6e-13 in every tick where a defect between 1e-9 and 4e-7 had sent it to
    DAQP) and dual feasible (``lam >= 0`` on an upper side, ``<= 0`` on a lower side -- DAQP's sign
    convention -- any sign on an equality row): the KKT conditions of a convex QP (H is not
    factorised, so not checked: a level's H is a sum of squares plus damping). -1 also when a
    state holds another bit (soft, binary, ...), the set holds more than n constraints or
    dependent ones (a zero row, a pivot of ``Â^T`` at most :data:`WORKING_SET_LU_PIVOT`), or the
    reduced Hessian is not positive definite: DAQP then solves.

    ``lu`` (n x n scratch): ``Â^T`` (its first k columns), then L and U in place (rows swapped as
    pivoted; U's diagonal holds the reciprocals of its pivots: the solves multiply). ``kkt``
    ((3n + 7) x n scratch): rows 0-6 the row scales ``1 / s_i``, each row's constraint index, the
    pivoting P, ``w``, ``H x + c``, ``D^-1 lam_W``, the reduced gradient; then n - k rows each
    of Z's columns, of ``H Z``, and the reduced Hessian with its factor (reciprocal diagonal).
    """
    n, m = x.shape[0], lam.shape[0]
    # data indexed flat (no reshaped views: numba's reshape calls a runtime helper): H (n x n), c, C ((m - n) x n:
    # constraint i >= n at n * n + n + (i - n) n = n + i n), upper, lower (m each). Indices known to be >= 0 are
    # cast to uint64 where the loops are hot: numba adds a negative-index fix-up to every signed index
    upper = n * n + n + (m - n) * n
    lower = upper + m
    k = 0  # the active constraints, gathered in one pass: Â^T in lu's first k columns, D b_W in w
    for i in range(sense.shape[0]):
        state = sense[i]
        if state & DAQP_SENSE_ZERO_ROW:
            continue  # a row DAQP was given as zero: never in its set (see _no_active_constraint)
        if state & ~(DAQP_SENSE_ACTIVE | DAQP_SENSE_LOWER | DAQP_SENSE_IMMUTABLE):
            return -1.0  # a soft or binary constraint, or a state this kernel does not know
        if not state & DAQP_SENSE_ACTIVE:
            continue
        if k == n:
            return -1.0  # more than n
        inverse = 1.0
        if i >= n:
            base = uint64(n + i * n)
            largest = 0.0
            for a in range(n):
                largest = max(largest, abs(data[base + uint64(a)]))
            if not largest > 0.0:
                return -1.0
            inverse = 1.0 / largest
            for a in range(n):
                lu[uint64(a), uint64(k)] = data[base + uint64(a)] * inverse
        else:
            for a in range(n):
                lu[uint64(a), uint64(k)] = 0.0
            lu[uint64(i), uint64(k)] = 1.0
        kkt[3, k] = data[(lower if state & DAQP_SENSE_LOWER else upper) + i] * inverse
        kkt[0, k] = inverse
        kkt[1, k] = i
        k += 1
    d = n - k
    # kkt's rows indexed in kkt (a view of each row costs as much as the work on it): 0 scale, 1 index, 2 perm,
    # 3 w, 4 g, 5 mu, 6 r (a view: the triangular solves take it), Z from 7, H Z from 7 + d, R (a view) from 7 + 2d
    z, hz = 7, 7 + d
    r, R = kkt[6], kkt[7 + 2 * d:7 + 3 * d]
    for a in range(n):
        kkt[2, a] = a
    for c in range(k):  # Â^T = P L U in place, the variables swapped along
        col = uint64(c)
        pivot, best = col, abs(lu[col, col])
        for rr in range(c + 1, n):
            row = uint64(rr)
            if abs(lu[row, col]) > best:
                pivot, best = row, abs(lu[row, col])
        if not best > WORKING_SET_LU_PIVOT:
            return -1.0
        if pivot != col:
            for aa in range(k):
                a = uint64(aa)
                lu[col, a], lu[pivot, a] = lu[pivot, a], lu[col, a]
            kkt[uint64(2), col], kkt[uint64(2), pivot] = kkt[uint64(2), pivot], kkt[uint64(2), col]
        inverse = 1.0 / lu[col, col]
        lu[col, col] = inverse
        for rr in range(c + 1, n):
            row = uint64(rr)
            factor = lu[row, col] * inverse
            lu[row, col] = factor
            for aa in range(c + 1, k):
                a = uint64(aa)
                lu[row, a] -= factor * lu[col, a]
    w = kkt[3]
    for aa in range(k):  # w = U^-T D b_W
        a = uint64(aa)
        total = w[a]
        for pp in range(aa):
            p = uint64(pp)
            total -= lu[p, a] * w[p]
        w[a] = total * lu[a, a]
    _unit_lower_back(lu, k, w)  # y1 = L1^-T w (in w), x_p = P (y1, 0)
    for a in range(n):
        x[int(kkt[2, a])] = kkt[3, a] if a < k else 0.0
    for t in range(d):  # Z's column t: P (-L1^-T (row k + t of L2), e_t)
        for aa in range(k):
            r[uint64(aa)] = lu[uint64(k + t), uint64(aa)]
        _unit_lower_back(lu, k, r)
        for a in range(n):
            kkt[z + t, int(kkt[2, a])] = -r[a] if a < k else (1.0 if a == k + t else 0.0)
    for aa in range(n):  # g = H x_p + c, HZ = H Z
        a = uint64(aa)
        row = uint64(aa * n)
        total = data[uint64(n * n) + a]
        for pp in range(n):
            p = uint64(pp)
            total += data[row + p] * x[p]
        kkt[uint64(4), a] = total
        for t in range(d):
            total = 0.0
            for pp in range(n):
                p = uint64(pp)
                total += data[row + p] * kkt[uint64(z + t), p]
            kkt[uint64(hz + t), a] = total
    for t in range(d):  # Z^T H Z (lower triangle), -Z^T g
        total = 0.0
        for aa in range(n):
            a = uint64(aa)
            total -= kkt[uint64(z + t), a] * kkt[uint64(4), a]
        r[t] = total
        for s in range(t + 1):
            total = 0.0
            for aa in range(n):
                a = uint64(aa)
                total += kkt[uint64(z + t), a] * kkt[uint64(hz + s), a]
            R[t, s] = total
    if not _reciprocal_cholesky(R, R, d, 0.0):
        return -1.0
    _forward(R, d, r)  # y2 = (Z^T H Z)^-1 (-Z^T g); x += Z y2, g += H Z y2
    _back(R, d, r)
    for t in range(d):
        step = r[t]
        for a in range(n):
            x[a] += kkt[z + t, a] * step
            kkt[4, a] += kkt[hz + t, a] * step
    for a in range(k):  # D^-1 lam_W = -U^-1 L1^-1 (P^T g)_1
        total = -kkt[4, int(kkt[2, a])]
        for p in range(a):
            total -= lu[a, p] * kkt[5, p]
        kkt[5, a] = total
    for a in range(k - 1, -1, -1):
        total = kkt[5, a]
        for p in range(a + 1, k):
            total -= lu[a, p] * kkt[5, p]
        kkt[5, a] = total * lu[a, a]
    for i in range(m):
        lam[i] = 0.0
    for j in range(k):  # the multipliers: the sign of their side (lam then holds scratch when not)
        i = int(kkt[1, j])
        value = kkt[5, j] * kkt[0, j]
        if not sense[i] & DAQP_SENSE_IMMUTABLE and (value > 0.0 if sense[i] & DAQP_SENSE_LOWER else value < 0.0):
            return -1.0
        lam[i] = value
    defect = leading_defect(data, x, m)
    if not defect <= tolerance:
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
          steady_mask: int, sense_word: int, start: int, given: int) -> None:
    """DAQP's solve: ``daqp_update_ldp(control[MASK])`` re-forms R^-1 (hence M = A R^-1, v, d)
    from the fresh buffers, ``daqp_solve`` writes x and lam (``result`` points to both); the
    answer is then checked: its defect (:func:`wbc.runtime.kernels.qp_defect`, relative
    violation of the bounds and rows) is written, inf when x is not finite; and the time
    since ``start``. The next tick's mask is ``steady_mask``. DAQP is given the first ``given``
    constraints only, the trailing rows after them being inert (:func:`._inert_rows.extent`: met
    exactly by every x, so the answer check over the first ``given`` is the check over all)."""
    flags = _int32_at(result.ctypes.data)  # DAQPResult's int32 words
    leave_out(problem, given, lam.shape[0])
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
            defect = leading_defect(data, x, given)  # inf when x is not finite
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
    given = extent(problem, x.shape[0], lam.shape[0])
    sense = sense_at(problem, sense_word, lam.shape[0])
    if unconstrained_first and _no_active_constraint(sense[:given]) and _unconstrained_answer(data, x, factor, lam,
                                                                                                given):
        inactive_after(sense, given)
        _answered(control, 0.0, start, clock_gettime, clock_id)
    else:
        _daqp(problem, workspace, result, control, data, x, lam, update_ldp, solve, clock_gettime, clock_id,
              steady_mask, sense_word, start, given)


@declared("void(float64[::1], float64[::1], float64[::1], float64[::1], float64[::1], float64[::1], float64[:, ::1], "
          "float64[::1], int64, int64, int64, int64, int64, int64, float64)", cache=CACHE, nogil=True)
def daqp_solve_working_set(problem: np.ndarray, workspace: np.ndarray, result: np.ndarray, control: np.ndarray,
                           data: np.ndarray, x: np.ndarray, scratch: np.ndarray, lam: np.ndarray, update_ldp: int,
                           solve: int, clock_gettime: int, clock_id: int, steady_mask: int, sense_word: int,
                           primal_tol: float) -> None:
    """:func:`daqp_solve` trying DAQP's working set first: the minimiser with the last answer's
    active constraints held as equalities (:func:`_working_set_answer`; ``scratch``: (4n + 7) x n,
    its LU factors in the first n rows) is the answer when it meets every optimality
    condition of the QP, within DAQP's ``primal_tol`` (exit flag 1, 0 iterations, its
    multipliers in ``lam``); DAQP is then not
    called and its working set stays as it was. With no active constraint that is the
    unconstrained minimiser, taken when it meets every bound and row exactly. Otherwise DAQP
    solves (:func:`_daqp`), from that working set.
    """
    start = now_ns(clock_gettime, clock_id)
    n = x.shape[0]
    given = extent(problem, n, lam.shape[0])
    sense = sense_at(problem, sense_word, lam.shape[0])
    if _no_active_constraint(sense[:given]):
        defect = -1.0
        if _unconstrained_answer(data, x, scratch[:n], lam, given):
            inactive_after(sense, given)
            defect = 0.0
    else:
        defect = _working_set_answer(data, sense, x, scratch[:n], lam, scratch[n:], primal_tol)
    if defect >= 0.0:
        _answered(control, defect, start, clock_gettime, clock_id)
    else:
        _daqp(problem, workspace, result, control, data, x, lam, update_ldp, solve, clock_gettime, clock_id,
              steady_mask, sense_word, start, given)


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
                            sense_word: int, settings: np.ndarray, flags: np.ndarray, dt: float) -> None:
    if flags[FLAG_FOUND_NAN] or flags[FLAG_STOPPED]:
        control[DAQP_CONTROL_EXITFLAG] = DAQP_SKIPPED
    else:
        daqp_solve_working_set(problem, workspace, result, control, data, x, scratch, lam, update_ldp, solve,
                               clock_gettime, clock_id, steady_mask, sense_word, settings[DAQP_SETTINGS_PRIMAL_TOL])


#: DAQP_SOLVE trying the last working set first (daqp_solve_working_set): the lower levels of strict
#: priorities, whose band rows are active tick after tick
DAQP_SOLVE_WORKING_SET = Op("DAQP_SOLVE_WORKING_SET", _daqp_solve_working_set, (
    *_QP_OPERANDS, ("scratch", ("4 * n + 7", "n")), ("lam", ("m",)), *_DAQP_OPERANDS, ("sense_word", None),
    ("settings", (DAQP_SETTINGS_WORDS,)), FLAGS_OPERAND), checks=_DAQP_CHECKS)


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


@njit(inline="always")
def _daqp_accept_level(control: np.ndarray, upper: np.ndarray, flags: np.ndarray, dt: float) -> None:
    if flags[FLAG_ACCEPTED]:
        control[DAQP_CONTROL_ACCEPTED_TIME] += upper[DAQP_CONTROL_TIME]


#: strict priorities, after the last level's DAQP_ACCEPT: when it accepted, the solve time of a level
#: above (``upper``, that level's control vector) added to the accepted solve time of the last level's
#: ``control`` -- one op per level above, in order: the cascade's solve time (the levels' sum) is then
#: kept as the one QP's is, written by an accepted run only
DAQP_ACCEPT_LEVEL = Op("DAQP_ACCEPT_LEVEL", _daqp_accept_level, (
    ("control", (DAQP_CONTROL_SIZE,)), ("upper", (DAQP_CONTROL_SIZE,)), FLAGS_OPERAND))
