"""Kernels of strict task priorities (:mod:`wbc.control.hierarchy`): the QP of each level below the
first gets the controller's constraints (:func:`level_constraints`) and, once the levels above
are solved, the band rows that hold their task values (:func:`band_rows`); a level's cost is
normalised like the one-level QP (:func:`normalise_level`); and the holonomic preview of a
hierarchy is its cascade without constraints (:func:`hierarchy_preview`).

QP layouts are those of :class:`wbc.qp.problem.QP` (one flat buffer: H, c, C, upper, lower).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from . import DAQP_CONTROL_DEFECT, DAQP_CONTROL_EXITFLAG, DAQP_CONTROL_SIZE, prepare_cache
from ._lazy import declared
from .assembly import normalise_cost
from .manipulability import _jacobi_eigenvectors
from .ops import FLAG_FOUND_NAN, FLAG_STOPPED, FLAGS_OPERAND, STACK, Op

CACHE = prepare_cache()  # before the first @njit below compiles; False: no writable cache (see wbc.runtime.kernels)


@njit(inline="always")
def _copy(source: np.ndarray, start: int, target: np.ndarray, to: int, count: int) -> None:
    """``target[to:to + count] = source[start:start + count]`` as a loop over views: the compiler
    vectorises it (indexed ``target[to + i]``, a signed offset, each access gets numba's
    negative-index fix-up, and the copy was ~6x slower)."""
    origin, destination = source[start:start + count], target[to:to + count]
    for i in range(count):
        destination[i] = origin[i]


@declared("void(float64[::1], float64[::1], int64, int64, int64, int64)", cache=CACHE, nogil=True)
def level_constraints(source: np.ndarray, target: np.ndarray, n: int, p: int, e: int, band: int) -> None:
    """Copy the bounds and rows of the QP in ``source`` (n variables, p inequality and e equality
    rows) into the QP in ``target`` (p + band inequality rows, then the same e equality rows):
    the inequality rows go first, the ``band`` rows after them are left as they are."""
    rows = n * n + n  # C's first entry in both
    _copy(source, rows, target, rows, p * n)
    _copy(source, rows + p * n, target, rows + (p + band) * n, e * n)
    m_src, m_dst = n + p + e, n + p + band + e
    src_up, dst_up = rows + (p + e) * n, rows + (p + band + e) * n
    for side in range(2):  # upper, then lower
        src, dst = src_up + side * m_src, dst_up + side * m_dst
        _copy(source, src, target, dst, n + p)
        _copy(source, src + n + p, target, dst + n + p + band, e)


@declared("void(float64[:, :], float64, float64)", cache=CACHE, nogil=True)
def normalise_level(Hc: np.ndarray, damping: float, damping_floor: float) -> None:
    """:func:`wbc.runtime.kernels.normalise_cost` of one level's ``[H; c]``; a level whose rows are all
    zero this tick (H = 0, hence c = 0) gets ``H = I``: every feasible point is optimal for it
    and the solver takes the smallest."""
    normalise_cost(Hc, damping, damping_floor)
    n = Hc.shape[1]
    for i in range(n):
        if Hc[i, i] != 0.0:
            return
    for i in range(n):
        Hc[i, i] = 1.0


@njit(inline="always")
def _band_row(stack_t: np.ndarray, r: int, x: np.ndarray, lower: np.ndarray, upper: np.ndarray, size: float,
              relative: float, data: np.ndarray, row: int, h: int, gap: int) -> None:
    """The band of stack row ``r`` in a QP in ``data``, divided by ``|a|`` (unit rows: a band is as
    tight for a task weighted 1e-12 as for one weighted 1e12, in the solvers' and the answer
    check's absolute and relative tolerances): with ``gap > 0`` row ``row``,
    ``y - eps <= a v <= y + eps`` (upper side at ``h``, lower side at ``h + gap``); with ``gap``
    0 rows ``row`` and ``row + 1``, ``+-a v <= +-y + eps`` (upper sides at ``h``, ``h + 1``). A zero
    row gets ``0 <= 0``, its other side open: inert, never an equality row."""
    nv = x.shape[0]
    norm = 0.0
    for j in range(nv):
        norm += stack_t[j, r] * stack_t[j, r]
    norm = math.sqrt(norm)
    scale = 1.0 / norm if norm > 0.0 else 0.0
    value = 0.0
    for j in range(nv):
        a = stack_t[j, r] * scale
        value += a * min(max(x[j], lower[j]), upper[j])
        data[row + j] = a
    width = relative * size if norm > 0.0 else 0.0
    data[h] = value + width
    if gap == 0:
        for j in range(nv):
            data[row + nv + j] = -data[row + j]
        data[h + 1] = width - value
    else:
        data[h + gap] = value - width if norm > 0.0 else -math.inf


@declared("void(float64[:, :], int64, int64, int64, int64, float64[:], float64[:], float64[:], float64, float64[::1], "
          "int64, int64, int64)", cache=CACHE, nogil=True)
def band_rows(stack_t: np.ndarray, first: int, last: int, first_preview: int, last_preview: int, x: np.ndarray,
              lower: np.ndarray, upper: np.ndarray, relative: float, data: np.ndarray, row: int, target_rows: int,
              two_sided: int) -> None:
    """The band that holds a solved level's task values for the levels below it.

    For each stack row ``a`` of the level (rows ``first:last`` and ``first_preview:last_preview``
    of ``A = stack_t^T``), divided by ``|a|``::

        y - eps <= a v <= y + eps,   y = a x_b,   eps = relative |a| max(1, |x_b|_inf)

    at the level's answer ``x`` projected onto the bounds ``[lower, upper]`` (``x_b``: exact on
    the bounds whatever the solver's tolerance). The rows go into the QP buffer ``data``
    (:class:`wbc.qp.problem.QP`'s layout: H, c, the ``target_rows`` rows C, then the upper and the
    lower sides of its m = nv + target_rows constraints), from its row ``row`` of C on. With
    ``two_sided`` (a backend that takes rows with two sides: DAQP) one row each, both sides
    written; otherwise (backends that take ``G v <= h`` only) two rows each, ``a v <= y + eps``
    and ``-a v <= -y + eps``, their lower sides left open.
    """
    size = 1.0
    for j in range(x.shape[0]):
        size = max(size, abs(min(max(x[j], lower[j]), upper[j])))
    nv, count, sides = x.shape[0], last - first, 1 if two_sided else 2
    rows_start = nv * nv + nv  # C's first entry
    upper_start = rows_start + target_rows * nv  # the upper sides (bounds, then rows)
    gap = nv + target_rows if two_sided else 0  # from a row's upper side to its lower side
    for slot in range(count + last_preview - first_preview):  # (one call site: _band_row is inlined once)
        r = first + slot if slot < count else first_preview + slot - count
        _band_row(stack_t, r, x, lower, upper, size, relative, data, rows_start + (row + sides * slot) * nv,
                  upper_start + nv + row + sides * slot, gap)


@declared("void(float64[:, :], float64[:], float64, float64[:])", cache=CACHE, nogil=True)
def hierarchy_preview(stack_t: np.ndarray, ranges: np.ndarray, floor: float, preview: np.ndarray) -> None:
    """Holonomic relaxation of a hierarchy: its levels solved in order without constraints.

    Level k is rows ``ranges[2k]:ranges[2k + 1]`` of ``A = [W J | W r] = stack_t^T`` (the last
    level's include ``sqrt(damping) I``). With ``Z`` an orthonormal basis of the directions the
    levels above leave free (``Z = I`` at first) and ``v`` their answer, level k takes
    ``v += Z z``, ``z = argmin |A_k Z z - (b_k - A_k v)|^2 + mu |z|^2`` (``mu = floor`` times the
    largest curvature ``max diag Z^T A_k^T A_k Z``), then keeps in ``Z`` the eigenvectors of
    ``Z^T A_k^T A_k Z`` whose eigenvalues are at most ``floor`` times the largest: the classical
    null-space projection. ``preview`` = v. Ranges are clipped to the stack; rows holding NaN
    or inf give ``preview = 0`` (the tick's NaN screen reports them).
    """
    nv, rows = stack_t.shape[0] - 1, stack_t.shape[1]
    basis = np.eye(nv)
    free = nv
    for j in range(nv):
        preview[j] = 0.0
    levels = ranges.shape[0] // 2
    for k in range(levels):
        first = min(max(int(ranges[2 * k]), 0), rows)
        last = min(max(int(ranges[2 * k + 1]), first), rows)
        count = last - first
        if free == 0 or count == 0:
            continue
        projected, residual = np.empty((count, free)), np.empty(count)
        for i in range(count):
            r = first + i
            value = stack_t[nv, r]
            for j in range(nv):
                value -= stack_t[j, r] * preview[j]
            residual[i] = value
            for c in range(free):
                total = 0.0
                for j in range(nv):
                    total += stack_t[j, r] * basis[j, c]
                projected[i, c] = total
            if not math.isfinite(value):
                for j in range(nv):
                    preview[j] = 0.0
                return
        normal, gradient = np.empty((free, free)), np.zeros(free)
        scale = 0.0
        for a in range(free):
            for b in range(free):
                total = 0.0
                for i in range(count):
                    total += projected[i, a] * projected[i, b]
                normal[a, b] = total
            for i in range(count):
                gradient[a] += projected[i, a] * residual[i]
            scale = max(scale, normal[a, a])
        if not (scale > 0.0 and math.isfinite(scale)):
            if not math.isfinite(scale):
                for j in range(nv):
                    preview[j] = 0.0
                return
            continue
        # z = (N + mu I)^-1 g by Cholesky (positive definite: mu > 0)
        factor = normal.copy()
        for a in range(free):
            factor[a, a] += floor * scale
        for a in range(free):
            pivot = factor[a, a]
            for p in range(a):
                pivot -= factor[a, p] * factor[a, p]
            pivot = math.sqrt(max(pivot, floor * scale))
            factor[a, a] = pivot
            for b in range(a + 1, free):
                total = factor[b, a]
                for p in range(a):
                    total -= factor[b, p] * factor[a, p]
                factor[b, a] = total / pivot
        step = gradient.copy()
        for a in range(free):
            for p in range(a):
                step[a] -= factor[a, p] * step[p]
            step[a] /= factor[a, a]
        for a in range(free - 1, -1, -1):
            for p in range(a + 1, free):
                step[a] -= factor[p, a] * step[p]
            step[a] /= factor[a, a]
        for j in range(nv):
            for a in range(free):
                preview[j] += basis[j, a] * step[a]
        if k == levels - 1:
            break
        values, vectors = np.empty(free), np.empty((free, free))
        _jacobi_eigenvectors(normal, vectors)  # normal ends diagonal: its eigenvalues
        for a in range(free):
            values[a] = normal[a, a]
        largest = 0.0
        for a in range(free):
            largest = max(largest, values[a])
        kept = 0
        remaining = np.empty((nv, free))
        for a in range(free):
            if values[a] <= floor * largest:
                for j in range(nv):
                    total = 0.0
                    for b in range(free):
                        total += basis[j, b] * vectors[b, a]
                    remaining[j, kept] = total
                kept += 1
        for j in range(nv):
            for a in range(kept):
                basis[j, a] = remaining[j, a]
        free = kept


# ------------------------------------------------------- tick-program ops


@njit(inline="always")
def _level_constraints(source: np.ndarray, target: np.ndarray, n: int, p: int, e: int, band: int, source_size: int,
                       target_size: int, dt: float) -> None:
    level_constraints(source, target, n, p, e, band)


#: a level's QP constraints from the first level's, with room for band rows
LEVEL_CONSTRAINTS = Op("LEVEL_CONSTRAINTS", _level_constraints, (
    ("source", ("source_size",)), ("target", ("target_size",)), ("n", None), ("p", None), ("e", None),
    ("band", None), ("source_size", None), ("target_size", None)),
    checks=("1 <= n", "0 <= p", "0 <= e", "0 <= band", "source_size == n * n + 3 * n + (p + e) * (n + 2)",
            "target_size == n * n + 3 * n + (p + band + e) * (n + 2)"))


@njit(inline="always")
def _normalise_level(Hc: np.ndarray, scaling: np.ndarray, nv: int, dt: float) -> None:
    normalise_level(Hc, scaling[0], scaling[1])


#: a level's cost normalisation; scaling = (damping, damping floor)
NORMALISE_LEVEL = Op("NORMALISE_LEVEL", _normalise_level, (("Hc", ("nv + 1", "nv")), ("scaling", (2,)),
                                                           ("nv", None)))


@njit(inline="always")
def _band(stack: np.ndarray, first: int, last: int, first_preview: int, last_preview: int, x: np.ndarray,
          lower: np.ndarray, upper: np.ndarray, control: np.ndarray, settings: np.ndarray, target: np.ndarray, nv: int,
          rows: int, size: int, row: int, target_rows: int, flags: np.ndarray, dt: float) -> None:
    if (flags[FLAG_FOUND_NAN] or flags[FLAG_STOPPED] or control[DAQP_CONTROL_EXITFLAG] < 1
            or not control[DAQP_CONTROL_DEFECT] <= settings[0]):
        flags[FLAG_STOPPED] = 1
    else:
        band_rows(stack, first, last, first_preview, last_preview, x, lower, upper, settings[1], target, row,
                  target_rows, 1)


#: the band rows of a solved level into the next level's QP (settings = (answer tolerance, relative
#: band)); when the level's solve failed (exit flag < 1, or its answer's defect above the tolerance)
#: nothing is written and the stopped flag skips every later DAQP_SOLVE
BAND = Op("BAND", _band, (
    STACK, ("first", None), ("last", None), ("first_preview", None), ("last_preview", None), ("x", ("nv",)),
    ("lower", ("nv",)), ("upper", ("nv",)), ("control", (DAQP_CONTROL_SIZE,)), ("settings", (2,)),
    ("target", ("size",)), ("nv", None), ("rows", None), ("size", None), ("row", None), ("target_rows", None),
    FLAGS_OPERAND),
    checks=("1 <= nv", "0 <= first <= last <= rows", "0 <= first_preview <= last_preview <= rows", "0 <= row",
            "row + last - first + last_preview - first_preview <= target_rows",
            "size == nv * nv + 3 * nv + target_rows * (nv + 2)"))


@njit(inline="always")
def _hierarchy_preview(stack: np.ndarray, ranges: np.ndarray, scaling: np.ndarray, preview: np.ndarray, nv: int,
                       rows: int, count: int, dt: float) -> None:
    hierarchy_preview(stack, ranges, scaling[1], preview)


#: the holonomic preview of a hierarchy (the cascade of its levels' row ranges)
HIERARCHY_PREVIEW = Op("HIERARCHY_PREVIEW", _hierarchy_preview, (
    STACK, ("ranges", ("count",)), ("scaling", (2,)), ("preview", ("nv",)), ("nv", None), ("rows", None),
    ("count", None)), checks=("1 <= nv", "2 <= count", "count % 2 == 0"))
