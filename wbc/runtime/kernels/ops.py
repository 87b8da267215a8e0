"""Operand schemas of the tick program's ops: the one place an op's operand order is written.

Each entry of :data:`OP_SPECS` lists an op's operands in row order: an *int* operand
(``None`` shape) or an *array* operand with its shape, whose entries are ints or
expressions over the op's int operands (``"nv + 1"``). :meth:`wbc.runtime.program.TickProgram.add`
takes the operands by name, checks every array against its declared shape (float64,
C-contiguous) and every ``checks`` expression (e.g. that a block of rows lies inside the
stack), and packs the row in this order -- so a misnamed, misshapen or out-of-range operand
raises when the controller is built, never corrupts memory at tick time. The interpreter
(:func:`wbc.runtime.kernels.tick.run_program`) reads the rows in the same order; ``tests/
test_program.py`` checks that every spec matches its decoder's positions and sizes.
"""

from __future__ import annotations

from typing import NamedTuple

from . import (
    CHAIN_COLUMNS,
    DAQP_CONTROL_SIZE,
    DAQP_PROBLEM_WORDS,
    DAQP_RESULT_WORDS,
    DAQP_WORKSPACE_WORDS,
    FRAME_DATA,
    FRAME_SETTINGS,
    OP_BAND,
    OP_DAQP_SOLVE,
    OP_FORWARD_KINEMATICS,
    OP_FRAME_TASK,
    OP_HAS_NAN,
    OP_HEADING_ROWS,
    OP_HIERARCHY_PREVIEW,
    OP_LEVEL_CONSTRAINTS,
    OP_LIFT,
    OP_LIFT_CHECK,
    OP_LM_DAMPING_LEVEL,
    OP_LM_DAMPING_ROWS,
    OP_LM_TASK,
    OP_MANIPULABILITY_BARRIER,
    OP_MERGE_BOUNDS,
    OP_NORMAL_EQUATIONS,
    OP_NORMALISE_COST,
    OP_NORMALISE_LEVEL,
    OP_POSITION_LIMITS,
    OP_POSITION_TASK,
    OP_POSTURE,
    OP_PREVIEW,
    OP_STEERING,
    POSITION_SETTINGS,
)

#: an operand's shape: ints and expressions over the op's int operands; None for an int operand
Shape = tuple[int | str, ...] | None


class OpSpec(NamedTuple):
    """Operands of one op, in row order, and the conditions on its int operands."""

    name: str
    operands: tuple[tuple[str, Shape], ...]
    checks: tuple[str, ...] = ()


_STACK = ("stack", ("nv + 1", "rows"))  # the controller's task stack A^T ((nv + 1) x rows)

#: the schema of every op of wbc's tick program, by opcode (checked by :meth:`wbc.runtime.program.TickProgram.add`)
OP_SPECS: dict[int, OpSpec] = {
    OP_FRAME_TASK: OpSpec("FRAME_TASK", (
        ("joint_jacobians_t", ("nv", 6)), ("rotation_t", (3, 3)), ("translation", (3,)), ("support", ("nv",)),
        ("settings", (FRAME_SETTINGS,)), ("frame", (FRAME_DATA,)), ("error", (6,)), _STACK,
        ("start", None), ("nv", None), ("rows", None)), ("0 <= start", "start + 6 <= rows")),
    OP_POSTURE: OpSpec("POSTURE", (
        ("q", ("dim",)), ("reference", ("dim",)), ("weights", ("dim",)), ("settings", (1,)), ("error", ("dim",)),
        _STACK, ("start", None), ("dim", None), ("nv", None), ("rows", None)),
        ("0 <= start", "start + dim <= rows")),
    OP_POSITION_LIMITS: OpSpec("POSITION_LIMITS", (
        ("q", ("k",)), ("lower_limit", ("k",)), ("upper_limit", ("k",)), ("gain", (1,)), ("lower", ("k",)),
        ("upper", ("k",)), ("k", None))),
    OP_NORMAL_EQUATIONS: OpSpec("NORMAL_EQUATIONS", (
        _STACK, ("nv", None), ("rows", None), ("first", None), ("last", None), ("reset", None),
        ("Hc", ("nv + 1", "nv"))), ("0 <= first", "first <= last", "last <= rows")),
    OP_PREVIEW: OpSpec("PREVIEW", (
        ("Hc", ("nv + 1", "nv")), ("factor", ("nv", "nv")), ("preview", ("nv",)), ("nv", None))),
    OP_STEERING: OpSpec("STEERING", (
        ("preview", ("nv",)), ("q", ("nq",)), ("x", None), ("y", None), ("heading", None), ("settings", (3,)),
        ("error", (1,)), _STACK, ("start", None), ("nv", None), ("rows", None), ("nq", None)),
        ("0 <= start", "start < rows", "0 <= x < nv", "0 <= y < nv", "0 <= heading < nq")),
    OP_MERGE_BOUNDS: OpSpec("MERGE_BOUNDS", (
        ("bounds", ("2 * count", "nv")), ("count", None), ("n_hard", None), ("nv", None), ("upper", ("nv",)),
        ("lower", ("nv",))), ("1 <= count", "0 <= n_hard <= count")),
    OP_HAS_NAN: OpSpec("HAS_NAN", (("data", ("size",)), ("size", None), ("infinite", None)), ("0 <= infinite <= 1",)),
    OP_LM_TASK: OpSpec("LM_TASK", (
        _STACK, ("feedforward", ("dim",)), ("mu", (1,)), ("lm", (1,)), ("start", None), ("dim", None), ("nv", None),
        ("rows", None), ("reset", None)), ("0 <= start", "start + dim <= rows", "0 <= reset <= 1")),
    OP_LM_DAMPING_ROWS: OpSpec("LM_DAMPING_ROWS", (
        _STACK, ("mu", (1,)), ("scaling", (2,)), ("nv", None), ("rows", None), ("first", None)),
        ("0 <= first", "first + nv <= rows")),
    OP_LM_DAMPING_LEVEL: OpSpec("LM_DAMPING_LEVEL", (
        ("mu", (1,)), ("scaling", (2,)), ("Hc", ("nv + 1", "nv")), ("nv", None))),
    OP_NORMALISE_COST: OpSpec("NORMALISE_COST", (("Hc", ("nv + 1", "nv")), ("scaling", (2,)), ("nv", None))),
    OP_HEADING_ROWS: OpSpec("HEADING_ROWS", (
        ("cos_part", ("rows", 2)), ("sin_part", ("rows", 2)), ("q", ("nq",)), ("heading", None),
        ("G", ("rows", "nv")), ("rows", None), ("nq", None), ("nv", None), ("x", None), ("y", None)),
        ("0 <= heading < nq", "0 <= x < nv", "0 <= y < nv")),
    OP_POSITION_TASK: OpSpec("POSITION_TASK", (
        ("joint_jacobians_t", ("nv", 6)), ("rotation_t", (3, 3)), ("translation", (3,)), ("support", ("nv",)),
        ("settings", (POSITION_SETTINGS,)), ("frame", (FRAME_DATA,)), ("error", (3,)), _STACK,
        ("start", None), ("nv", None), ("rows", None), ("jacobian", (6, "nv")), ("feedforward", (3,))),
        ("0 <= start", "start + 3 <= rows")),
    OP_MANIPULABILITY_BARRIER: OpSpec("MANIPULABILITY_BARRIER", (
        ("joint_jacobians_t", ("nv", 6)), ("rotation_t", (3, 3)), ("translation", (3,)), ("local", (12,)),
        ("support", ("nv",)), ("ancestor", ("nv", "nv")), ("jacobian", (6, "nv")), ("origin", (3,)),
        ("gradient", ("nv",)), ("G", ("nv",)), ("h", (1,)), ("settings", (2,)), ("value", (1,)),
        ("first", None), ("last", None), ("nv", None)), ("0 <= first < last <= 6",)),
    OP_DAQP_SOLVE: OpSpec("DAQP_SOLVE", (
        ("problem", (DAQP_PROBLEM_WORDS,)), ("workspace", (DAQP_WORKSPACE_WORDS,)), ("result", (DAQP_RESULT_WORDS,)),
        ("control", (DAQP_CONTROL_SIZE,)), ("data", ("size",)), ("x", ("n",)), ("n", None), ("size", None),
        ("update_ldp", None), ("solve", None), ("clock_gettime", None), ("clock_id", None), ("steady_mask", None)),
        ("1 <= n", "n * n + 3 * n <= size", "(size - n * n - 3 * n) % (n + 2) == 0", "update_ldp != 0",
         "solve != 0", "clock_gettime != 0")),
    OP_LIFT: OpSpec("LIFT", (
        ("stack", ("nv + 1", "stack_rows")), ("diagonal", ("rows",)), ("source", ("source_size",)),
        ("lifted", ("lifted_size",)), ("scaling", (2,)), ("nv", None), ("stack_rows", None), ("rows", None),
        ("k", None), ("p", None), ("e", None), ("source_size", None), ("lifted_size", None)),
        ("1 <= nv", "0 <= k <= rows <= stack_rows", "0 <= p", "0 <= e",
         "source_size == nv * nv + 3 * nv + (p + e) * (nv + 2)",
         "lifted_size == (nv + k) * (nv + k) + 3 * (nv + k) + (p + e + k) * (nv + k + 2)")),
    OP_LIFT_CHECK: OpSpec("LIFT_CHECK", (
        ("lifted", ("lifted_size",)), ("x", ("nv + k",)), ("lam", ("nv + k + p + e + k",)), ("scratch", ("2 * nv",)),
        ("control", (DAQP_CONTROL_SIZE,)), ("nv", None), ("k", None), ("p", None), ("e", None),
        ("lifted_size", None)),
        ("1 <= nv", "0 <= k", "0 <= p", "0 <= e",
         "lifted_size == (nv + k) * (nv + k) + 3 * (nv + k) + (p + e + k) * (nv + k + 2)")),
    OP_FORWARD_KINEMATICS: OpSpec("FORWARD_KINEMATICS", (
        ("q", ("nq",)), ("chain", ("joints", CHAIN_COLUMNS)), ("placements", ("joints", 12)),
        ("jacobians_t", ("nv", 6)), ("nq", None), ("joints", None), ("nv", None)), ("1 <= joints",)),
    # strict priorities (wbc.control.hierarchy)
    OP_LEVEL_CONSTRAINTS: OpSpec("LEVEL_CONSTRAINTS", (
        ("source", ("source_size",)), ("target", ("target_size",)), ("n", None), ("p", None), ("e", None),
        ("band", None), ("source_size", None), ("target_size", None)),
        ("1 <= n", "0 <= p", "0 <= e", "0 <= band", "source_size == n * n + 3 * n + (p + e) * (n + 2)",
         "target_size == n * n + 3 * n + (p + band + e) * (n + 2)")),
    OP_NORMALISE_LEVEL: OpSpec("NORMALISE_LEVEL", (("Hc", ("nv + 1", "nv")), ("scaling", (2,)), ("nv", None))),
    OP_BAND: OpSpec("BAND", (
        _STACK, ("first", None), ("last", None), ("first_preview", None), ("last_preview", None), ("x", ("nv",)),
        ("lower", ("nv",)), ("upper", ("nv",)), ("control", (DAQP_CONTROL_SIZE,)), ("settings", (2,)),
        ("target", ("size",)), ("nv", None), ("rows", None), ("size", None), ("row", None), ("target_rows", None)),
        ("1 <= nv", "0 <= first <= last <= rows", "0 <= first_preview <= last_preview <= rows", "0 <= row",
         "row + 2 * (last - first + last_preview - first_preview) <= target_rows",
         "size == nv * nv + 3 * nv + target_rows * (nv + 2)")),
    OP_HIERARCHY_PREVIEW: OpSpec("HIERARCHY_PREVIEW", (
        _STACK, ("ranges", ("count",)), ("scaling", (2,)), ("preview", ("nv",)), ("nv", None), ("rows", None),
        ("count", None)), ("1 <= nv", "2 <= count", "count % 2 == 0")),
}
