"""The compiled part of a control tick: a list of kernel calls run by one native call.

Tasks and constraints that have a kernel (:mod:`wbc.runtime.kernels`) register their rows here
once, when the controller is built (``TaskData.add_ops`` / ``ConstraintData.add_ops``);
the controller appends the assembly (normal equations, bound clip, cost normalisation, NaN
screen). Each tick then costs one call of ``run_program`` (:mod:`wbc.runtime.kernels.tick`) for all of it.

Operands are passed by address. Memory safety rests on two rules, both enforced here when
an op is added: every array operand is checked against the op's declared schema
(:class:`wbc.runtime.kernels.ops.Op`: name, float64, C-contiguous, exact shape in terms of the
op's int operands, range conditions on those ints), and the program keeps a reference to
every array it was given, so none is freed or reallocated while the program can run
(views keep their base alive; Pinocchio's buffers live in the controller's ``Kinematics``;
an op whose arrays point into memory owned by another object -- the DAQP workspace of
:class:`wbc.solvers.daqp.native.NativeWorkspace` -- registers that object with :meth:`keep_alive`).
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from types import CodeType
from typing import TYPE_CHECKING, Any

import numpy as np

from . import kernels
from .kernels.ops import (
    FLAGS,
    OP_BUILTIN,
    OP_EXTERNAL,
    PROGRAM_ACCEPTED_NS,
    PROGRAM_CLOCK,
    PROGRAM_CLOCK_ID,
    PROGRAM_HEADER,
    PROGRAM_INPUT,
    PROGRAM_INPUT_SIZE,
    PROGRAM_OUTPUT,
    PROGRAM_OUTPUT_SIZE,
    PROGRAM_RUN_NS,
    RUN_FOUND_NAN,
    Op,
)
from .native_entry import unchecked_entry

if TYPE_CHECKING:  # pragma: no cover
    from .compiled_op import CompiledOp


class TickProgram:
    """Rows ``[kind, callback, operands...]`` over registered arrays (see :mod:`wbc.runtime.kernels.tick`)."""

    def __init__(self) -> None:
        self._arrays: list[np.ndarray] = []
        self._rows: list[list[int]] = []
        self._row_ops: list[Op | None] = []  # the op of each row of wbc's ops (its callback fetched by _resolve)
        self._queued = False  # some row's callback is queued for the compile workers (filled in by _resolve)
        self._packed = np.zeros(PROGRAM_HEADER, dtype=np.int64)
        self._program = np.zeros((0, 1), dtype=np.int64)  # the rows, a view into _packed
        self._owners: list[Any] = []
        self._address_list: list[int] = []
        self._input = (-1, 0)  # operand index and size of the input (set_input; -1: none)
        self._output = (-1, 0)  # operand index and size of the output (set_output; -1: none)
        self._clock = (0, 0)  # the clock timing the runs given a configuration (set_clock; 0: none)
        kernels.prepare("run_program")  # the interpreter compiles now, not at the first run (a compile worker may)

    def keep_alive(self, owner: Any) -> None:
        """Keep ``owner`` (which frees memory an op's operands point to) alive as long as this program."""
        if not any(known is owner for known in self._owners):
            self._owners.append(owner)

    def array(self, array: np.ndarray, dtype: str = "float64") -> int:
        """Register ``array`` (C-contiguous ``dtype``, any shape) and return its operand index."""
        if not isinstance(array, np.ndarray) or array.dtype != dtype or not array.flags.c_contiguous:
            raise TypeError(f"program operands must be C-contiguous {dtype} arrays")
        for index, known in enumerate(self._arrays):
            if known is array:
                return index
        self._arrays.append(array)
        self._address_list.append(array.__array_interface__["data"][0])
        return len(self._arrays) - 1

    def set_input(self, array: np.ndarray) -> None:
        """Make ``array`` (C-contiguous float64, 1-D) the program's *input*: a run given a
        configuration ``q`` (:meth:`stepper`) first copies it there."""
        self._input = self._vector(array, "input")
        self._pack()

    def set_output(self, array: np.ndarray) -> None:
        """Make ``array`` (C-contiguous float64, 1-D: the answer the program's solve writes) the
        program's *output*: a run given an ``out`` (:meth:`stepper`) that returns
        :data:`~wbc.runtime.kernels.ops.RUN_ACCEPTED` copies it there at its end."""
        self._output = self._vector(array, "output")
        self._pack()

    def _vector(self, array: np.ndarray, role: str) -> tuple[int, int]:
        """(operand index, size) of ``array``, registered as the program's ``role`` (a 1-D array)."""
        if not (isinstance(array, np.ndarray) and array.ndim == 1):
            raise TypeError(f"a program's {role} is a 1-D array")
        return self.array(array), array.size

    def set_clock(self, clock_gettime: int, clock_id: int) -> None:
        """Time every run given a configuration (:meth:`stepper`'s) with ``clock_gettime(clock_id)``
        (the address of libc's function, e.g. :class:`wbc.solvers.daqp.abi.Entry`'s): from the
        start of the native call, before ``q`` is copied in, to its return -- read by
        :meth:`run_time` and :meth:`accepted_run_time`. Before :meth:`stepper`, as :meth:`set_input`."""
        if not (isinstance(clock_gettime, int) and clock_gettime != 0 and isinstance(clock_id, int)):
            raise TypeError("set_clock(): the address of clock_gettime (not 0) and a clock id, both ints")
        self._clock = (clock_gettime, clock_id)
        self._pack()

    def run_time(self) -> float:
        """Seconds of the latest timed run (:meth:`set_clock`), whatever it returned; 0 before one."""
        return self._packed.item(PROGRAM_RUN_NS) * 1e-9

    def accepted_run_time(self) -> float:
        """Seconds of the latest timed run that returned
        :data:`~wbc.runtime.kernels.ops.RUN_ACCEPTED`; 0 before one."""
        return self._packed.item(PROGRAM_ACCEPTED_NS) * 1e-9

    def add(self, op: Op | CompiledOp, **operands: Any) -> None:
        """Append one op, its operands given by name: one of wbc's (:class:`wbc.runtime.kernels.ops.Op`,
        e.g. ``kernels.FRAME_TASK``) or a third-party :class:`wbc.runtime.compiled_op.CompiledOp`.

        Raises TypeError for a missing or unknown operand, an array that is not C-contiguous
        float64 (or the declared dtype) of the declared shape, or int operands that break the
        op's conditions. The program's flags (operand ``flags``) are the program's own.
        """
        row: list[int]
        if isinstance(op, Op):
            kernels.load()  # numbers the ops
            if op.code <= 0:
                raise TypeError(f"{op.spec.name} op: not one of wbc.runtime.kernels' ops (declare a built-in op as "
                                "an attribute of its kernel module there; a third-party op is a CompiledOp)")
            # compiled now, when the controller is built; on a first start with compile workers, with the
            # program's other ops before it first runs (_resolve)
            queued = kernels.submit(op)
            self._queued = self._queued or queued
            row = [OP_BUILTIN, 0 if queued else kernels.callback(op)]
        elif hasattr(op, "address"):  # a CompiledOp: its callback's address in the row
            row = [OP_EXTERNAL, op.address]
        else:
            raise TypeError(f"program ops are wbc.runtime.kernels ops or CompiledOps, got {op!r}")
        spec, dtypes = op.spec, op.dtypes
        names = [name for name, _ in spec.operands if name != FLAGS]
        if set(operands) != set(names):
            missing, unknown = sorted(set(names) - set(operands)), sorted(set(operands) - set(names))
            raise TypeError(f"{spec.name} op: missing operands {missing}, unknown operands {unknown}")
        sizes = {name: int(operands[name]) for name, shape in spec.operands if shape is None}
        for check in spec.checks:
            if not eval(_compiled(check), {"__builtins__": {}}, sizes):  # noqa: S307 -- the package's own specs
                raise TypeError(f"{spec.name} op: {check} does not hold for {sizes}")
        arrays = []
        for name, shape in spec.operands:
            if name == FLAGS:
                continue
            if shape is None:
                row.append(sizes[name])
                continue
            expected = tuple(dim if isinstance(dim, int) else eval(_compiled(dim), {"__builtins__": {}}, sizes)
                             for dim in shape)  # noqa: S307 -- the package's own specs
            array = operands[name]
            if not isinstance(array, np.ndarray) or array.shape != expected:
                raise TypeError(f"{spec.name} op: operand {name} must have shape {expected}, got "
                                f"{getattr(array, 'shape', type(array).__name__)}")
            dtype = dtypes.get(name, "float64")
            if array.dtype != dtype or not array.flags.c_contiguous:
                raise TypeError(f"{spec.name} op: operand {name} must be a C-contiguous {dtype} array")
            arrays.append((len(row), array, dtype))
            row.append(-1)
        for position, array, dtype in arrays:  # registered only once the whole op checks
            row[position] = self.array(array, dtype)
        if not isinstance(op, Op):
            self.keep_alive(op)  # its callback's address is in the row
        self._rows.append(row)
        self._row_ops.append(op if isinstance(op, Op) else None)
        self._pack()

    def _resolve(self) -> None:
        """Fill in the callbacks of the ops :meth:`add` queued for the compile workers."""
        if not self._queued:
            return
        queued = [(row, op) for row, op in zip(self._rows, self._row_ops, strict=True) if op is not None and not row[1]]
        for (row, _), address in zip(queued, kernels.callbacks([op for _, op in queued]), strict=True):
            row[1] = address
        self._queued = False
        self._pack()

    def _pack(self) -> None:
        width = max((len(row) for row in self._rows), default=1)
        rows = [row + [0] * (width - len(row)) for row in self._rows]
        header = [len(rows), width, *[0] * (PROGRAM_HEADER - 2)]
        header[PROGRAM_INPUT], header[PROGRAM_INPUT_SIZE] = self._input
        header[PROGRAM_OUTPUT], header[PROGRAM_OUTPUT_SIZE] = self._output
        header[PROGRAM_CLOCK], header[PROGRAM_CLOCK_ID] = self._clock
        #: what the native call receives, one array: [rows, width, the flags, the input and its size, the
        #: clock and the run times, the output and its size, the rows..., the addresses...]
        self._packed = np.array([*header, *(value for row in rows for value in row), *self._address_list],
                                dtype=np.int64)
        self._program = self._packed[PROGRAM_HEADER:PROGRAM_HEADER + len(rows) * width].reshape(-1, width)

    def drop(self, index: int) -> None:
        """Remove row ``index`` (its arrays stay registered and alive); before :meth:`runner`,
        whose callable runs the rows packed when it was made."""
        del self._rows[index]
        del self._row_ops[index]
        self._pack()

    def __len__(self) -> int:
        return len(self._rows)

    def run(self, dt: float) -> bool:
        """Run every row for control period ``dt`` [s]; True when a NaN screen row found a NaN."""
        if self._queued:
            self._resolve()
        return kernels.run_program(self._packed, _NO_INPUT, _NO_OUTPUT, dt) == RUN_FOUND_NAN

    def runner(self) -> Callable[[float], int]:
        """A callable ``run(dt)`` without a Python frame of its own (for the hot path of
        :meth:`wbc.Controller.step`): it runs the rows added so far and returns
        :data:`~wbc.runtime.kernels.ops.RUN_FOUND_NAN`, :data:`~wbc.runtime.kernels.ops.RUN_ACCEPTED` or 0."""
        self._resolve()
        return functools.partial(kernels.run_program, self._packed, _NO_INPUT, _NO_OUTPUT)

    def stepper(self) -> functools.partial[int]:
        """A callable ``run(q, out, dt)`` that copies the configuration ``q`` into the program's input
        (:meth:`set_input`), runs the rows added so far and, when the solve's answer is accepted,
        copies the program's output (:meth:`set_output`) into ``out``, in one native call, returning
        what :meth:`runner`'s does -- the control loop's tick from the caller's ``q`` to the checked
        answer in the caller's ``out``.

        It calls the compiled code without numba's type check of the arguments
        (:func:`wbc.runtime.native_entry.unchecked_entry`): ``q`` must be a 1-D float64 ndarray
        (any strides; read-only too) and ``out`` a writable C-contiguous 1-D float64 ndarray, of
        the output's size or empty (nothing copied), which the caller checks; a ``q`` of another
        size than the input's, or an ``out`` of another size than the output's, returns
        :data:`~wbc.runtime.kernels.ops.RUN_BAD_INPUT`, nothing run or written.
        With a clock (:meth:`set_clock`) each run is timed. It runs the rows packed when it was made.
        It is a :class:`functools.partial` of the compiled entry on the packed operands
        (``args[0]``): a caller on the hot path may call ``func(args[0], q, out, dt)`` itself, ~60 ns
        less than the partial's call."""
        if self._input[0] < 0:
            raise TypeError("stepper(): the program has no input (set_input)")
        self._resolve()
        return functools.partial(unchecked_entry(kernels.run_program), self._packed)


#: the ``q`` of a run that copies no configuration
_NO_INPUT = np.zeros(0)
_NO_INPUT.flags.writeable = False
#: the ``out`` of a run that copies no answer (empty: never written)
_NO_OUTPUT = np.zeros(0)


@functools.cache
def _compiled(expression: str) -> CodeType:
    """An op schema's shape or check expression, compiled once per process."""
    return compile(expression, "<op schema>", "eval")


def ops_follow_compute(item: Any, compute: str = "compute", add_ops: str = "add_ops") -> bool:
    """Whether ``item``'s compiled ops may stand in for its Python ``compute``: False when a
    subclass overrides ``compute`` below the class that defines ``add_ops`` (it has rows of
    its own, which the inherited ops would silently replace)."""
    def owner(name: str) -> type:
        return next(cls for cls in type(item).__mro__ if name in vars(cls))

    return issubclass(owner(add_ops), owner(compute))
