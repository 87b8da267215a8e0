"""The op schemas (wbc.runtime.kernels.ops) are the one place an op's operand order is written:
the interpreter must read each row as its schema says, and TickProgram.add must refuse
anything else when the controller is built."""

import ast
import inspect
import re

import numpy as np
import pytest

from wbc.runtime import kernels
from wbc.runtime.kernels import ops, tick
from wbc.runtime.program import TickProgram

CONSTANTS = {name: getattr(kernels, name) for name in ("FRAME_SETTINGS", "FRAME_DATA", "POSITION_SETTINGS",
                                                       "DAQP_PROBLEM_WORDS", "DAQP_WORKSPACE_WORDS",
                                                       "DAQP_RESULT_WORDS", "DAQP_CONTROL_SIZE", "CHAIN_COLUMNS")}


def _decoder_blocks() -> dict[str, str]:
    """Source of each ``if/elif code == OP_X:`` branch of run_program, by opcode name."""
    source = inspect.getsource(tick.run_program)
    parts = re.split(r"\n\s+(?:el)?if code == (OP_\w+):\n", source)
    return {parts[i]: parts[i + 1] for i in range(1, len(parts) - 1, 2)}


def _normal(expression: str, names_at: dict[int, str]) -> str:
    expression = re.sub(r"op\[(\d+)\]", lambda m: names_at[int(m.group(1))], expression.strip())
    for name, value in CONSTANTS.items():
        expression = re.sub(rf"\b{name}\b", str(value), expression)
    return expression.replace(" ", "")


@pytest.mark.parametrize("code", sorted(ops.OP_SPECS), ids=lambda code: ops.OP_SPECS[code].name)
def test_the_interpreter_reads_every_row_as_its_schema_says(code):
    spec = ops.OP_SPECS[code]
    block = _decoder_blocks()[f"OP_{spec.name}"]
    position = {name: i + 1 for i, (name, _) in enumerate(spec.operands)}
    shape_of = dict(spec.operands)
    names_at = {i: name for name, i in position.items()}
    # int operands: "nv, rows, start = op[10], op[11], op[9]" / "k = op[7]"
    for targets, values in re.findall(r"^\s*([\w, ]+) = (op\[\d+\](?:, op\[\d+\])*)\s*$", block, re.M):
        for name, value in zip(targets.split(","), values.split(","), strict=True):
            index = int(re.search(r"\d+", value).group())
            assert names_at[index] == name.strip() and shape_of[name.strip()] is None, (spec.name, name, index)
    # array operands: _vector(addresses, op[k], n) / _matrix(addresses, op[k], rows, columns)
    reads = re.findall(r"_(vector|matrix)\(addresses, op\[(\d+)\], ([^()]+?)\)", block)
    assert reads, spec.name
    arrays = {i for i, (_, shape) in enumerate(spec.operands, start=1) if shape is not None}
    assert {int(index) for _, index, _ in reads} == arrays, spec.name
    for _, index, dims in reads:
        shape = shape_of[names_at[int(index)]]
        declared = [str(dim).replace(" ", "") for dim in shape]
        read = [_normal(dim, names_at) for dim in ast.literal_eval(f"[{dims!r}]")[0].split(",")]
        assert read == declared, (spec.name, names_at[int(index)], read, declared)
    # ints used directly as kernel arguments (x, y, heading, first row, ...) are ints in the schema
    for index in map(int, re.findall(r"(?<![\w\[])op\[(\d+)\](?!\])", block)):
        assert index in names_at, (spec.name, index)


def test_misnamed_misshapen_or_out_of_range_operands_are_refused():
    program = TickProgram()
    Hc, factor, preview = np.zeros((5, 4)), np.zeros((4, 4)), np.zeros(4)
    program.add(kernels.OP_PREVIEW, Hc=Hc, factor=factor, preview=preview, nv=4)
    with pytest.raises(TypeError, match="missing operands \\['preview'\\]"):
        program.add(kernels.OP_PREVIEW, Hc=Hc, factor=factor, preveiw=preview, nv=4)
    with pytest.raises(TypeError, match="operand factor must have shape \\(4, 4\\)"):
        program.add(kernels.OP_PREVIEW, Hc=Hc, factor=np.zeros((4, 5)), preview=preview, nv=4)
    with pytest.raises(TypeError, match="C-contiguous float64"):
        program.add(kernels.OP_PREVIEW, Hc=Hc, factor=factor, preview=np.zeros(8)[::2], nv=4)
    stack = np.zeros((5, 10))
    with pytest.raises(TypeError, match="start \\+ 6 <= rows"):  # a block past the end of the stack
        program.add(kernels.OP_FRAME_TASK, joint_jacobians_t=np.zeros((4, 6)), rotation_t=np.zeros((3, 3)),
                    translation=np.zeros(3), support=np.zeros(4), settings=np.zeros(kernels.FRAME_SETTINGS),
                    frame=np.zeros(kernels.FRAME_DATA), error=np.zeros(6), stack=stack, start=5, nv=4, rows=10)
    assert len(program) == 1  # nothing half-added
