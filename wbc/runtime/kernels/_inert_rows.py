"""DAQP given only the rows that can bind: the rows every x satisfies are left out of its problem.

A general row ``lower_i <= a_i x <= upper_i`` with ``a_i = 0`` and ``lower_i <= 0 <= upper_i``
holds for every x: the inert rows of :class:`wbc.CollisionAvoidance` and
:class:`wbc.BaseFootprintAvoidance` (``G`` row 0, ``h`` = ``INERT``), a zero equality row.
Leaving it out changes neither the feasible set nor the minimiser, and its multiplier is 0.
DAQP 0.11 still pays for it on every solve: ``daqp_update_M`` forms ``M = A R^-1`` for every
row (the warm tick re-forms R^-1, hence M), ``daqp_normalize_M`` and ``daqp_update_d`` pass
over every row, and each iteration's feasibility scan forms ``M u`` for every row
(``daqp_compute_Mu``) before the row is found to be zero and skipped (``DAQP_ZERO_ROW``).

:func:`pack`, right before DAQP's update, points DAQP's problem at a packed copy of the other
rows (``m`` the packed count; the simple bounds stay in front); :func:`unpack`, right after
its solve, points it back at the QP's own buffers (and DAQP's m back at the QP's) and spreads what DAQP wrote -- the
multipliers and, warm-started, its constraint states -- back to the QP's row order. Between
solves the problem and DAQP's states are the unpacked ones, so everything else (the first
tries of :mod:`.native_qp`, the answer check against the whole QP, ``NativeWorkspace.working_set``)
sees the QP as it is.

``packed`` (float64, ``(m - n) n + 3 m`` words): the packed rows ((m - n) x n, the first
``kept`` used), their upper and lower bounds (m each, the simple bounds first), then ``m``
int32 constraint states in the last m words: the simple bounds', the kept rows', then the
left-out rows' (a permutation of the states DAQP was given). ``order`` (int64, m - n): the
kept rows in ascending order, then the left-out ones in descending order.
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
    DAQP_WORKSPACE_M,
    DAQP_WORKSPACE_SENSE,
)


@intrinsic
def _int32_at(typingctx, address):
    """The int32 pointer at integer ``address`` (DAQP's constraint states, whose address DAQP's problem holds)."""
    def codegen(context, builder, signature, args):
        return builder.inttoptr(args[0], context.get_value_type(types.CPointer(types.int32)))

    return types.CPointer(types.int32)(types.int64), codegen


@intrinsic
def _float64_at(typingctx, address):
    """The float64 pointer at integer ``address`` (the row data DAQP's problem points to)."""
    def codegen(context, builder, signature, args):
        return builder.inttoptr(args[0], context.get_value_type(types.CPointer(types.float64)))

    return types.CPointer(types.float64)(types.int64), codegen


@njit(inline="always")
def _packed_states(packed: np.ndarray, m: int, n: int) -> np.ndarray:
    """The int32 constraint states in the last m words of ``packed``."""
    return packed[(m - n) * n + 2 * m:].view(np.int32)[:m]


@njit(inline="always")
def pack(problem: np.ndarray, packed: np.ndarray, order: np.ndarray, n: int, m: int,
         sense_word: int) -> tuple[int, int, int, int, int]:
    """Point DAQP's ``problem`` (n variables, m = n + rows constraints, states at its word
    ``sense_word``) at the rows that are not met by every x, packed into ``packed`` (module
    docstring). Returns (kept rows, then the problem's A, upper, lower and states addresses
    to restore); kept = m - n and the problem untouched when no row is left out."""
    words, ints = problem.view(np.int64), problem.view(np.int32)
    rows = m - n
    a_address, upper_address = words[DAQP_PROBLEM_A], words[DAQP_PROBLEM_A + 1]
    lower_address, sense_address = words[DAQP_PROBLEM_A + 2], words[sense_word]
    if rows == 0 or a_address == 0 or sense_address == 0:
        return rows, a_address, upper_address, lower_address, sense_address
    A = carray(_float64_at(a_address), (rows, n))
    upper, lower = carray(_float64_at(upper_address), (m,)), carray(_float64_at(lower_address), (m,))
    kept, tail = 0, rows
    for i in range(rows):
        inert = lower[n + i] <= 0.0 <= upper[n + i]  # False for a NaN bound
        if inert:
            for a in range(n):
                if A[i, a] != 0.0:
                    inert = False
                    break
        if inert:
            tail -= 1
            order[tail] = i
        else:
            order[kept] = i
            kept += 1
    if kept == rows:
        return rows, a_address, upper_address, lower_address, sense_address
    sense = carray(_int32_at(sense_address), (m,))
    packed_A = packed[:rows * n].reshape((rows, n))
    packed_upper, packed_lower = packed[rows * n:rows * n + m], packed[rows * n + m:rows * n + 2 * m]
    states = _packed_states(packed, m, n)
    for a in range(n):
        packed_upper[a], packed_lower[a], states[a] = upper[a], lower[a], sense[a]
    for k in range(rows):
        i = order[k]
        if k < kept:
            packed_A[k] = A[i]
            packed_upper[n + k], packed_lower[n + k] = upper[n + i], lower[n + i]
        states[n + k] = sense[n + i]
    words[DAQP_PROBLEM_A] = packed_A.ctypes.data
    words[DAQP_PROBLEM_A + 1], words[DAQP_PROBLEM_A + 2] = packed_upper.ctypes.data, packed_lower.ctypes.data
    words[sense_word] = states.ctypes.data
    ints[DAQP_PROBLEM_M] = n + kept
    return kept, a_address, upper_address, lower_address, sense_address


@njit(inline="always")
def unpack(problem: np.ndarray, workspace: np.ndarray, lam: np.ndarray, packed: np.ndarray, order: np.ndarray,
           n: int, sense_word: int, packing: tuple[int, int, int, int, int]) -> None:
    """Undo :func:`pack` (``packing``: what it returned) after DAQP's solve: the problem's
    addresses and m restored, DAQP's m too (its next update re-reads it from the problem); the
    multipliers DAQP wrote for the packed rows moved to their rows of ``lam`` (m), 0 on the rows
    left out; when DAQP's states are the warm start (the problem's states are DAQP's own array),
    its states of the packed rows moved to their rows, and a left-out row keeps the state it had,
    inactive unless immutable (an equality row)."""
    m = lam.shape[0]
    rows = m - n
    kept, a_address, upper_address, lower_address, sense_address = packing
    if kept == rows:
        return
    words, ints = problem.view(np.int64), problem.view(np.int32)
    words[DAQP_PROBLEM_A], words[DAQP_PROBLEM_A + 1] = a_address, upper_address
    words[DAQP_PROBLEM_A + 2], words[sense_word] = lower_address, sense_address
    ints[DAQP_PROBLEM_M] = workspace.view(np.int32)[DAQP_WORKSPACE_M] = m
    # in place from the last row: packed row k goes to row order[k] >= k, not yet read
    j = kept - 1
    for i in range(rows - 1, -1, -1):
        if j >= 0 and order[j] == i:
            lam[n + i] = lam[n + j]
            j -= 1
        else:
            lam[n + i] = 0.0
    if sense_address != workspace.view(np.int64)[DAQP_WORKSPACE_SENSE]:
        return  # a cold start: the next solve starts from the initial states again
    sense, states = carray(_int32_at(sense_address), (m,)), _packed_states(packed, m, n)
    j, tail = kept - 1, kept  # the left-out rows are in descending order from order[kept]
    for i in range(rows - 1, -1, -1):
        if j >= 0 and order[j] == i:
            sense[n + i] = sense[n + j]
            j -= 1
        else:
            state = states[n + tail]
            sense[n + i] = state if state & DAQP_SENSE_IMMUTABLE else state & ~DAQP_SENSE_ACTIVE
            tail += 1
