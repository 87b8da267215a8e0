"""The tick program's interpreter, and the C callbacks of the ops, generated from their declarations.

The program's operands are registered once (:class:`wbc.runtime.program.TickProgram`) as
C-contiguous arrays and handed over by address: entering a numba function costs ~0.1 us per
array argument, a dozen arrays would cost more than the arithmetic. One native call,
``run_program(packed, q, out, dt)``, copies ``q`` into the program's input (unless ``q`` is empty),
runs every row and copies an accepted answer into ``out`` (unless ``out`` is empty); ``packed`` =
[rows, width, the flags (:data:`~wbc.runtime.kernels.ops.FLAG_COUNT`), the input's operand index and
size, the clock and the run times (:data:`~.ops.PROGRAM_CLOCK`), the output's operand index and size,
the rows (rows x width, row-major), the operand addresses].
Each row is [kind, callback address, operands...] (array operands by index into the addresses):
``run_program`` calls the row's callback, wbc's own op (:data:`~.ops.OP_BUILTIN`, which also
receives the flags) or a third party's (:data:`~.ops.OP_EXTERNAL`). It returns
:data:`~wbc.runtime.kernels.ops.RUN_FOUND_NAN`, :data:`~wbc.runtime.kernels.ops.RUN_ACCEPTED` or 0
(:data:`~wbc.runtime.kernels.ops.RUN_BAD_INPUT`: ``q`` does not fit the input or ``out`` the output,
nothing run).

An op's callback is a numba ``cfunc`` generated from its declaration (:func:`callbacks_source`:
read the op's int operands from its row, view each array operand at its address with its
declared shape, call the op's kernel with the operands in declaration order, then ``dt``). It is
compiled when a program first adds the op (:func:`wbc.runtime.kernels.callback`), i.e. when a
controller that uses it is built, never in a tick, and only for the ops used: a controller's
first start after an install compiles its own ops, each once, whatever the other ops of its
program (the interpreter does not change with them). numba caches a function by its source
file, so :func:`callbacks` writes the source to a file named by its content hash next to the
package's numba cache (:func:`wbc.runtime.kernels._cache.write_generated`): a change of any
kernel file (part of the source's header, the package's source stamp) gives a new file.
Without a writable cache directory the callbacks are compiled in memory.
"""

from __future__ import annotations

from pathlib import Path
from types import ModuleType

import numpy as np
from llvmlite import ir
from numba import types
from numba.extending import intrinsic

from . import _cache, prepare_cache
from ._clock import now_ns
from ._lazy import ENTRY, declared
from .ops import (
    FLAG_ACCEPTED,
    FLAG_COUNT,
    FLAG_FOUND_NAN,
    FLAGS,
    OP_BUILTIN,
    PROGRAM_ACCEPTED_NS,
    PROGRAM_CLOCK,
    PROGRAM_CLOCK_ID,
    PROGRAM_HEADER,
    PROGRAM_INPUT,
    PROGRAM_INPUT_SIZE,
    PROGRAM_OUTPUT,
    PROGRAM_OUTPUT_SIZE,
    PROGRAM_RUN_NS,
    RUN_ACCEPTED,
    RUN_BAD_INPUT,
    RUN_FOUND_NAN,
    Op,
    decoder_source,
)

CACHE = prepare_cache()  # before anything below compiles; False: no writable cache (see wbc.runtime.kernels)

#: file names of the generated callbacks (``<prefix><content hash>.py``)
GENERATED_PREFIX = "wbc_tick_ops_"
#: the C signature of wbc's op callbacks: (operand addresses, the op's row after [kind, callback], dt, flags)
BUILTIN_SIGNATURE = types.void(types.CPointer(types.int64), types.CPointer(types.int64), types.float64,
                               types.CPointer(types.int64))


@intrinsic
def _float64_at(typingctx, address):
    """The float64 pointer at integer ``address`` (memory the caller knows: a registered array, see
    TickProgram; the rows DAQP's problem points to, :mod:`._inert_rows`)."""
    def codegen(context, builder, signature, args):
        return builder.inttoptr(args[0], context.get_value_type(types.CPointer(types.float64)))

    return types.CPointer(types.float64)(types.int64), codegen


@intrinsic
def _int64_at(typingctx, address):
    """The int64 pointer at integer ``address`` (memory the caller knows: a registered array, see
    TickProgram; the words of DAQP's structures, :mod:`._inert_rows`)."""
    def codegen(context, builder, signature, args):
        return builder.inttoptr(args[0], context.get_value_type(types.CPointer(types.int64)))

    return types.CPointer(types.int64)(types.int64), codegen


@intrinsic
def _call_external(typingctx, callback, addresses, row, dt):
    """``void callback(int64* addresses, int64* row, double dt)``: a CompiledOp's C callback."""
    signature = types.void(types.int64, types.int64, types.int64, types.float64)

    def codegen(context, builder, signature, args):
        int_pointer = ir.IntType(64).as_pointer()
        function = ir.FunctionType(ir.VoidType(), [int_pointer, int_pointer, ir.DoubleType()])
        callee = builder.inttoptr(args[0], function.as_pointer())
        builder.call(callee, [builder.inttoptr(args[1], int_pointer), builder.inttoptr(args[2], int_pointer),
                              args[3]])
        return context.get_dummy_value()

    return signature, codegen


@intrinsic
def _call_builtin(typingctx, callback, addresses, row, dt, flags):
    """``void callback(int64* addresses, int64* row, double dt, int64* flags)``: one of wbc's ops."""
    signature = types.void(types.int64, types.int64, types.int64, types.float64, types.int64)

    def codegen(context, builder, signature, args):
        int_pointer = ir.IntType(64).as_pointer()
        function = ir.FunctionType(ir.VoidType(), [int_pointer, int_pointer, ir.DoubleType(), int_pointer])
        callee = builder.inttoptr(args[0], function.as_pointer())
        builder.call(callee, [builder.inttoptr(args[1], int_pointer), builder.inttoptr(args[2], int_pointer),
                              args[3], builder.inttoptr(args[4], int_pointer)])
        return context.get_dummy_value()

    return signature, codegen


#: ``q`` of :func:`run_program`: any 1-D float64 array, read-only too (only read); a writable one converts to it
_Q = types.Array(types.float64, 1, "A", readonly=True)


# the GIL stays held: releasing and taking it back costs ~0.05 us a tick, and a tick is a few us
# declared, not compiled at import: a first start compiles it with the controller's kernels (a compile worker may)
@declared(types.int64(types.int64[::1], _Q, types.float64[::1], types.float64), cache=CACHE, **ENTRY)
def run_program(packed: np.ndarray, q: np.ndarray, out: np.ndarray, dt: float) -> int:
    """Copy ``q`` into the program's input (unless it is empty), then run the rows of the program
    ``packed`` in order; RUN_FOUND_NAN when a NaN screen found a NaN, else RUN_ACCEPTED when the
    solve's answer was accepted -- then copied into ``out`` from the program's output, unless ``out``
    is empty --, else 0 (RUN_BAD_INPUT: ``q`` does not fit the input or ``out`` the output, nothing
    run). A run given a ``q`` by a program with a clock is timed from here to its return (header
    words ``PROGRAM_RUN_NS``, and ``PROGRAM_ACCEPTED_NS`` when it returns RUN_ACCEPTED)."""
    clock = packed[PROGRAM_CLOCK] if q.size else 0
    start = now_ns(clock, packed[PROGRAM_CLOCK_ID]) if clock != 0 else 0
    rows, width = packed[0], packed[1]
    flags = packed[2:2 + FLAG_COUNT]
    for i in range(FLAG_COUNT):
        flags[i] = 0
    program = packed[PROGRAM_HEADER:PROGRAM_HEADER + rows * width].reshape((rows, width))
    operand_addresses = packed[PROGRAM_HEADER + rows * width:]
    if ((q.size and (packed[PROGRAM_INPUT] < 0 or q.size != packed[PROGRAM_INPUT_SIZE]))
            or (out.size and (packed[PROGRAM_OUTPUT] < 0 or out.size != packed[PROGRAM_OUTPUT_SIZE]))):
        return RUN_BAD_INPUT
    if q.size:
        target = _float64_at(operand_addresses[packed[PROGRAM_INPUT]])
        for i in range(q.size):
            target[i] = q[i]
    addresses = np.int64(operand_addresses.ctypes.data)
    flag_address = np.int64(flags.ctypes.data)
    for r in range(rows):
        op = program[r]
        row = np.int64(op.ctypes.data) + np.int64(16)  # the operands, after [kind, callback]
        if op[0] == OP_BUILTIN:
            _call_builtin(op[1], addresses, row, dt, flag_address)
        else:  # OP_EXTERNAL
            _call_external(op[1], addresses, row, dt)
    outcome = RUN_FOUND_NAN if flags[FLAG_FOUND_NAN] else RUN_ACCEPTED if flags[FLAG_ACCEPTED] else 0
    if outcome == RUN_ACCEPTED and out.size:
        answer = _float64_at(operand_addresses[packed[PROGRAM_OUTPUT]])
        for i in range(out.size):
            out[i] = answer[i]
    if clock != 0:
        elapsed = now_ns(clock, packed[PROGRAM_CLOCK_ID]) - start
        packed[PROGRAM_RUN_NS] = elapsed
        if outcome == RUN_ACCEPTED:
            packed[PROGRAM_ACCEPTED_NS] = elapsed
    return outcome


def callbacks_source(ops: list[Op], stamp: str) -> str:
    """The module defining the Python function ``op_<NAME>(addresses, op, dt, flag_pointer)`` of each
    op of ``ops`` (compiled as a cfunc by :func:`wbc.runtime.kernels.callback`), generated from their
    declarations: the decoder is the function's own body (as an ``inline="always"`` helper, numba
    copied its IR into the callback: ~0.3 s more CPU at a first start); ``stamp`` (the package's
    source stamp) is written into its header."""
    lines = [f'"""The C callbacks of wbc\'s tick-program ops, generated by {__name__} from their declarations; '
             "do not edit.", "", f"Kernel sources: sha256 {stamp}.", '"""', "", "from numba import carray",
             f"from {__name__} import _float64_at, _int64_at"]
    for op in ops:
        kernel = op.kernel.py_func
        lines.append(f"from {kernel.__module__} import {kernel.__name__} as _kernel_{op.spec.name}")
    for op in ops:
        name = op.spec.name
        decoder = decoder_source(op.spec, op.dtypes, f"op_{name}", "addresses, op, dt, flag_pointer", 0,
                                 f"_kernel_{name}")
        lines += ["", "", decoder[0], f"    {FLAGS} = carray(flag_pointer, ({FLAG_COUNT},))", *decoder[1:]]
    return "\n".join([*lines, ""])


def callbacks(ops: list[Op], stamp: str, directory: Path | None) -> ModuleType:
    """The module of :func:`callbacks_source`: imported from a file in ``directory`` (numba's cache
    directory of the package: the callbacks compiled from it are cached next to it), or built in
    memory when ``directory`` is None or cannot be written."""
    return _cache.load_generated(directory, GENERATED_PREFIX, callbacks_source(ops, stamp), f"{__name__}_generated")
