"""Third-party compiled ops: a kernel written outside wbc that runs inside the tick program.

wbc's own compiled items are rows of the tick program (:mod:`wbc.runtime.program`), all run by one
native call. A :class:`CompiledOp` lets any package add rows of its own to that call
without touching wbc's files: it declares its operands once, like wbc's own ops
(:class:`wbc.runtime.kernels.ops.OpSpec`: names, shapes over the op's int operands, conditions), and
gives an ``@njit`` kernel that takes them in that order followed by ``dt``::

    @njit
    def centering_rows(q, middle, weights, settings, stack, start, dim, nv, rows, dt): ...

    CENTERING = CompiledOp("CENTERING", centering_rows, (
        ("q", ("nq",)), ("middle", ("dim",)), ("weights", ("dim",)), ("settings", (2,)),
        ("stack", ("nv + 1", "rows")), ("start", None), ("dim", None), ("nv", None), ("rows", None),
        ("nq", None)), checks=("0 <= start", "start + dim <= rows"))

    # in TaskData.add_ops:  program.add(CENTERING, q=kin.q, ..., start=start, ...); return True

Array operands are C-contiguous float64, or int64 when declared ``(name, shape, "int64")``.
:meth:`wbc.runtime.program.TickProgram.add` checks them against the declaration when the controller
is built, exactly as for wbc's ops, so a wrong operand raises there and never reaches the
kernel. The op is compiled here into a C callback (a numba ``cfunc`` generated from the
declaration, which unpacks the operands and calls the kernel); the program calls it
through its address. Unlike wbc's kernels it is compiled once per process (~0.5 s), when
the op is created (at import of the module that defines it), never in a tick.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from numba import carray, cfunc, types
from numba.extending import intrinsic

from .kernels.ops import OpSpec

_DTYPES = ("float64", "int64")
_RESERVED = {"addresses", "row", "dt", "carray", "kernel", "unpack"}
#: the C signature of every op callback: (operand addresses, the op's row after [opcode,
#: callback], dt)
SIGNATURE = types.void(types.CPointer(types.int64), types.CPointer(types.int64), types.float64)


@intrinsic
def _float64_at(typingctx, address):
    """The float64 pointer at integer ``address`` (a registered operand)."""
    def codegen(context, builder, signature, args):
        return builder.inttoptr(args[0], context.get_value_type(types.CPointer(types.float64)))

    return types.CPointer(types.float64)(types.int64), codegen


@intrinsic
def _int64_at(typingctx, address):
    """The int64 pointer at integer ``address`` (a registered operand)."""
    def codegen(context, builder, signature, args):
        return builder.inttoptr(args[0], context.get_value_type(types.CPointer(types.int64)))

    return types.CPointer(types.int64)(types.int64), codegen


class CompiledOp:
    """A third-party op of the tick program (see the module docstring).

    Args:
        name: shown in error messages.
        kernel: an ``@njit`` function taking the operands in declaration order, then ``dt``.
        operands: ``(name, shape)`` or ``(name, shape, dtype)``; ``shape`` None for an int
            operand, else a tuple of ints and expressions over the int operands.
        checks: conditions on the int operands, checked when the op is added.
    """

    def __init__(self, name: str, kernel: Any, operands: tuple[tuple[Any, ...], ...],
                 checks: tuple[str, ...] = ()) -> None:
        declared, self.dtypes = [], {}
        ints = {entry[0] for entry in operands if entry[1] is None}
        for entry in operands:
            if not (isinstance(entry, tuple) and len(entry) in (2, 3) and isinstance(entry[0], str)
                    and entry[0].isidentifier()):
                raise TypeError(f"{name}: each operand is (name, shape) or (name, shape, dtype), got {entry!r}")
            if entry[0] in _RESERVED or entry[0].startswith("_"):
                raise TypeError(f"{name}: operand name {entry[0]!r} is reserved (and names may not start with _)")
            operand, shape = entry[0], entry[1]
            dtype = entry[2] if len(entry) == 3 else "float64"
            if shape is not None and dtype not in _DTYPES:
                raise TypeError(f"{name}: operand {operand} has dtype {dtype!r}; array operands are {_DTYPES}")
            for dim in shape or ():
                names = set() if isinstance(dim, int) else set(compile(dim, "<shape>", "eval").co_names)
                if not names <= ints:
                    raise TypeError(f"{name}: shape of {operand} uses {sorted(names - ints)}, not int operands")
            declared.append((operand, shape))
            self.dtypes[operand] = dtype
        if len({entry[0] for entry in declared}) != len(declared):
            raise TypeError(f"{name}: operand names repeat")
        self.spec = OpSpec(name, tuple(declared), tuple(checks))
        self.kernel = kernel
        self._callback = cfunc(SIGNATURE, nopython=True)(self._unpacker())
        self.address: int = self._callback.address  #: the C callback the program calls

    def _unpacker(self) -> Callable[..., None]:
        """``(addresses, row, dt) -> kernel(operands..., dt)``, generated from the declaration."""
        lines = ["def unpack(addresses, row, dt):"]
        arguments = []
        for index, (operand, shape) in enumerate(self.spec.operands):
            if shape is None:
                lines.append(f"    {operand} = row[{index}]")
        for index, (operand, shape) in enumerate(self.spec.operands):
            if shape is not None:
                pointer = "_float64_at" if self.dtypes[operand] == "float64" else "_int64_at"
                dims = ", ".join(str(dim) for dim in shape)
                lines.append(f"    _{operand} = carray({pointer}(addresses[row[{index}]]), ({dims},))")
            arguments.append(operand if shape is None else f"_{operand}")
        lines.append(f"    kernel({', '.join(arguments + ['dt'])})")
        namespace = {"carray": carray, "_float64_at": _float64_at, "_int64_at": _int64_at, "kernel": self.kernel}
        exec("\n".join(lines), namespace)  # noqa: S102 -- source generated from validated identifiers
        return namespace["unpack"]

    def __repr__(self) -> str:
        return f"CompiledOp({self.spec.name!r}, {[name for name, _ in self.spec.operands]})"
