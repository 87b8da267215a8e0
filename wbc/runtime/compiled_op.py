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
through its address, when the op is created, never in a tick. When the kernel is a
module-level function of an imported module (not ``__main__``, not a file run by
``runpy.run_path``), the callback's source is written to a file in numba's cache directory for
that module and the callback is cached like wbc's own (~16 ms to load in later processes; its key:
the callback's source, whose header holds a hash of every ``*.py`` file of the kernel's folder and
numba's version, so an edit there recompiles it -- callees in other folders are not part of the
key, as with numba's own cache); otherwise it is compiled in memory in every process (~1 s).
"""

from __future__ import annotations

import hashlib
import inspect
import sys
from pathlib import Path
from types import ModuleType
from typing import Any

import numba
from numba import cfunc, types

from .kernels import _cache
from .kernels.ops import decoder_source, parse

#: file names of the generated callbacks: ``<prefix><op name>_<hash of the op's and the kernel's names and the
#: kernel's file>_<content hash>.py``
GENERATED_PREFIX = "wbc_compiled_op_"

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
        module = self._module()
        cache = getattr(module, "__file__", None) is not None  # not when built in memory
        try:
            self._callback = cfunc(SIGNATURE, nopython=True, cache=cache)(module.unpack)
        except RuntimeError:  # numba cannot cache it (the file went away meanwhile): in memory
            self._callback = cfunc(SIGNATURE, nopython=True)(module.unpack)
        self.address: int = self._callback.address  #: the C callback the program calls

    def _module(self) -> ModuleType:
        """The module defining ``unpack(addresses, op, dt) -> kernel(operands..., dt)``, generated
        from the declaration (``op``: the row after [opcode, callback]): a file in numba's cache
        directory of the kernel's module when the kernel can be imported by name, else in memory."""
        function = getattr(self.kernel, "py_func", self.kernel)
        module_name, name = str(getattr(function, "__module__", "")), str(getattr(function, "__name__", ""))
        named = module_name != "__main__" and all(part.isidentifier() for part in module_name.split("."))
        source_file = _source_file(function) if named and module_name in sys.modules else None
        # the kernel imported by name from its module's file: its callback cached next to numba's cache of it
        source = (Path(source_file) if source_file is not None
                  and getattr(sys.modules[module_name], name, None) is self.kernel else None)
        directory = _cache.cache_dir(source) if source is not None else None
        stamp = (_cache.source_stamp(source.parent, numba.__version__) if directory is not None and source is not None
                 else "none")
        lines = [f'"""The C callback of the CompiledOp {self.spec.name}, generated by {__name__}; do not edit.',
                 "", f"Kernel folder sources: sha256 {stamp}.", '"""', "", "from numba import carray",
                 "from wbc.runtime.kernels.tick import _float64_at, _int64_at"]
        if directory is not None:
            lines.append(f"from {module_name} import {name} as kernel")
        lines += ["", "", *decoder_source(self.spec, self.dtypes, "unpack", "addresses, op, dt", 0, "kernel"), ""]
        # the prefix names the op and its kernel (another op's files are deleted by their prefix)
        key = hashlib.sha256(f"{self.spec.name} {module_name}.{name} {source_file}".encode()).hexdigest()[:12]
        module = _cache.load_generated(directory, f"{GENERATED_PREFIX}{self.spec.name}_{key}_", "\n".join(lines),
                                       f"{__name__}_{self.spec.name}")
        if directory is None:
            module.__dict__["kernel"] = self.kernel
        return module

    def __repr__(self) -> str:
        return f"CompiledOp({self.spec.name!r}, {[name for name, _ in self.spec.operands]})"


def _source_file(function: Any) -> str | None:
    """The file that defines ``function``; None when there is none (built in memory, a notebook cell)."""
    try:
        return inspect.getsourcefile(function)
    except (TypeError, OSError):
        return None
