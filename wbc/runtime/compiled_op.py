"""Third-party compiled ops: a kernel written outside wbc that runs inside the tick program.

wbc's own compiled items are rows of the tick program (:mod:`wbc.runtime.program`), all run by one
native call. A :class:`CompiledOp` lets any package add rows of its own to that call
without touching wbc's files: it declares its operands once, like wbc's own ops
(:mod:`wbc.runtime.kernels.ops`: names, shapes over the op's int operands, conditions), and
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

from .kernels.ops import decoder_source, parse
from .kernels.tick import _float64_at, _int64_at

#: the C signature of every op callback: (operand addresses, the op's row after [opcode,
#: callback], dt)
SIGNATURE = types.void(types.CPointer(types.int64), types.CPointer(types.int64), types.float64)


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
        self.spec, self.dtypes = parse(name, operands, checks)
        self.kernel = kernel
        self._callback = cfunc(SIGNATURE, nopython=True)(self._unpacker())
        self.address: int = self._callback.address  #: the C callback the program calls

    def _unpacker(self) -> Callable[..., None]:
        """``(addresses, op, dt) -> kernel(operands..., dt)``, generated from the declaration
        (``op``: the row after [opcode, callback])."""
        lines = decoder_source(self.spec, self.dtypes, "unpack", "addresses, op, dt", 0, "kernel")
        namespace = {"carray": carray, "_float64_at": _float64_at, "_int64_at": _int64_at, "kernel": self.kernel}
        exec("\n".join(lines), namespace)  # noqa: S102 -- source generated from validated identifiers
        return namespace["unpack"]

    def __repr__(self) -> str:
        return f"CompiledOp({self.spec.name!r}, {[name for name, _ in self.spec.operands]})"
