"""QP assembly: normal equations, holonomic preview solve, bound clip, cost normalisation,
NaN screen and the answer check (layout of :class:`wbc.qp.problem.QP`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, uint64

from . import DAQP_CONTROL_DEFECT, DAQP_CONTROL_EXITFLAG, DAQP_CONTROL_SIZE, prepare_cache
from ._lazy import declared
from .ops import FLAG_FOUND_NAN, FLAGS_OPERAND, STACK, Op

CACHE = prepare_cache()  # before the first @njit below compiles; False: no writable cache (see wbc.runtime.kernels)

# inlined by LLVM (forceinline), not by numba's IR inlining: compiled once, not copied into each caller's IR
# (a first start compiles ~0.1-0.2 s sooner, benchmarks/README.md section 8; the ticks are alike)
@njit(forceinline=True, no_cpython_wrapper=True)
def _normal_equations_of(stack_t: np.ndarray, first: int, last: int, reset: bool, Hc: np.ndarray) -> None:
    """``Hc = [H; c]`` of the least-squares stack ``A = [W J | W r]`` stored transposed.

    ``stack_t`` is ``A^T`` ((nv + 1) x rows); rows ``first:last`` of ``A`` are used:
    ``H = sum_rows (WJ)_r^T (WJ)_r``, ``c = -sum_rows (WJ)_r^T (W r)_r``, one rank-1 update
    per row over its non-zero entries only -- posture and damping rows have one, so the cost
    grows with the dense rows (nv^2 / 2 each), not with nv^2 times every row (and nothing is
    allocated). ``reset=False``
    adds to ``Hc`` instead of overwriting it (the preview rows).
    """
    nv = Hc.shape[1]
    if reset:
        for i in range(nv + 1):
            for j in range(nv):
                Hc[i, j] = 0.0
    for r in range(first, last):
        target = stack_t[nv, r]
        for i in range(nv):
            value = stack_t[i, r]
            if value == 0.0:
                continue
            for j in range(i, nv):
                other = stack_t[j, r]
                if other != 0.0:
                    Hc[i, j] += value * other
            Hc[nv, i] -= target * value
    for i in range(nv):  # mirror the upper triangle
        for j in range(i):
            Hc[i, j] = Hc[j, i]


@declared("void(float64[:, :], int64, int64, boolean, float64[:, :])", cache=CACHE, nogil=True)
def normal_equations(stack_t: np.ndarray, first: int, last: int, reset: bool, Hc: np.ndarray) -> None:
    """:func:`_normal_equations_of` on arrays of any strides (called from Python)."""
    _normal_equations_of(stack_t, first, last, reset, Hc)


@declared("float64(float64[:, :], float64[:], float64, int64, int64)", cache=CACHE, nogil=True)
def lm_curvature(stack_t: np.ndarray, feedforward: np.ndarray, dt: float, start: int, dim: int) -> float:
    """``|dt (W r - W xi)| max_j |(W J) e_j|`` of the task whose rows of ``A = [W J | W r] =
    stack_t^T`` are ``start:start + dim`` (``W xi``: their feed-forward part, ``feedforward``):
    the weighted step the task's error feedback asks this tick times the norm of its largest
    weighted Jacobian column -- the scale of the second-order term ``sum_i (W^2 dx)_i grad^2 x_i``
    that the task's linear model drops (for one revolute joint ``|d^2 p / d theta^2| =
    |d p / d theta|``, the distance to the axis). :class:`wbc.Controller` multiplies it by
    ``lm_damping``. A NaN target gives NaN (the tick's NaN screen then refuses the QP)."""
    nv = stack_t.shape[0] - 1
    step = 0.0
    for i in range(dim):
        value = dt * (stack_t[nv, start + i] - feedforward[i])
        step += value * value
    lever = 0.0
    for j in range(nv):
        column = 0.0
        for i in range(dim):
            column += stack_t[j, start + i] * stack_t[j, start + i]
        if column > lever:
            lever = column
    return math.sqrt(step) * math.sqrt(lever)


@declared("void(float64[:, :], float64, float64)", cache=CACHE, nogil=True)
def lm_damping_rows(damping_rows_t: np.ndarray, damping: float, mu: float) -> None:
    """The damping rows ``sqrt(max(damping, mu)) I`` of one weighted level (``damping_rows_t``:
    their nv x nv block of the stack ``A^T``): the damping raised to the tasks' ``mu`` where that
    is larger."""
    value = math.sqrt(max(damping, mu)) if mu == mu else mu  # a NaN mu (NaN target) stays: the screen sees it
    for j in range(damping_rows_t.shape[0]):
        damping_rows_t[j, j] = value


@declared("void(float64[:, :], float64, float64)", cache=CACHE, nogil=True)
def lm_damping_level(Hc: np.ndarray, damping: float, mu: float) -> None:
    """Raise the damping ``damping`` that one level of a hierarchy has (``Hc = [H; c]``) to its
    tasks' ``mu``: add ``max(mu - damping, 0) I`` to its H."""
    extra = mu - damping
    if extra > 0.0 or extra != extra:  # a NaN mu (NaN target) stays: the screen sees it
        for j in range(Hc.shape[1]):
            Hc[j, j] += extra


@declared("boolean(float64[:, :], float64[:, :], int64, float64)", cache=CACHE, nogil=True)
def cholesky(A: np.ndarray, factor: np.ndarray, size: int, relative: float) -> bool:
    """``A = L L^T`` for the leading ``size`` x ``size`` block of ``A`` (its lower triangle read),
    L into the lower triangle of ``factor`` (which may be ``A`` itself). False when a pivot is
    not positive, or at most ``relative`` times its diagonal entry of A (L is then partial)."""
    for j in range(size):
        pivot = A[j, j]
        for p in range(j):
            pivot -= factor[j, p] * factor[j, p]
        if not pivot > 0.0 or pivot <= relative * A[j, j]:
            return False
        factor[j, j] = math.sqrt(pivot)
        for a in range(j + 1, size):
            total = A[a, j]
            for p in range(j):
                total -= factor[a, p] * factor[j, p]
            factor[a, j] = total / factor[j, j]
    return True


@declared("void(float64[:, :], int64, float64[:])", cache=CACHE, nogil=True)
def forward_substitution(factor: np.ndarray, size: int, b: np.ndarray) -> None:
    """``b = L^-1 b`` in place (L: the lower triangle of ``factor``'s leading ``size`` block)."""
    for a in range(size):
        total = b[a]
        for p in range(a):
            total -= factor[a, p] * b[p]
        b[a] = total / factor[a, a]


@declared("void(float64[:, :], int64, float64[:])", cache=CACHE, nogil=True)
def back_substitution(factor: np.ndarray, size: int, b: np.ndarray) -> None:
    """``b = L^-T b`` in place (L: the lower triangle of ``factor``'s leading ``size`` block)."""
    for a in range(size - 1, -1, -1):
        total = b[a]
        for p in range(a + 1, size):
            total -= factor[p, a] * b[p]
        b[a] = total / factor[a, a]


@njit(inline="always")
def _minimiser(Hc: np.ndarray, factor: np.ndarray, x: np.ndarray) -> bool:
    """``x = -H^-1 c``, the unconstrained minimiser of ``1/2 x^T H x + c^T x`` (``Hc = [H; c]``),
    by Cholesky ``H = L L^T`` (``factor``: n x n scratch, L in its lower triangle). Returns False,
    with ``x = 0``, when H is not positive definite."""
    nv = Hc.shape[1]
    if not cholesky(Hc, factor, nv, 0.0):
        for i in range(nv):
            x[i] = 0.0
        return False
    for a in range(nv):
        x[a] = -Hc[nv, a]
    forward_substitution(factor, nv, x)
    back_substitution(factor, nv, x)
    return True


@declared("boolean(float64[:, :], float64[:, :], float64[:])", cache=CACHE, nogil=True)
def preview_solve(Hc: np.ndarray, factor: np.ndarray, preview: np.ndarray) -> bool:
    """Holonomic relaxation ``preview = -H^-1 c`` by Cholesky (:func:`_minimiser`; ``factor``: nv x nv
    scratch). Returns False, with ``preview = 0``, when H is not positive definite (no damping)."""
    return _minimiser(Hc, factor, preview)


@declared("void(float64[:, :], int64, float64[:], float64[:])", cache=CACHE, nogil=True)
def merge_bounds(bounds: np.ndarray, n_hard: int, upper: np.ndarray, lower: np.ndarray) -> None:
    """The QP's bounds from every bounded constraint's own pair (:class:`wbc.qp.bounds.BoundPolicy`).

    ``bounds`` holds, per constraint k, its upper bound in row 2k and its lower bound in row
    2k + 1, the ``n_hard`` hard constraints first. Hard bounds are intersected; soft ones are
    intersected, set to the midpoint where they exclude each other, and clipped into the hard
    ones (without hard bounds: taken as they are)."""
    count = bounds.shape[0] // 2
    for i in range(bounds.shape[1]):
        hard_upper, hard_lower = math.inf, -math.inf
        for k in range(n_hard):
            hard_upper = min(hard_upper, bounds[2 * k, i])
            hard_lower = max(hard_lower, bounds[2 * k + 1, i])
        if n_hard == count:
            upper[i], lower[i] = hard_upper, hard_lower
            continue
        soft_upper, soft_lower = math.inf, -math.inf
        for k in range(n_hard, count):
            soft_upper = min(soft_upper, bounds[2 * k, i])
            soft_lower = max(soft_lower, bounds[2 * k + 1, i])
        if soft_lower > soft_upper:
            soft_upper = soft_lower = 0.5 * (soft_upper + soft_lower)
        if n_hard == 0:
            upper[i], lower[i] = soft_upper, soft_lower
        else:
            upper[i] = min(max(soft_upper, hard_lower), hard_upper)
            lower[i] = min(max(soft_lower, hard_lower), hard_upper)


@declared("void(float64[:, :], float64, float64)", cache=CACHE, nogil=True)
def normalise_cost(Hc: np.ndarray, damping: float, damping_floor: float) -> None:
    """Scale ``[H; c]`` so that ``max_i H_ii = 1`` (the minimiser is unchanged), then raise the
    damping to at least ``damping_floor`` of that scale.

    Costs far from 1 (a weight of 1e11, or 1e-12 everywhere) otherwise meet absolute
    tolerances inside the solvers: DAQP then returned answers violating hard rows by O(1).
    ``damping`` is the part of ``H_ii`` that is damping: where it is below ``damping_floor``
    times the scale, ``H`` is numerically singular in double precision (costs 1e12 over a
    damping of 1e-3) and the floor is added, a regularisation below every solver's tolerance."""
    n = Hc.shape[1]
    scale = 0.0
    for i in range(n):
        scale = max(scale, Hc[i, i])
    if scale > 0.0 and math.isfinite(scale):
        inverse = 1.0 / scale
        for i in range(n + 1):
            for j in range(n):
                Hc[i, j] *= inverse
        missing = damping_floor - damping * inverse
        if missing > 0.0:
            for i in range(n):
                Hc[i, i] += missing


@njit(inline="always")
def _defect(C: np.ndarray, c0: int, upper: np.ndarray, u0: int, lower: np.ndarray, l0: int, x: np.ndarray,
            count: int) -> float:
    """:func:`constraint_defect` over the first ``count`` constraints, with ``C`` flat (row-major,
    from ``C[c0]``) and the sides from ``upper[u0]`` and ``lower[l0]``: offsets into the arrays
    (the QP's flat buffer for all three, :func:`leading_defect`), not slices of them (a view
    costs as much as a fifth of the loop). Unsigned indices: numba adds no negative-index fix-up
    to them (~20 % of the loop)."""
    n = x.shape[0]
    worst = 0.0
    for index in range(count):
        i = uint64(index)
        if index < n:
            value = x[i]
            size = abs(value)
        else:
            value = 0.0
            size = 0.0
            row = uint64(c0 + (index - n) * n)
            for column in range(n):
                j = uint64(column)
                term = C[row + j] * x[j]
                value += term
                size += abs(term)
        if not math.isfinite(value):
            return math.inf
        high, low = upper[uint64(u0) + i], lower[uint64(l0) + i]
        excess = max(value - high, low - value)
        if excess > 0.0:
            bound = high if value > high else low
            worst = max(worst, excess / max(1.0, abs(bound), size))
    return worst


@declared("float64(float64[:, ::1], float64[:], float64[:], float64[:])", cache=CACHE, nogil=True)
def constraint_defect(C: np.ndarray, upper: np.ndarray, lower: np.ndarray, x: np.ndarray) -> float:
    """Largest relative violation of ``lower <= (x; C x) <= upper`` (the layout of
    :class:`wbc.qp.problem.QP`): each violation is divided by ``max(1, |bound|, sum_j |C_rj x_j|)``,
    the size of the numbers it was computed from. NaN in ``x`` gives inf."""
    return _defect(C.reshape(C.size), 0, upper, 0, lower, 0, x, upper.shape[0])


@njit(inline="always")
def _qp_defect(data: np.ndarray, x: np.ndarray, given: int) -> float:
    """:func:`_defect` of ``x`` over the first ``given`` constraints of the QP stored in ``data``."""
    n = x.shape[0]
    m = n + (data.shape[0] - n * n - 3 * n) // (n + 2)
    start = n * n + n  # C's first entry
    upper = start + (m - n) * n
    lower = upper + m
    return _defect(data, start, data, upper, data, lower, x, given)


@declared("float64(float64[::1], float64[:])", cache=CACHE, nogil=True)
def qp_defect(data: np.ndarray, x: np.ndarray) -> float:
    """:func:`constraint_defect` of ``x`` on the QP stored in ``data`` (:class:`wbc.qp.problem.QP`'s
    flat buffer: H (n x n), c (n), C (rows x n), upper, lower (n + rows each), so
    ``len(data) = n^2 + 3 n + rows (n + 2)``) with ``n = len(x)``: the check run on every
    answer, with two arguments (each costs ~0.1 us to pass), on offsets into ``data`` (a reshaped
    view of C would cost a runtime call in numba). ``x`` of any stride (Python's answer checks);
    the compiled solves call :func:`leading_defect`."""
    n = x.shape[0]
    return _qp_defect(data, x, n + (data.shape[0] - n * n - 3 * n) // (n + 2))


@declared("float64(float64[::1], float64[::1], int64)", cache=CACHE, nogil=True)
def leading_defect(data: np.ndarray, x: np.ndarray, given: int) -> float:
    """:func:`qp_defect` over the first ``given`` of the QP's m bounds and rows (the rest inert:
    met exactly by every x, :func:`wbc.runtime.kernels._inert_rows.extent`), ``x`` contiguous
    (the compiled solves' answer: its loads then need no stride, ~20 % of the loop). Compiled
    once, for one signature: the native solve calls it from three places."""
    return _qp_defect(data, x, given)


@njit(inline="always")
def _any_nan(data: np.ndarray) -> bool:
    """:func:`has_nan` in one pass without an early exit: a reduction the compiler vectorises on a
    contiguous array (~4x faster than returning at the first NaN, a pass that a NaN-free QP --
    nearly every tick -- makes to its end anyway)."""
    found = False
    for i in range(data.shape[0]):
        found |= data[i] != data[i]
    return found


@njit(inline="always")
def _any_non_finite(data: np.ndarray) -> bool:
    """:func:`has_non_finite` as :func:`_any_nan` (``x - x`` is NaN exactly for a NaN or infinite x)."""
    found = False
    for i in range(data.shape[0]):
        difference = data[i] - data[i]
        found |= difference != difference
    return found


@declared("boolean(float64[:])", cache=CACHE, nogil=True)
def has_nan(data: np.ndarray) -> bool:
    """True when some entry of ``data`` is NaN (infinite entries are allowed: open bounds)."""
    return _any_nan(data)


@declared("boolean(float64[:])", cache=CACHE, nogil=True)
def has_non_finite(data: np.ndarray) -> bool:
    """True when some entry of ``data`` is NaN or infinite."""
    return _any_non_finite(data)


@declared("boolean(float64[:, :], float64[:], float64[::1], float64[::1], int64, int64, int64, int64, float64, "
          "float64)", cache=CACHE, nogil=True)
def lift_qp(stack_t: np.ndarray, diagonal: np.ndarray, source: np.ndarray, lifted: np.ndarray, nv: int, k: int,
            p: int, e: int, damping: float, damping_floor: float) -> bool:
    """The lifted form of the QP (:mod:`wbc.qp.lifting`): its dense stack rows as ``k`` auxiliary
    variables. Returns True when a NaN was met (nothing to solve).

    ``stack_t``: the task stack ``A^T`` ((nv + 1) x rows); ``diagonal[r] = 1`` for a row with
    one non-zero entry (posture, damping), 0 for a dense one (k of them). ``source``: the
    v-QP's buffer (:class:`wbc.qp.problem.QP` with nv variables, p inequality and e equality rows;
    its bounds and rows are read, its H and c are not used). ``lifted``: the buffer of the
    QP over ``x = (v, w)``, N = nv + k variables, rows ``[G 0; A 0; U -I]``::

        min 1/2 v^T D v + d^T v + 1/2 |w|^2 - t^T w   s.t. U v - w = 0 and the v-QP's limits,

    ``D = sum`` of the squared diagonal entries, ``d = -sum`` of their ``entry * target``;
    ``U`` the dense rows, ``t`` their targets. Off-diagonal H entries and the w columns of
    G, A are zero from allocation and never written. As :func:`normalise_cost`: the cost is
    scaled by the largest curvature of the v-problem ``max_i (D_ii + sum_r U_ri^2)`` and the
    damping floored at ``damping_floor`` of that scale.
    """
    rows = diagonal.shape[0]
    n = nv + k
    m_src, m = nv + p + e, n + p + e + k
    c0, C0 = n * n, n * n + n
    up0 = C0 + (p + e + k) * n
    lo0 = up0 + m
    src_C0 = nv * nv + nv
    src_up0 = src_C0 + (p + e) * nv
    src_lo0 = src_up0 + m_src
    for i in range(n):
        lifted[i * n + i] = 0.0
        lifted[c0 + i] = 0.0
    slot = 0
    for r in range(rows):
        target = stack_t[nv, r]
        if target != target:
            return True
        if diagonal[r] != 0.0:
            column = -1
            for i in range(nv):
                value = stack_t[i, r]
                if value != 0.0:
                    if value != value or column >= 0:  # NaN, or a second entry: not a diagonal row
                        return True
                    column = i
            if column >= 0:
                value = stack_t[column, r]
                lifted[column * n + column] += value * value
                lifted[c0 + column] -= value * target
            continue
        row = C0 + (p + e + slot) * n
        for i in range(nv):
            value = stack_t[i, r]
            if value != value:
                return True
            lifted[row + i] = value
        lifted[row + nv + slot] = -1.0
        lifted[nv * n + nv + slot + slot * n] = 1.0  # H[nv + slot, nv + slot]
        lifted[c0 + nv + slot] = -target
        lifted[up0 + n + p + e + slot] = 0.0
        lifted[lo0 + n + p + e + slot] = 0.0
        slot += 1
    # the v-QP's rows and bounds
    for a in range(p + e):
        for i in range(nv):
            value = source[src_C0 + a * nv + i]
            if value != value:
                return True
            lifted[C0 + a * n + i] = value
    for i in range(nv):
        lifted[up0 + i], lifted[lo0 + i] = source[src_up0 + i], source[src_lo0 + i]
    for a in range(p + e):
        lifted[up0 + n + a], lifted[lo0 + n + a] = source[src_up0 + nv + a], source[src_lo0 + nv + a]
    for i in range(n + p + e):
        if lifted[up0 + i] != lifted[up0 + i] or lifted[lo0 + i] != lifted[lo0 + i]:
            return True
    # normalisation (see normalise_cost): the v-problem's curvature D_ii + sum_r U_ri^2
    scale = 0.0
    for i in range(nv):
        curvature = lifted[i * n + i]
        for j in range(k):
            value = lifted[C0 + (p + e + j) * n + i]
            curvature += value * value
        scale = max(scale, curvature)
    if scale > 0.0 and math.isfinite(scale):
        inverse = 1.0 / scale
        for i in range(n):
            lifted[i * n + i] *= inverse
            lifted[c0 + i] *= inverse
        missing = damping_floor - damping * inverse
        if missing > 0.0:
            for i in range(nv):
                lifted[i * n + i] += missing
    return False


@declared("float64(float64[::1], float64[::1], float64[::1], float64[::1], int64, int64, int64, int64)", cache=CACHE,
          nogil=True)
def lifted_stationarity(lifted: np.ndarray, x: np.ndarray, lam: np.ndarray, scratch: np.ndarray, nv: int, k: int,
                        p: int, e: int) -> float:
    """How far the v part of a lifted QP's answer (:func:`lift_qp`'s buffer ``lifted``, answer
    ``x = (v, w)`` with multipliers ``lam``: bounds, then rows, DAQP's signs) is from the
    stationarity of the *v-problem* it stands for, with ``w = U v`` substituted:

        r = D v + d + U^T (W U v + c_w) + lam_bounds[:nv] + G^T lam_rows[:p + e] = 0,

    ``W``, ``c_w`` the w block of the Hessian and cost; ``scratch`` (2 nv): r and the sums of
    the magnitudes of its terms. Returns ``max_i |r_i| / s_i`` (rows whose terms are all 0
    count 0; inf when x is not finite). O(nv (k + active rows)), row-major. An exact answer
    gives ~1e-15; the lifted QP's equality rows can hide an answer that is not the v-problem's
    optimum (an ill-conditioned LDP) behind a small residual of their own -- this one sees it."""
    n = nv + k
    C0 = n * n + n
    rows = p + e
    value, size = scratch[:nv], scratch[nv:2 * nv]
    for i in range(nv):
        curvature = lifted[i * n + i] * x[i]
        value[i] = curvature + lifted[n * n + i] + lam[i]
        size[i] = abs(curvature) + abs(lifted[n * n + i]) + abs(lam[i])
    for a in range(rows):
        multiplier = lam[n + a]
        if multiplier == 0.0:  # an inactive row
            continue
        row = C0 + a * n
        for i in range(nv):
            term = lifted[row + i] * multiplier
            value[i] += term
            size[i] += abs(term)
    for j in range(k):
        row = C0 + (rows + j) * n
        uv = 0.0
        for t in range(nv):
            uv += lifted[row + t] * x[t]
        w_slot = nv + j
        pull, push = lifted[w_slot * n + w_slot] * uv, lifted[n * n + w_slot]
        magnitude = abs(pull) + abs(push)
        for i in range(nv):
            u = lifted[row + i]
            value[i] += u * (pull + push)
            size[i] += abs(u) * magnitude
    worst = 0.0
    for i in range(nv):
        if not math.isfinite(value[i]):
            return math.inf
        if size[i] > 0.0:
            worst = max(worst, abs(value[i]) / size[i])
    return worst


# ------------------------------------------------------- tick-program ops


@njit(inline="always")
def _normal_equations(stack: np.ndarray, nv: int, rows: int, first: int, last: int, reset: int, Hc: np.ndarray,
                      dt: float) -> None:
    _normal_equations_of(stack, first, last, reset != 0, Hc)  # compiled here for the program's C-contiguous arrays


#: [H; c] of the stack's rows first:last, added to Hc (or written, reset = 1)
NORMAL_EQUATIONS = Op("NORMAL_EQUATIONS", _normal_equations, (
    STACK, ("nv", None), ("rows", None), ("first", None), ("last", None), ("reset", None),
    ("Hc", ("nv + 1", "nv"))), checks=("0 <= first", "first <= last", "last <= rows"))


@njit(inline="always")
def _linear_cost(stack: np.ndarray, nv: int, rows: int, first: int, last: int, Hc: np.ndarray, dt: float) -> None:
    for r in range(first, last):
        for i in range(nv):
            Hc[nv, i] += stack[i, r]


#: c += the W J part of the stack's rows first:last (linear cost terms c_k^T v, no Hessian)
LINEAR_COST = Op("LINEAR_COST", _linear_cost, (
    STACK, ("nv", None), ("rows", None), ("first", None), ("last", None), ("Hc", ("nv + 1", "nv"))),
    checks=("0 <= first", "first <= last", "last <= rows"))


@njit(inline="always")
def _preview(Hc: np.ndarray, factor: np.ndarray, preview: np.ndarray, nv: int, dt: float) -> None:
    _minimiser(Hc, factor, preview)


#: the holonomic preview H^-1 c (factor: scratch)
PREVIEW = Op("PREVIEW", _preview, (("Hc", ("nv + 1", "nv")), ("factor", ("nv", "nv")), ("preview", ("nv",)),
                                   ("nv", None)))


@njit(inline="always")
def _merge_bounds(bounds: np.ndarray, count: int, n_hard: int, nv: int, upper: np.ndarray, lower: np.ndarray,
                  dt: float) -> None:
    merge_bounds(bounds, n_hard, upper, lower)


#: the QP's bounds from the (upper, lower) pairs of count bounded constraints, the first n_hard hard
MERGE_BOUNDS = Op("MERGE_BOUNDS", _merge_bounds, (
    ("bounds", ("2 * count", "nv")), ("count", None), ("n_hard", None), ("nv", None), ("upper", ("nv",)),
    ("lower", ("nv",))), checks=("1 <= count", "0 <= n_hard <= count"))


@njit(inline="always")
def _has_nan(data: np.ndarray, size: int, infinite: int, flags: np.ndarray, dt: float) -> None:
    if flags[FLAG_FOUND_NAN] == 0 and (_any_non_finite(data) if infinite else _any_nan(data)):
        flags[FLAG_FOUND_NAN] = 1


#: the NaN screen (infinite = 1: infinite entries count too): sets the found-NaN flag, which skips
#: every later DAQP_SOLVE and makes run_program return True
HAS_NAN = Op("HAS_NAN", _has_nan, (("data", ("size",)), ("size", None), ("infinite", None), FLAGS_OPERAND),
             checks=("0 <= infinite <= 1",))


@njit(inline="always")
def _lm_task(stack: np.ndarray, feedforward: np.ndarray, mu: np.ndarray, lm: np.ndarray, start: int, dim: int,
             nv: int, rows: int, reset: int, dt: float) -> None:
    if reset:
        mu[0] = 0.0
    if lm[0] > 0.0:
        mu[0] += lm[0] * lm_curvature(stack, feedforward, dt, start, dim)


#: adds lm_damping times the task's lm_curvature to mu (reset = 1: mu starts from 0)
LM_TASK = Op("LM_TASK", _lm_task, (
    STACK, ("feedforward", ("dim",)), ("mu", (1,)), ("lm", (1,)), ("start", None), ("dim", None), ("nv", None),
    ("rows", None), ("reset", None)), checks=("0 <= start", "start + dim <= rows", "0 <= reset <= 1"))


@njit(inline="always")
def _lm_damping_rows(stack: np.ndarray, mu: np.ndarray, scaling: np.ndarray, nv: int, rows: int, first: int,
                     dt: float) -> None:
    lm_damping_rows(stack[:nv, first:first + nv], scaling[0], mu[0])


#: the damping rows (first:first + nv of the stack) of a weighted level; scaling = (damping, floor)
LM_DAMPING_ROWS = Op("LM_DAMPING_ROWS", _lm_damping_rows, (
    STACK, ("mu", (1,)), ("scaling", (2,)), ("nv", None), ("rows", None), ("first", None)),
    checks=("0 <= first", "first + nv <= rows"))


@njit(inline="always")
def _lm_damping_level(mu: np.ndarray, scaling: np.ndarray, Hc: np.ndarray, nv: int, dt: float) -> None:
    lm_damping_level(Hc, scaling[0], mu[0])


#: the damping added to the Hessian of one level of a hierarchy
LM_DAMPING_LEVEL = Op("LM_DAMPING_LEVEL", _lm_damping_level, (
    ("mu", (1,)), ("scaling", (2,)), ("Hc", ("nv + 1", "nv")), ("nv", None)))


@njit(inline="always")
def _normalise_cost(Hc: np.ndarray, scaling: np.ndarray, nv: int, dt: float) -> None:
    normalise_cost(Hc, scaling[0], scaling[1])


#: the cost normalisation; scaling = (damping, damping floor)
NORMALISE_COST = Op("NORMALISE_COST", _normalise_cost, (("Hc", ("nv + 1", "nv")), ("scaling", (2,)),
                                                         ("nv", None)))


@njit(inline="always")
def _lift(stack: np.ndarray, diagonal: np.ndarray, source: np.ndarray, lifted: np.ndarray, scaling: np.ndarray,
          nv: int, stack_rows: int, rows: int, k: int, p: int, e: int, source_size: int, lifted_size: int,
          flags: np.ndarray, dt: float) -> None:
    if lift_qp(stack, diagonal, source, lifted, nv, k, p, e, scaling[0], scaling[1]):
        flags[FLAG_FOUND_NAN] = 1


#: the lifted QP (wbc.qp.lifting) from the stack and the source QP; a NaN met sets the found-NaN flag
LIFT = Op("LIFT", _lift, (
    ("stack", ("nv + 1", "stack_rows")), ("diagonal", ("rows",)), ("source", ("source_size",)),
    ("lifted", ("lifted_size",)), ("scaling", (2,)), ("nv", None), ("stack_rows", None), ("rows", None),
    ("k", None), ("p", None), ("e", None), ("source_size", None), ("lifted_size", None), FLAGS_OPERAND),
    checks=("1 <= nv", "0 <= k <= rows <= stack_rows", "0 <= p", "0 <= e",
            "source_size == nv * nv + 3 * nv + (p + e) * (nv + 2)",
            "lifted_size == (nv + k) * (nv + k) + 3 * (nv + k) + (p + e + k) * (nv + k + 2)"))


@njit(inline="always")
def _lift_check(lifted: np.ndarray, x: np.ndarray, lam: np.ndarray, scratch: np.ndarray, control: np.ndarray,
                nv: int, k: int, p: int, e: int, lifted_size: int, dt: float) -> None:
    if control[DAQP_CONTROL_EXITFLAG] >= 1:
        stationarity = lifted_stationarity(lifted, x, lam, scratch, nv, k, p, e)
        control[DAQP_CONTROL_DEFECT] = max(control[DAQP_CONTROL_DEFECT], stationarity)


#: after a successful solve of the lifted QP, its defect becomes the larger of the answer's defect
#: and its stationarity in v (lifted_stationarity)
LIFT_CHECK = Op("LIFT_CHECK", _lift_check, (
    ("lifted", ("lifted_size",)), ("x", ("nv + k",)), ("lam", ("nv + k + p + e + k",)), ("scratch", ("2 * nv",)),
    ("control", (DAQP_CONTROL_SIZE,)), ("nv", None), ("k", None), ("p", None), ("e", None), ("lifted_size", None)),
    checks=("1 <= nv", "0 <= k", "0 <= p", "0 <= e",
            "lifted_size == (nv + k) * (nv + k) + 3 * (nv + k) + (p + e + k) * (nv + k + 2)"))
