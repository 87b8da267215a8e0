"""A clock read from compiled code: ``clock_gettime`` called through its address (an int
operand), so the machine code holds no address of this process and numba can cache it."""

from __future__ import annotations

from llvmlite import ir
from numba import types
from numba.extending import intrinsic

_I8P = ir.IntType(8).as_pointer()
_I32, _I64 = ir.IntType(32), ir.IntType(64)


@intrinsic
def now_ns(typingctx, function, clock_id):
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
