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
from numba import njit, types
from numba.extending import intrinsic

from . import (
    DAQP_CONTROL_DEFECT,
    DAQP_CONTROL_EXITFLAG,
    DAQP_CONTROL_ITERATIONS,
    DAQP_CONTROL_MASK,
    DAQP_CONTROL_SIZE,
    DAQP_CONTROL_TIME,
    DAQP_PROBLEM_WORDS,
    DAQP_RESULT_EXITFLAG,
    DAQP_RESULT_ITERATIONS,
    DAQP_RESULT_WORDS,
    DAQP_SKIPPED,
    DAQP_WORKSPACE_WORDS,
    prepare_cache,
)
from ._lazy import declared
from .assembly import qp_defect
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


@declared("void(float64[::1], float64[::1], float64[::1], float64[::1], float64[::1], float64[::1], int64, int64, "
          "int64, int64, int64)", cache=CACHE, nogil=True)
def daqp_solve(problem: np.ndarray, workspace: np.ndarray, result: np.ndarray, control: np.ndarray,
               data: np.ndarray, x: np.ndarray, update_ldp: int, solve: int, clock_gettime: int, clock_id: int,
               steady_mask: int) -> None:
    """One DAQP solve of the QP whose buffers ``problem`` points to (``data``: the same QP's
    flat buffer, :class:`wbc.qp.problem.QP`), writing ``control`` (layout ``DAQP_CONTROL_*``).

    ``daqp_update_ldp(control[MASK])`` re-forms R^-1 (hence M = A R^-1, v, d) from the
    fresh buffers, ``daqp_solve`` writes x (``result`` points to ``x``); the answer is then
    checked: its defect (:func:`wbc.runtime.kernels.qp_defect`, relative violation of the bounds and
    rows) is written, inf when x is not finite. The next tick's mask is ``steady_mask``.
    """
    start = _now_ns(clock_gettime, clock_id)
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
                data: np.ndarray, x: np.ndarray, n: int, size: int, update_ldp: int, solve: int, clock_gettime: int,
                clock_id: int, steady_mask: int, flags: np.ndarray, dt: float) -> None:
    if flags[FLAG_FOUND_NAN] or flags[FLAG_STOPPED]:
        control[DAQP_CONTROL_EXITFLAG] = DAQP_SKIPPED
    else:
        daqp_solve(problem, workspace, result, control, data, x, update_ldp, solve, clock_gettime, clock_id,
                   steady_mask)


#: the compiled DAQP solve (wbc.solvers.daqp.native); skipped (exit flag DAQP_SKIPPED) when a NaN screen
#: before it found a NaN, or a BAND row stopped
DAQP_SOLVE = Op("DAQP_SOLVE", _daqp_solve, (
    ("problem", (DAQP_PROBLEM_WORDS,)), ("workspace", (DAQP_WORKSPACE_WORDS,)), ("result", (DAQP_RESULT_WORDS,)),
    ("control", (DAQP_CONTROL_SIZE,)), ("data", ("size",)), ("x", ("n",)), ("n", None), ("size", None),
    ("update_ldp", None), ("solve", None), ("clock_gettime", None), ("clock_id", None), ("steady_mask", None),
    FLAGS_OPERAND),
    checks=("1 <= n", "n * n + 3 * n <= size", "(size - n * n - 3 * n) % (n + 2) == 0", "update_ldp != 0",
            "solve != 0", "clock_gettime != 0"))


@njit(inline="always")
def _daqp_accept(control: np.ndarray, tolerance: np.ndarray, flags: np.ndarray, dt: float) -> None:
    if control[DAQP_CONTROL_EXITFLAG] >= 1.0 and control[DAQP_CONTROL_DEFECT] <= tolerance[0]:
        flags[FLAG_ACCEPTED] = 1


#: the controller's check of a DAQP_SOLVE's answer (``control``, its control vector): the program's flag
#: FLAG_ACCEPTED when DAQP solved (exit flag >= 1) and the answer's defect is at most ``tolerance[0]``
DAQP_ACCEPT = Op("DAQP_ACCEPT", _daqp_accept, (
    ("control", (DAQP_CONTROL_SIZE,)), ("tolerance", (1,)), FLAGS_OPERAND))
