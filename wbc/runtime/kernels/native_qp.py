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
    DAQP_SKIPPED,
    DAQP_WORKSPACE_WORDS,
    prepare_cache,
)
from ._lazy import declared
from .assembly import _minimiser, qp_defect
from .ops import FLAG_ACCEPTED, FLAG_FOUND_NAN, FLAG_STOPPED, FLAGS_OPERAND, Op

CACHE = prepare_cache()  # before the first @njit below compiles; False: no writable cache (see wbc.runtime.kernels)

_I8P = ir.IntType(8).as_pointer()
_I32, _I64 = ir.IntType(32), ir.IntType(64)


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


@intrinsic
def _int32_at(typingctx, address):
    """The int32 pointer at integer ``address`` (DAQP's constraint states, whose address DAQP's problem holds)."""
    def codegen(context, builder, signature, args):
        return builder.inttoptr(args[0], context.get_value_type(types.CPointer(types.int32)))

    return types.CPointer(types.int32)(types.int64), codegen


@intrinsic
def _now_ns(typingctx, function, clock_id):
    """``clock_gettime(clock_id, &t)`` at address ``function``, as ns (``struct timespec``: two
    longs, on the stack)."""
    signature = types.int64(types.int64, types.int64)

    def codegen(context, builder, signature, args):
        timespec = ir.LiteralStructType([_I64, _I64])
        slot = builder.alloca(timespec)
        callee = builder.inttoptr(args[0], ir.FunctionType(_I32, [_I32, _I8P]).as_pointer())
        builder.call(callee, [builder.trunc(args[1], _I32), builder.bitcast(slot, _I8P)])
        seconds = builder.load(builder.gep(slot, [_I32(0), _I32(0)]))
        nanoseconds = builder.load(builder.gep(slot, [_I32(0), _I32(1)]))
        return builder.add(builder.mul(seconds, _I64(1_000_000_000)), nanoseconds)

    return signature, codegen


@njit(inline="always")
def _no_active_constraint(problem: np.ndarray, sense_word: int, m: int) -> bool:
    """Whether DAQP's working set -- the constraint states its problem points to (word
    ``sense_word`` of ``problem``), the next solve's warm start -- holds no active constraint."""
    address = problem.view(np.int64)[sense_word]
    if address == 0:
        return True
    sense = carray(_int32_at(address), (m,))
    for i in range(m):
        if sense[i] & DAQP_SENSE_ACTIVE:
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


@declared("void(float64[::1], float64[::1], float64[::1], float64[::1], float64[::1], float64[::1], float64[:, ::1], "
          "float64[::1], int64, int64, int64, int64, int64, int64, int64)", cache=CACHE, nogil=True)
def daqp_solve(problem: np.ndarray, workspace: np.ndarray, result: np.ndarray, control: np.ndarray,
               data: np.ndarray, x: np.ndarray, factor: np.ndarray, lam: np.ndarray, update_ldp: int, solve: int,
               clock_gettime: int, clock_id: int, steady_mask: int, unconstrained_first: int, sense_word: int) -> None:
    """One DAQP solve of the QP whose buffers ``problem`` points to (``data``: the same QP's
    flat buffer, :class:`wbc.qp.problem.QP`), writing ``control`` (layout ``DAQP_CONTROL_*``).

    With ``unconstrained_first`` (a QP without equality rows) and no active constraint in DAQP's
    working set (:func:`_no_active_constraint`: the last answer met no limit), the unconstrained
    minimiser ``-H^-1 c`` is tried first (:func:`_unconstrained_answer`, ``factor``: n x n
    scratch): when it satisfies every bound and row it is the answer (exit flag 1, defect 0, 0
    iterations, multipliers ``lam`` 0), DAQP is not called and its working set stays empty.
    Otherwise ``daqp_update_ldp(control[MASK])`` re-forms R^-1 (hence M = A R^-1, v, d) from the
    fresh buffers, ``daqp_solve`` writes x and ``lam`` (``result`` points to both); the answer is
    then checked: its defect (:func:`wbc.runtime.kernels.qp_defect`, relative violation of the
    bounds and rows) is written, inf when x is not finite. The next tick's mask is ``steady_mask``.
    """
    start = _now_ns(clock_gettime, clock_id)
    if (unconstrained_first and _no_active_constraint(problem, sense_word, lam.shape[0])
            and _unconstrained_answer(data, x, factor, lam)):
        control[DAQP_CONTROL_EXITFLAG] = DAQP_OPTIMAL
        control[DAQP_CONTROL_DEFECT] = 0.0
        control[DAQP_CONTROL_ITERATIONS] = 0
        control[DAQP_CONTROL_TIME] = (_now_ns(clock_gettime, clock_id) - start) * 1e-9
        return
    flags = result.view(np.int32)
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
    control[DAQP_CONTROL_EXITFLAG] = flag
    control[DAQP_CONTROL_DEFECT] = defect
    control[DAQP_CONTROL_ITERATIONS] = iterations
    control[DAQP_CONTROL_TIME] = (_now_ns(clock_gettime, clock_id) - start) * 1e-9


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


#: the compiled DAQP solve (wbc.solvers.daqp.native); skipped (exit flag DAQP_SKIPPED) when a NaN screen
#: before it found a NaN, or a BAND row stopped
DAQP_SOLVE = Op("DAQP_SOLVE", _daqp_solve, (
    ("problem", (DAQP_PROBLEM_WORDS,)), ("workspace", (DAQP_WORKSPACE_WORDS,)), ("result", (DAQP_RESULT_WORDS,)),
    ("control", (DAQP_CONTROL_SIZE,)), ("data", ("size",)), ("x", ("n",)), ("factor", ("n", "n")), ("lam", ("m",)),
    ("n", None), ("size", None), ("m", None), ("update_ldp", None), ("solve", None), ("clock_gettime", None),
    ("clock_id", None), ("steady_mask", None), ("unconstrained_first", None), ("sense_word", None), FLAGS_OPERAND),
    checks=("1 <= n", "n * n + 3 * n <= size", "(size - n * n - 3 * n) % (n + 2) == 0",
            "m == n + (size - n * n - 3 * n) // (n + 2)", "update_ldp != 0", "solve != 0", "clock_gettime != 0",
            f"0 <= sense_word < {DAQP_PROBLEM_WORDS}"))


@njit(inline="always")
def _daqp_accept(control: np.ndarray, tolerance: np.ndarray, flags: np.ndarray, dt: float) -> None:
    if control[DAQP_CONTROL_EXITFLAG] >= 1.0 and control[DAQP_CONTROL_DEFECT] <= tolerance[0]:
        flags[FLAG_ACCEPTED] = 1


#: the controller's check of a DAQP_SOLVE's answer (``control``, its control vector): the program's flag
#: FLAG_ACCEPTED when DAQP solved (exit flag >= 1) and the answer's defect is at most ``tolerance[0]``
DAQP_ACCEPT = Op("DAQP_ACCEPT", _daqp_accept, (
    ("control", (DAQP_CONTROL_SIZE,)), ("tolerance", (1,)), FLAGS_OPERAND))
