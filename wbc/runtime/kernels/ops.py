"""Op declarations of the tick program: an op's operands are written once, next to its kernel.

An op is declared in its kernel's module as an :class:`Op` (wbc's own, in a module of this
package) or a :class:`wbc.runtime.compiled_op.CompiledOp` (a third party's, anywhere), both in
the same format: a name, the operands in row order -- an *int* operand ``(name, None)`` or an
*array* operand ``(name, shape)`` / ``(name, shape, dtype)`` whose shape entries are ints or
expressions over the op's int operands (``"nv + 1"``) -- the ``checks`` on the int operands
(e.g. that a block of rows lies inside the stack), and a kernel that takes the operands in
that order, then ``dt``::

    FRAME_TASK = Op("FRAME_TASK", _frame_task, (
        ("joint_jacobians_t", ("nv", 6)), ..., ("start", None), ("nv", None), ("rows", None)),
        checks=("0 <= start", "start + 6 <= rows"))

:meth:`wbc.runtime.program.TickProgram.add` takes the operands by name, checks every array
against its declared shape and dtype (C-contiguous) and every check, and packs the row in
this order -- so a misnamed, misshapen or out-of-range operand raises when the controller
is built, never corrupts memory at tick time. The C callback of each op that reads its row
back (called by the interpreter ``run_program``) is *generated* from these declarations
(:mod:`.tick`), so no second copy of an operand order exists. An :class:`Op` is found by
:func:`wbc.runtime.kernels.load` as a module attribute of its own name; its number is assigned there.

Control flow between ops goes through the program's *flags* (:data:`FLAGS`): a built-in op
that declares the operand ``("flags", (FLAG_COUNT,), "int64")`` receives them (the program
supplies them, the caller does not): ``flags[FLAG_FOUND_NAN]`` (a NaN screen found a NaN:
``run_program`` returns RUN_FOUND_NAN, and the solves after it are skipped),
``flags[FLAG_STOPPED]`` (a level of a hierarchy failed: the levels below it are not solved)
and ``flags[FLAG_ACCEPTED]`` (the program's solve answered within the tolerance of the
controller's answer check). All are 0 when a run starts; the run returns them
(:data:`RUN_FOUND_NAN`, :data:`RUN_ACCEPTED`).

**Input.** A program may have an *input* (:meth:`wbc.runtime.program.TickProgram.set_input`:
the configuration ``q`` its ops read): a run given a non-empty ``q`` first copies it there, so
the control loop's tick is one native call from the caller's ``q`` to the checked answer.
**Output.** A program may have an *output* (:meth:`wbc.runtime.program.TickProgram.set_output`:
the array holding the answer its solve accepted): a run given a non-empty ``out`` copies the
output there when it returns RUN_ACCEPTED (and leaves ``out`` alone otherwise), so the caller's
answer is a fresh array filled in native code -- allocated before the call, when the allocator's
code is still in cache: after a tick's native run, creating a small array costs ~2x as long.
**Clock.** A program may time those runs (:meth:`wbc.runtime.program.TickProgram.set_clock`): from
the run's start, before ``q`` is copied in, to its end (header words ``PROGRAM_*_NS``).
"""

from __future__ import annotations

import inspect
from typing import Any, NamedTuple

#: an operand's shape: ints and expressions over the op's int operands; None for an int operand
Shape = tuple[int | str, ...] | None

#: the dtypes of array operands
DTYPES = ("float64", "int64")
#: the operand through which a built-in op reads and sets the program's flags
FLAGS = "flags"
#: the program's flags: a NaN screen found a NaN; a level of a hierarchy failed; the solve's answer passed
#: the controller's check
FLAG_FOUND_NAN, FLAG_STOPPED, FLAG_ACCEPTED = 0, 1, 2
#: the number of the program's flags
FLAG_COUNT = 3
#: the declaration of the flags operand
FLAGS_OPERAND = (FLAGS, (FLAG_COUNT,), "int64")
#: words of the program's packed array after the flags: the operand index of its input (-1: none), its size
PROGRAM_INPUT, PROGRAM_INPUT_SIZE = 2 + FLAG_COUNT, 3 + FLAG_COUNT
#: the clock that times the runs given a configuration: the address of ``int clock_gettime(clockid_t,
#: struct timespec*)`` (0: untimed) and the clock's id; then the ns from the start of the latest timed
#: run to its end, and the same of the latest timed run that returned RUN_ACCEPTED (both 0 before one)
PROGRAM_CLOCK, PROGRAM_CLOCK_ID, PROGRAM_RUN_NS, PROGRAM_ACCEPTED_NS = (4 + FLAG_COUNT, 5 + FLAG_COUNT,
                                                                        6 + FLAG_COUNT, 7 + FLAG_COUNT)
#: the operand index of the program's output (-1: none) and its size
PROGRAM_OUTPUT, PROGRAM_OUTPUT_SIZE = 8 + FLAG_COUNT, 9 + FLAG_COUNT
#: words before the rows in the program's packed array: rows, width, the flags, the input and its size, the
#: clock and the run times, the output and its size
PROGRAM_HEADER = 10 + FLAG_COUNT
#: what a run returns: a NaN screen found a NaN (the solves after it skipped); else the solve's answer
#: was accepted (flag :data:`FLAG_ACCEPTED`); else 0 -- or, before any row runs, that its ``q`` does not
#: fit the program's input, or a non-empty ``out`` its output (another size, or none: nothing written)
RUN_FOUND_NAN, RUN_ACCEPTED, RUN_BAD_INPUT = 1, 2, 3
#: the row of a third-party op (a CompiledOp): [OP_EXTERNAL, callback address, operands...]; of one of
#: wbc's ops: [OP_BUILTIN, callback address, operands...] (its callback also receives the flags)
OP_EXTERNAL, OP_BUILTIN = 0, 1
#: the task stack A^T ((nv + 1) x rows: W J in rows :nv, W r in row nv), an operand of many ops
STACK = ("stack", ("nv + 1", "rows"))
#: names the generated decoders use for themselves
_RESERVED = {"addresses", "op", "dt", "carray", "kernel", "unpack", "np", FLAGS}


class OpSpec(NamedTuple):
    """Operands of one op, in row order, and the conditions on its int operands."""

    name: str
    operands: tuple[tuple[str, Shape], ...]
    checks: tuple[str, ...] = ()


def parse(name: str, operands: tuple[tuple[Any, ...], ...], checks: tuple[str, ...] = (),
          flags: bool = False) -> tuple[OpSpec, dict[str, str]]:
    """The :class:`OpSpec` and the array dtypes of a declaration; TypeError naming the fault
    for a malformed one. ``flags``: the operand :data:`FLAGS_OPERAND` may be declared."""
    declared: list[tuple[str, Shape]] = []
    dtypes: dict[str, str] = {}
    ints = {entry[0] for entry in operands if isinstance(entry, tuple) and len(entry) >= 2 and entry[1] is None}
    for entry in operands:
        if not (isinstance(entry, tuple) and len(entry) in (2, 3) and isinstance(entry[0], str)
                and entry[0].isidentifier()):
            raise TypeError(f"{name}: each operand is (name, shape) or (name, shape, dtype), got {entry!r}")
        if flags and entry == FLAGS_OPERAND:
            declared.append((FLAGS, (FLAG_COUNT,)))
            dtypes[FLAGS] = "int64"
            continue
        if entry[0] in _RESERVED or entry[0].startswith("_"):
            raise TypeError(f"{name}: operand name {entry[0]!r} is reserved (and names may not start with _)")
        operand, shape = entry[0], entry[1]
        dtype = entry[2] if len(entry) == 3 else "float64"
        if shape is not None and dtype not in DTYPES:
            raise TypeError(f"{name}: operand {operand} has dtype {dtype!r}; array operands are {DTYPES}")
        for dim in shape or ():
            names = set() if isinstance(dim, int) else set(compile(dim, "<shape>", "eval").co_names)
            if not names <= ints:
                raise TypeError(f"{name}: shape of {operand} uses {sorted(names - ints)}, not int operands")
        declared.append((operand, shape))
        dtypes[operand] = dtype
    if len({entry[0] for entry in declared}) != len(declared):
        raise TypeError(f"{name}: operand names repeat")
    return OpSpec(name, tuple(declared), tuple(checks)), dtypes


class Op:
    """One of wbc's ops, declared in its kernel's module of :mod:`wbc.runtime.kernels` (see the
    module docstring); run by the generated interpreter.

    Args:
        name: the op's name, also the module attribute it is assigned to.
        kernel: an ``@njit`` function of the same module whose parameters are the operands in
            declaration order, then ``dt`` (checked: the names too); a thin
            ``inline="always"`` adapter where the arithmetic wants slices or transposes.
        operands: ``(name, shape)`` or ``(name, shape, dtype)``; ``shape`` None for an int
            operand, else a tuple of ints and expressions over the int operands;
            :data:`FLAGS_OPERAND` for the program's flags.
        checks: conditions on the int operands, checked when the op is added.
    """

    def __init__(self, name: str, kernel: Any, operands: tuple[tuple[Any, ...], ...],
                 checks: tuple[str, ...] = ()) -> None:
        self.spec, self.dtypes = parse(name, operands, checks, flags=True)
        parameters = [*(operand for operand, _ in self.spec.operands), "dt"]
        if kernel is not None and list(inspect.signature(getattr(kernel, "py_func", kernel)).parameters) != parameters:
            raise TypeError(f"{name}: the kernel's parameters must be the operands in declaration order, then dt: "
                            f"{parameters}")
        self.kernel = kernel
        #: the opcode, assigned by wbc.runtime.kernels.load (0 until then)
        self.code = 0

    def __repr__(self) -> str:
        return f"Op({self.spec.name!r}, {[name for name, _ in self.spec.operands]})"


def decoder_source(spec: OpSpec, dtypes: dict[str, str], function: str, parameters: str, first: int,
                   kernel: str) -> list[str]:
    """Source lines of ``def function(parameters)`` (parameters among ``op``, ``addresses``,
    ``flags``, ``dt``): the op's operands read from its row ``op`` (the first at position
    ``first``; flags not in the row), each array viewed at its address (``_float64_at`` /
    ``_int64_at``, ``carray``) with its declared shape, then ``kernel(operands..., dt)``."""
    lines = [f"def {function}({parameters}):"]
    positions = {name: first + i for i, name in enumerate(name for name, _ in spec.operands if name != FLAGS)}
    arguments = []
    for operand, shape in spec.operands:
        if shape is None:
            lines.append(f"    {operand} = op[{positions[operand]}]")
    for operand, shape in spec.operands:
        if shape is not None and operand != FLAGS:
            pointer = "_float64_at" if dtypes[operand] == "float64" else "_int64_at"
            dims = ", ".join(str(dim) for dim in shape)
            lines.append(f"    _{operand} = carray({pointer}(addresses[op[{positions[operand]}]]), ({dims},))")
        arguments.append(operand if shape is None or operand == FLAGS else f"_{operand}")
    lines.append(f"    {kernel}({', '.join([*arguments, 'dt'])})")
    return lines
