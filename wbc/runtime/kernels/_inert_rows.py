"""DAQP given only the rows that can bind: the trailing rows every x satisfies are left out of its problem.

A general row ``lower_i <= a_i x <= upper_i`` with ``a_i = 0`` and ``lower_i <= 0 <= upper_i``
holds for every x: the inert rows of :class:`wbc.CollisionAvoidance` and
:class:`wbc.BaseFootprintAvoidance` (``G`` row 0, ``h`` = ``INERT``, after the rows of the
tick's pairs), a zero equality row. Leaving it out changes neither the feasible set nor the
minimiser, and its multiplier is 0. DAQP 0.11 still pays for it on every solve:
``daqp_update_M`` forms ``M = A R^-1`` for every row (a warm tick re-forms R^-1, hence M),
``daqp_normalize_M`` and ``daqp_update_d`` pass over every row, and each iteration's
feasibility scan forms ``M u`` for every row (``daqp_compute_Mu``) before the row is found to
be zero and skipped (its ``DAQP_ZERO_ROW`` mark).

DAQP reads the rows as one row-major block and the bounds and states as arrays indexed by
row, so the rows *after the last one that can bind* (:func:`extent`) are left out for free:
:func:`leave_out` gives DAQP's problem a smaller ``m`` (nothing is copied, every index stays the QP's), and
:func:`restore`, right after the solve, gives it back the QP's ``m`` (DAQP's workspace too:
its next update re-reads it from the problem), sets the multipliers of the rows left out to 0
and, warm-started, makes their states inactive (DAQP's zero-row mark undone; an immutable
state -- an equality row -- is kept). Between solves the problem and DAQP's states are the
whole QP's, so everything else (``NativeWorkspace.working_set``, the Python answer check) sees
the QP as it is. The native solve (:mod:`.native_qp`) finds the extent once, before its first
try, and reads the QP up to it only -- the states of its try, the answer check (a row every x
meets exactly adds nothing to the defect): the cost of the inert rows is then the one backward
scan that finds them. Inert rows
followed by a live row (a constraint with inert rows before another constraint's rows, or
before equality rows) are given to DAQP as before.
"""

from __future__ import annotations

import numpy as np
from numba import carray, njit, types
from numba.extending import intrinsic

from . import (
    DAQP_PROBLEM_A,
    DAQP_PROBLEM_M,
    DAQP_SENSE_ACTIVE,
    DAQP_SENSE_IMMUTABLE,
    DAQP_SENSE_LOWER,
    DAQP_SENSE_SOFT,
    DAQP_SENSE_ZERO_ROW,
    DAQP_WORKSPACE_M,
    DAQP_WORKSPACE_SENSE,
    prepare_cache,
)
from .tick import _float64_at, _int64_at

CACHE = prepare_cache()  # before the first @njit below compiles; False: no writable cache (see wbc.runtime.kernels)


@intrinsic
def _int32_at(typingctx, address):
    """The int32 pointer at integer ``address`` (DAQP's constraint states, whose address DAQP's problem holds)."""
    def codegen(context, builder, signature, args):
        return builder.inttoptr(args[0], context.get_value_type(types.CPointer(types.int32)))

    return types.CPointer(types.int32)(types.int64), codegen


@njit(cache=CACHE, nogil=True)
def extent(problem: np.ndarray, n: int, m: int) -> int:
    """The constraints of DAQP's ``problem`` (n variables, m = n + rows constraints) up to its last
    row that not every x satisfies: every row after it is inert (``a_i = 0``, ``lower_i <= 0 <=
    upper_i``: no NaN either), so any x meets it exactly (a defect of 0, a multiplier of 0)."""
    words = _int64_at(problem.ctypes.data)
    rows = m - n
    if rows == 0 or words[DAQP_PROBLEM_A] == 0:
        return m
    A = carray(_float64_at(words[DAQP_PROBLEM_A]), (rows, n))
    upper = carray(_float64_at(words[DAQP_PROBLEM_A + 1]), (m,))
    lower = carray(_float64_at(words[DAQP_PROBLEM_A + 2]), (m,))
    last = rows
    while last > 0:
        row = last - 1
        if not lower[n + row] <= 0.0 <= upper[n + row]:  # (also for a NaN bound)
            break
        nonzero = False
        for a in range(n):
            nonzero |= A[row, a] != 0.0
        if nonzero:
            break
        last = row
    return n + last


@njit(cache=CACHE, nogil=True)
def leave_out(problem: np.ndarray, given: int, m: int) -> None:
    """Give DAQP's ``problem`` (m constraints) only its first ``given`` (:func:`extent`)."""
    if given < m:
        _int32_at(problem.ctypes.data)[DAQP_PROBLEM_M] = given


@njit(cache=CACHE, nogil=True)
def restore(problem: np.ndarray, workspace: np.ndarray, lam: np.ndarray, given: int, sense_word: int) -> None:
    """Undo :func:`leave_out` (which gave DAQP ``given`` constraints) after DAQP's solve: the
    problem's and DAQP's m back to the QP's (``len(lam)``), the multipliers of the rows left out
    0; when DAQP's states are the warm start (the problem's states are DAQP's own array), their
    states inactive unless immutable, DAQP's zero-row mark undone."""
    m = lam.shape[0]
    if given == m:
        return
    _int32_at(problem.ctypes.data)[DAQP_PROBLEM_M] = m
    _int32_at(workspace.ctypes.data)[DAQP_WORKSPACE_M] = m
    for i in range(given, m):
        lam[i] = 0.0
    sense = sense_at(problem, sense_word, m)
    if sense.shape[0] == 0 or sense.ctypes.data != _int64_at(workspace.ctypes.data)[DAQP_WORKSPACE_SENSE]:
        return  # a cold start: the next solve starts from the initial states again
    for i in range(given, m):
        state = sense[i]
        if state & DAQP_SENSE_ZERO_ROW:  # constants.h DAQP_ZERO_ROW_SENSE
            sense[i] = ((state & DAQP_SENSE_LOWER) | ((state >> 12) & DAQP_SENSE_ACTIVE)
                        | ((state >> 11) & (DAQP_SENSE_IMMUTABLE | DAQP_SENSE_SOFT)))
    inactive_after(sense, given)


@njit(inline="always")
def sense_at(problem: np.ndarray, sense_word: int, m: int) -> np.ndarray:
    """DAQP's constraint states -- the array its problem points to (word ``sense_word`` of
    ``problem``), the next solve's warm start -- as an int32 array of ``m`` (empty when unset)."""
    address = _int64_at(problem.ctypes.data)[sense_word]  # (a pointer, not ndarray.view: less to compile)
    return carray(_int32_at(address), (m if address != 0 else 0,))


@njit(inline="always")
def inactive_after(sense: np.ndarray, given: int) -> None:
    """The states after the first ``given`` (the rows left out, :func:`extent`) made inactive, an
    immutable one (an equality row) kept: what :func:`restore` leaves after DAQP's solve, and what
    the native solve's first tries leave when they answer without DAQP."""
    for i in range(given, sense.shape[0]):  # (a store per state, no branch: the loop vectorises)
        state = sense[i]
        sense[i] = state if state & DAQP_SENSE_IMMUTABLE else state & ~DAQP_SENSE_ACTIVE
