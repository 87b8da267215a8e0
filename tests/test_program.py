"""An op is declared once, next to its kernel (wbc.runtime.kernels.ops.Op); the interpreter is
generated from the declarations: every declared op is dispatched, its decoder hands the kernel
exactly the arrays and ints TickProgram.add was given, and TickProgram.add refuses anything
else when the controller is built."""

import importlib
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from conftest import child_environment
from wbc.runtime import kernels
from wbc.runtime.compiled_op import CompiledOp
from wbc.runtime.kernels import ops
from wbc.runtime.program import TickProgram

DT = 0.01
NO_OUT = np.zeros(0)  # a stepper's out that takes no answer


def _declared() -> dict[str, ops.Op]:
    """Every Op of the topic modules, found independently of kernels.load."""
    found = {}
    for module_name in kernels.topic_modules():
        module = importlib.import_module(f"wbc.runtime.kernels.{module_name}")
        found |= {name: value for name, value in vars(module).items() if isinstance(value, ops.Op)}
    return found


DECLARED = _declared()

#: the ops that call DAQP (run here only where a flag skips them: their addresses are dummies)
DAQP_OPS = ("DAQP_SOLVE", "DAQP_SOLVE_WORKING_SET")

#: int operands satisfying each op's checks (the arrays follow from them)
INTS = {
    "BAND": dict(first=1, last=3, first_preview=0, last_preview=1, nv=3, rows=5, size=9 + 9 + 8 * 5, row=1,
                 target_rows=8),
    "DAQP_ACCEPT": {},
    "DAQP_ACCEPT_LEVEL": {},
    "DAQP_SOLVE": dict(n=3, size=9 + 9 + 2 * 5, m=5, update_ldp=1, solve=1, clock_gettime=1, clock_id=1,
                       steady_mask=0, unconstrained_first=1, sense_word=7),
    "DAQP_SOLVE_WORKING_SET": dict(n=3, size=9 + 9 + 2 * 5, m=5, update_ldp=1, solve=1, clock_gettime=1,
                                   clock_id=1, steady_mask=0, sense_word=7),
    "FORWARD_KINEMATICS": dict(nq=2, joints=3, nv=2),
    "FRAME_TASK": dict(start=2, nv=4, rows=9),
    "HAS_NAN": dict(size=7, infinite=1),
    "HEADING_ROWS": dict(rows=3, nq=5, nv=4, heading=2, x=0, y=1),
    "HIERARCHY_PREVIEW": dict(nv=3, rows=6, count=4),
    "LEVEL_CONSTRAINTS": dict(n=3, p=2, e=1, band=2, source_size=9 + 9 + 3 * 5, target_size=9 + 9 + 5 * 5),
    "LIFT": dict(nv=3, stack_rows=6, rows=4, k=2, p=1, e=1, source_size=9 + 9 + 2 * 5,
                 lifted_size=25 + 15 + 4 * 7),
    "LIFT_CHECK": dict(nv=3, k=2, p=1, e=1, lifted_size=25 + 15 + 4 * 7),
    "LM_DAMPING_LEVEL": dict(nv=3),
    "LM_DAMPING_ROWS": dict(nv=3, rows=8, first=4),
    "LM_TASK": dict(start=1, dim=3, nv=4, rows=6, reset=1),
    "MANIPULABILITY_BARRIER": dict(first=0, last=6, nv=5),
    "MERGE_BOUNDS": dict(count=3, n_hard=1, nv=4),
    "NORMALISE_COST": dict(nv=4),
    "NORMALISE_LEVEL": dict(nv=4),
    "NORMAL_EQUATIONS": dict(nv=4, rows=7, first=1, last=6, reset=1),
    "LINEAR_COST": dict(nv=4, rows=7, first=5, last=7),
    "POSITION_LIMITS": dict(k=4),
    "POSITION_TASK": dict(start=1, nv=4, rows=6),
    "POSTURE": dict(start=1, dim=3, nv=4, rows=6),
    "PREVIEW": dict(nv=4),
    "STEERING": dict(x=0, y=1, heading=2, start=1, nv=4, rows=6, nq=5),
}


def _chain() -> np.ndarray:
    """A universe row and two joints (revolute about z, then prismatic along x) of CHAIN_COLUMNS."""
    chain = np.zeros((3, kernels.CHAIN_COLUMNS))
    for j, (parent, kind, axis) in enumerate([(0, 0.0, (0, 0, 1)), (1, kernels.CHAIN_PRISMATIC, (1, 0, 0))], start=1):
        chain[j, :7] = (parent, kind, j - 1, j - 1, *axis)
        chain[j, 7:16] = np.eye(3).ravel()
        chain[j, 16:19] = (0.1 * j, 0.0, 0.2)
    return chain


def _operands(op: ops.Op, rng: np.random.Generator) -> dict:
    """Operands of ``op`` by name: its ints from INTS, random arrays of the declared shapes (valid
    where the kernel indexes with the values)."""
    ints = INTS[op.spec.name]
    operands: dict = dict(ints)
    for name, shape in op.spec.operands:
        if shape is None or name == ops.FLAGS:
            continue
        dims = tuple(dim if isinstance(dim, int) else eval(dim, {}, ints) for dim in shape)  # noqa: S307
        operands[name] = rng.normal(size=dims)
    if op.spec.name == "FORWARD_KINEMATICS":
        operands["chain"] = _chain()
    if op.spec.name == "HIERARCHY_PREVIEW":
        operands["ranges"] = np.array([0.0, 2.0, 2.0, 6.0])
    if op.spec.name == "HAS_NAN":
        operands["data"][3] = np.inf
    if op.spec.name in ("BAND", "LIFT_CHECK"):  # a successful solve: band rows written, stationarity checked
        operands["control"][[kernels.DAQP_CONTROL_EXITFLAG, kernels.DAQP_CONTROL_DEFECT]] = (1.0, 0.0)
    if op.spec.name == "BAND":
        operands["settings"][0] = 1.0
    if op.spec.name in ("LM_DAMPING_LEVEL", "LM_DAMPING_ROWS", "LM_TASK"):  # damping that acts
        operands["mu"][0] = 2.0
        if "scaling" in operands:
            operands["scaling"] = np.array([0.5, 0.1])
    if op.spec.name == "LM_TASK":
        operands["lm"][0] = 0.3
    if op.spec.name in ("MANIPULABILITY_BARRIER", "FRAME_TASK", "POSITION_TASK"):
        operands["support"] = (rng.random(operands["support"].size) > 0.3).astype(float)
    return operands


@pytest.fixture(scope="module", autouse=True)
def loaded():
    kernels.load()


def test_every_declared_op_is_numbered_and_bound():
    assert DECLARED and set(DECLARED) == set(INTS)  # a new op gets a case here
    codes = sorted(op.code for op in DECLARED.values())
    assert codes == list(range(1, len(DECLARED) + 1))  # unique, none is OP_EXTERNAL
    assert ops.OP_EXTERNAL not in codes
    for name, op in DECLARED.items():
        assert getattr(kernels, name) is op and op.spec.name == name


@pytest.mark.parametrize("name", sorted(set(DECLARED) - {*DAQP_OPS, "DAQP_ACCEPT", "DAQP_ACCEPT_LEVEL"}))  # (below)
def test_the_generated_decoder_calls_the_kernel_with_the_declared_operands(name):
    """One row run by run_program changes every array exactly as the kernel called directly on
    copies of the same arrays (operands in declaration order, then dt)."""
    op = DECLARED[name]
    operands = _operands(op, np.random.default_rng(len(name)))
    direct = {key: value.copy() if isinstance(value, np.ndarray) else value for key, value in operands.items()}
    program = TickProgram()
    program.add(op, **operands)  # first: compiles the kernels it calls for their declared signatures, as in use
    flags = np.zeros(ops.FLAG_COUNT, dtype=np.int64)
    op.kernel(*(flags if key == ops.FLAGS else direct[key] for key, _ in op.spec.operands), DT)
    found_nan = program.run(DT)
    assert found_nan == bool(flags[ops.FLAG_FOUND_NAN])
    changed = False
    for key, value in operands.items():
        if isinstance(value, np.ndarray):
            np.testing.assert_array_equal(value, direct[key], err_msg=f"{name}: operand {key}")
            changed = changed or not np.array_equal(value, _operands(op, np.random.default_rng(len(name)))[key],
                                                    equal_nan=True)
    assert changed or found_nan, f"{name}: the run wrote nothing"


def _daqp_operands(control: np.ndarray, name: str) -> dict:
    """Operands of DAQP op ``name`` whose function addresses are dummies: the row must be skipped."""
    operands = _operands(DECLARED[name], np.random.default_rng(0))
    operands["control"] = control
    return operands


@pytest.mark.parametrize("name", DAQP_OPS)
def test_a_nan_screen_skips_the_solves_after_it(name):
    program = TickProgram()
    data, control = np.array([0.0, np.nan]), np.full(kernels.DAQP_CONTROL_SIZE, 7.0)
    program.add(kernels.HAS_NAN, data=data, size=2, infinite=0)
    program.add(DECLARED[name], **_daqp_operands(control, name))  # would jump to address 1 if run
    assert program.run(DT) is True
    assert control[kernels.DAQP_CONTROL_EXITFLAG] == kernels.DAQP_SKIPPED
    screen = TickProgram()  # the flags start from 0 at every run: a clean tick after a NaN is clean
    screen.add(kernels.HAS_NAN, data=data, size=2, infinite=0)
    assert screen.run(DT) is True
    data[1] = 0.0
    assert screen.run(DT) is False


@pytest.mark.parametrize("name", DAQP_OPS)
def test_a_failed_level_stops_the_solves_below_it(name):
    operands = _operands(DECLARED["BAND"], np.random.default_rng(1))
    operands["control"][kernels.DAQP_CONTROL_EXITFLAG] = -1.0  # the level's solve failed
    target = operands["target"].copy()
    program = TickProgram()
    program.add(kernels.BAND, **operands)
    control = np.full(kernels.DAQP_CONTROL_SIZE, 7.0)
    program.add(DECLARED[name], **_daqp_operands(control, name))
    assert program.run(DT) is False  # a stop is no NaN
    assert control[kernels.DAQP_CONTROL_EXITFLAG] == kernels.DAQP_SKIPPED
    np.testing.assert_array_equal(operands["target"], target)  # no band rows written


@pytest.mark.parametrize(("exitflag", "defect", "accepted"), [
    (1.0, 0.0, True), (2.0, 1e-6, True),  # solved (DAQP's exit flags >= 1), defect at most the tolerance
    (1.0, 1.1e-6, False), (1.0, np.inf, False), (1.0, np.nan, False),  # an answer that does not check
    (0.0, 0.0, False), (-1.0, 0.0, False), (-4.0, 0.0, False)])  # skipped, infeasible, iteration limit
def test_the_accept_op_passes_exactly_the_answers_within_the_tolerance(exitflag, defect, accepted):
    control = np.zeros(kernels.DAQP_CONTROL_SIZE)
    control[[kernels.DAQP_CONTROL_EXITFLAG, kernels.DAQP_CONTROL_DEFECT]] = (exitflag, defect)
    program = TickProgram()
    program.add(kernels.DAQP_ACCEPT, control=control, tolerance=np.array([1e-6]))
    assert program.runner()(DT) == (ops.RUN_ACCEPTED if accepted else 0)
    assert program.run(DT) is False  # not a NaN either way


@pytest.mark.parametrize("accepted", [True, False])
def test_the_level_ops_add_the_levels_solve_times_to_an_accepted_answer_only(accepted):
    """Strict priorities: DAQP_ACCEPT on the last level's control, then DAQP_ACCEPT_LEVEL per level
    above: the accepted solve time is the three solve times' sum (written out here); a run that is
    not accepted leaves the accepted time of the run before."""
    last, upper = np.zeros(kernels.DAQP_CONTROL_SIZE), np.zeros((2, kernels.DAQP_CONTROL_SIZE))
    last[[kernels.DAQP_CONTROL_EXITFLAG, kernels.DAQP_CONTROL_DEFECT, kernels.DAQP_CONTROL_TIME]] = (
        1.0 if accepted else -1.0, 0.0, 3e-6)
    last[kernels.DAQP_CONTROL_ACCEPTED_TIME] = 7.0  # an earlier accepted run's
    upper[:, kernels.DAQP_CONTROL_TIME] = (1e-6, 2e-6)
    program = TickProgram()
    program.add(kernels.DAQP_ACCEPT, control=last, tolerance=np.array([1e-6]))
    for control in upper:
        program.add(kernels.DAQP_ACCEPT_LEVEL, control=last, upper=control)
    assert program.runner()(DT) == (ops.RUN_ACCEPTED if accepted else 0)
    assert last[kernels.DAQP_CONTROL_ACCEPTED_TIME] == ((3e-6 + 1e-6) + 2e-6 if accepted else 7.0)
    assert last[kernels.DAQP_CONTROL_TIME] == 3e-6 and (upper[:, kernels.DAQP_CONTROL_TIME] == (1e-6, 2e-6)).all()


def test_a_nan_screen_outranks_an_accepted_answer_and_flags_start_clean():
    data, control = np.zeros(2), np.zeros(kernels.DAQP_CONTROL_SIZE)
    control[kernels.DAQP_CONTROL_EXITFLAG] = 1.0
    program = TickProgram()
    program.add(kernels.DAQP_ACCEPT, control=control, tolerance=np.array([1e-6]))
    program.add(kernels.HAS_NAN, data=data, size=2, infinite=0)
    run = program.runner()
    assert run(DT) == ops.RUN_ACCEPTED
    data[0] = np.nan
    assert run(DT) == ops.RUN_FOUND_NAN
    data[0], control[kernels.DAQP_CONTROL_EXITFLAG] = 0.0, -1.0
    assert run(DT) == 0  # no flag of an earlier run survives


def _input_program(size: int) -> tuple[TickProgram, np.ndarray, np.ndarray]:
    """(program, its input, seen): the program screens its input for NaN and inf, then writes
    input + dt into ``seen`` (a CompiledOp)."""
    from numba import njit

    @njit(nogil=True)
    def copy(source, target, n, dt):
        for i in range(n):
            target[i] = source[i] + dt

    into, seen = np.zeros(size), np.zeros(size)
    program = TickProgram()
    program.set_input(into)
    program.add(kernels.HAS_NAN, data=into, size=size, infinite=1)
    program.add(CompiledOp("COPY", copy, (("source", ("n",)), ("target", ("n",)), ("n", None))),
                source=into, target=seen, n=size)
    return program, into, seen


def test_a_stepper_copies_q_into_the_input_before_the_rows_run():
    program, into, seen = _input_program(4)
    step = program.stepper()
    q = np.array([1.0, 2.0, 3.0, 4.0])
    assert step(q, NO_OUT, 0.5) == 0
    np.testing.assert_array_equal(into, q)
    np.testing.assert_array_equal(seen, q + 0.5)  # the rows saw this q
    wide = np.arange(8.0)
    wide.flags.writeable = False
    assert step(wide[::2], NO_OUT, 0.0) == 0  # any strides, read-only: only read
    np.testing.assert_array_equal(seen, [0.0, 2.0, 4.0, 6.0])
    assert step(np.array([0.0, np.inf, 0.0, 0.0]), NO_OUT, 0.0) == ops.RUN_FOUND_NAN  # the screen saw it
    into[:] = 7.0
    assert program.run(0.0) is False  # run(dt) copies nothing
    np.testing.assert_array_equal(seen, np.full(4, 7.0))


def test_a_stepper_refuses_a_q_of_another_size_before_running():
    program, into, seen = _input_program(3)
    step = program.stepper()
    for q in (np.zeros(2), np.zeros(4), np.full(2, np.nan)):
        assert step(q, NO_OUT, DT) == ops.RUN_BAD_INPUT
        np.testing.assert_array_equal(into, np.zeros(3))
        np.testing.assert_array_equal(seen, np.zeros(3))
    with pytest.raises(TypeError, match="the program has no input"):
        TickProgram().stepper()
    with pytest.raises(TypeError, match="1-D array"):
        TickProgram().set_input(np.zeros((2, 2)))


def test_a_stepper_copies_the_output_into_out_only_for_an_accepted_answer():
    """set_output: a run that returns RUN_ACCEPTED copies the output (here the rows' input + dt)
    into the caller's ``out``, its own memory; a run that is not accepted, or found a NaN,
    leaves ``out`` alone; an ``out`` of another size than the output's, or any ``out`` without
    an output, is refused before anything runs."""
    control = np.zeros(kernels.DAQP_CONTROL_SIZE)
    control[kernels.DAQP_CONTROL_EXITFLAG] = 1.0  # solved, defect 0: accepted
    program, into, seen = _input_program(3)
    program.add(kernels.DAQP_ACCEPT, control=control, tolerance=np.array([1e-6]))
    program.set_output(seen)
    step, q, out = program.stepper(), np.array([1.0, -2.0, 0.25]), np.full(3, -7.0)
    assert step(q, out, DT) == ops.RUN_ACCEPTED
    np.testing.assert_array_equal(out, q + DT)
    seen[:] = 0.0
    np.testing.assert_array_equal(out, q + DT)  # a copy, not a view of the output
    for exitflag, given, outcome in ((-1.0, q, 0), (1.0, np.array([0.0, np.nan, 0.0]), ops.RUN_FOUND_NAN)):
        control[kernels.DAQP_CONTROL_EXITFLAG], out[:] = exitflag, -7.0
        assert step(given, out, DT) == outcome
        np.testing.assert_array_equal(out, np.full(3, -7.0))  # not accepted: out untouched
    control[kernels.DAQP_CONTROL_EXITFLAG], into[:], seen[:] = 1.0, 0.0, 0.0
    for wrong in (np.full(2, -7.0), np.full(4, -7.0)):
        assert step(q, wrong, DT) == ops.RUN_BAD_INPUT
        np.testing.assert_array_equal(wrong, np.full(wrong.size, -7.0))
        np.testing.assert_array_equal(into, np.zeros(3))  # nothing run: q not copied in
        np.testing.assert_array_equal(seen, np.zeros(3))
    assert step(q, NO_OUT, DT) == ops.RUN_ACCEPTED  # an empty out takes nothing
    without, _, _ = _input_program(3)
    assert without.stepper()(q, np.zeros(3), DT) == ops.RUN_BAD_INPUT  # no output to copy
    with pytest.raises(TypeError, match="1-D array"):
        TickProgram().set_output(np.zeros((2, 2)))


def _libc_clock() -> tuple[int, int]:
    """(address of libc's clock_gettime, CLOCK_MONOTONIC): time.perf_counter's clock, found here."""
    import ctypes
    import time

    return ctypes.cast(ctypes.CDLL(None).clock_gettime, ctypes.c_void_p).value, time.CLOCK_MONOTONIC


def test_a_clock_times_the_runs_given_a_q_and_keeps_the_latest_accepted_one():
    """set_clock: every stepper run that ran is timed (run_time), from the native call's start to
    its return -- within the wall time around the call, same clock; the accepted ones also in
    accepted_run_time, which a run that was not accepted, a run without q (runner) and a refused
    q leave alone. Without a clock nothing is timed."""
    import time

    control = np.zeros(kernels.DAQP_CONTROL_SIZE)
    control[kernels.DAQP_CONTROL_EXITFLAG] = 1.0  # solved, defect 0: accepted
    untimed, _, _ = _input_program(3)
    untimed.add(kernels.DAQP_ACCEPT, control=control, tolerance=np.array([1e-6]))
    assert untimed.stepper()(np.ones(3), NO_OUT, DT) == ops.RUN_ACCEPTED
    assert untimed.run_time() == untimed.accepted_run_time() == 0.0
    program, into, _ = _input_program(3)
    program.add(kernels.DAQP_ACCEPT, control=control, tolerance=np.array([1e-6]))
    program.set_clock(*_libc_clock())
    step, header = program.stepper(), program._packed
    start = time.perf_counter()
    assert step(np.ones(3), NO_OUT, DT) == ops.RUN_ACCEPTED
    elapsed = time.perf_counter() - start
    assert 0.0 < program.run_time() == program.accepted_run_time() <= elapsed
    header[ops.PROGRAM_RUN_NS], header[ops.PROGRAM_ACCEPTED_NS] = -1, -5  # marks: which words a run writes
    control[kernels.DAQP_CONTROL_EXITFLAG] = -1.0  # not accepted
    start = time.perf_counter()
    assert step(np.ones(3), NO_OUT, DT) == 0
    elapsed = time.perf_counter() - start
    assert 0.0 < program.run_time() <= elapsed and program.accepted_run_time() == -5e-9
    header[ops.PROGRAM_RUN_NS] = -1
    assert step(np.full(3, np.nan), NO_OUT, DT) == ops.RUN_FOUND_NAN  # ran (the screen found it): timed
    assert program.run_time() > 0.0 and program.accepted_run_time() == -5e-9
    control[kernels.DAQP_CONTROL_EXITFLAG], into[:] = 1.0, 0.0  # (the input held the NaN)
    header[ops.PROGRAM_RUN_NS] = -1
    assert program.runner()(DT) == ops.RUN_ACCEPTED and step(np.ones(4), NO_OUT, DT) == ops.RUN_BAD_INPUT
    assert program.run_time() == -1e-9 and program.accepted_run_time() == -5e-9  # neither was a timed run
    with pytest.raises(TypeError, match="clock_gettime"):
        program.set_clock(0, 1)


def test_misnamed_misshapen_or_out_of_range_operands_are_refused():
    program = TickProgram()
    Hc, factor, preview = np.zeros((5, 4)), np.zeros((4, 4)), np.zeros(4)
    program.add(kernels.PREVIEW, Hc=Hc, factor=factor, preview=preview, nv=4)
    with pytest.raises(TypeError, match="missing operands \\['preview'\\]"):
        program.add(kernels.PREVIEW, Hc=Hc, factor=factor, preveiw=preview, nv=4)
    with pytest.raises(TypeError, match="operand factor must have shape \\(4, 4\\)"):
        program.add(kernels.PREVIEW, Hc=Hc, factor=np.zeros((4, 5)), preview=preview, nv=4)
    with pytest.raises(TypeError, match="C-contiguous float64"):
        program.add(kernels.PREVIEW, Hc=Hc, factor=factor, preview=np.zeros(8)[::2], nv=4)
    stack = np.zeros((5, 10))
    with pytest.raises(TypeError, match="start \\+ 6 <= rows"):  # a block past the end of the stack
        program.add(kernels.FRAME_TASK, joint_jacobians_t=np.zeros((4, 6)), rotation_t=np.zeros((3, 3)),
                    translation=np.zeros(3), support=np.zeros(4), settings=np.zeros(kernels.FRAME_SETTINGS),
                    frame=np.zeros(kernels.FRAME_DATA), error=np.zeros(6), stack=stack, start=5, nv=4, rows=10,
                    feedforward=np.zeros(6))
    with pytest.raises(TypeError, match="unknown operands \\['flags'\\]"):  # the flags are the program's own
        program.add(kernels.HAS_NAN, data=np.zeros(3), size=3, infinite=0, flags=np.zeros(2, dtype=np.int64))
    assert len(program) == 1  # nothing half-added


def test_an_op_declared_outside_the_kernels_package_is_refused():
    stray = ops.Op("STRAY", kernels.PREVIEW.kernel, kernels.PREVIEW.spec.operands)  # not numbered by load
    with pytest.raises(TypeError, match="STRAY op: not one of wbc.runtime.kernels' ops"):
        TickProgram().add(stray, Hc=np.zeros((3, 2)), factor=np.zeros((2, 2)), preview=np.zeros(2), nv=2)


def test_declarations_are_checked_when_made():
    with pytest.raises(TypeError, match="shape of G uses \\['cols'\\], not int operands"):
        ops.Op("BAD", None, (("G", ("rows", "cols")), ("rows", None)))
    with pytest.raises(TypeError, match="operand name 'op' is reserved"):
        ops.Op("BAD", None, (("op", None),))
    with pytest.raises(TypeError, match="operand name 'flags' is reserved"):  # a CompiledOp's callback has none
        ops.parse("BAD", (ops.FLAGS_OPERAND,))
    with pytest.raises(TypeError, match="kernel's parameters must be the operands in declaration order"):
        ops.Op("BAD", kernels.PREVIEW.kernel, (("Hc", ("nv + 1", "nv")), ("preview", ("nv",)),
                                               ("factor", ("nv", "nv")), ("nv", None)))  # factor and preview swapped
    with pytest.raises(TypeError, match="operand names repeat"):
        ops.Op("BAD", None, (("n", None), ("n", None)))


def test_compiled_ops_use_the_same_declaration_format():
    from numba import njit

    @njit(nogil=True)
    def scale(x, factor, n, dt):
        for i in range(n):
            x[i] *= factor[0] * dt

    declaration = (("x", ("n",)), ("factor", (1,)), ("n", None))
    external = CompiledOp("SCALE", scale, declaration)
    assert external.spec == ops.Op("SCALE", scale, declaration).spec
    x = np.arange(3.0)
    program = TickProgram()
    program.add(external, x=x, factor=np.array([2.0]), n=3)
    program.run(0.5)
    np.testing.assert_array_equal(x, [0.0, 1.0, 2.0])


_NEW_KERNEL_FILE = '''
import numpy as np
from numba import njit

from . import prepare_cache
from .ops import STACK, Op

CACHE = prepare_cache()


@njit("void(float64[:], float64[:], float64[:], float64, float64[:])", cache=CACHE, nogil=True)
def centering_rows(q, middle, settings, dt, target):
    for i in range(len(q)):
        target[i] = settings[0] / dt * (middle[i] - q[i])


@njit(inline="always")
def _centering(q, middle, settings, stack, start, dim, nv, rows, dt):
    centering_rows(q, middle, settings, dt, stack[nv, start:start + dim])


CENTERING = Op("CENTERING", _centering, (
    ("q", ("dim",)), ("middle", ("dim",)), ("settings", (1,)), STACK, ("start", None), ("dim", None), ("nv", None),
    ("rows", None)), checks=("0 <= start", "start + dim <= rows"))
'''


@pytest.mark.slow  # compiles a copy of every kernel (~25 s)
def test_a_new_op_is_its_kernel_file_alone(tmp_path):
    """A copy of the kernels package plus one file declaring an op -- no opcode, no edit of
    __init__.py, ops.py or tick.py -- runs that op in the generated interpreter."""
    package = tmp_path / "kernels_copy"
    shutil.copytree(Path(kernels.__file__).parent, package, ignore=shutil.ignore_patterns("__pycache__"))
    (package / "centering.py").write_text(_NEW_KERNEL_FILE)
    code = textwrap.dedent("""
        import numpy as np
        import kernels_copy
        import kernels_copy.ops
        from wbc.runtime import program

        program.kernels, program.Op = kernels_copy, kernels_copy.ops.Op  # the program on the copy
        tick = program.TickProgram()
        stack = np.zeros((3, 4))
        tick.add(kernels_copy.CENTERING, q=np.array([1.0, 2.0]), middle=np.zeros(2), settings=np.array([0.5]),
                 stack=stack, start=1, dim=2, nv=2, rows=4)
        tick.run(0.1)
        print(stack[2].tolist())
    """)
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=900,
                            cwd=tmp_path,
                            env={**child_environment(tmp_path), "NUMBA_CACHE_DIR": str(tmp_path / "cache")})
    assert result.returncode == 0, result.stderr
    assert result.stdout.split("\n")[-2] == str([0.0, 0.5 / 0.1 * -1.0, 0.5 / 0.1 * -2.0, 0.0])


def _kinematics_rows(controller) -> int:
    callback = kernels.callback(kernels.FORWARD_KINEMATICS)
    return sum(row[:2] == [ops.OP_BUILTIN, callback] for row in controller._program._rows)


def test_the_kinematics_are_computed_once_per_tick_when_python_items_read_them():
    """A Python item (here a LinearConstraint holding the base's x velocity at 0, which the posture
    task leaves at 0 anyway) makes Kinematics.update compute the kinematics before the program: the
    program then has no forward-kinematics op of its own (it had one, computing them a second time
    every tick); without Python items it keeps it."""
    import wbc

    robot = wbc.load_robot("youbot")
    q = robot.neutral()
    posture = wbc.PostureTask(cost=1.0, target=q)
    compiled = wbc.Controller(robot, [posture], [wbc.JointVelocityLimits()])
    still = np.eye(1, robot.nv)  # v_x of the base = 0
    guarded = wbc.Controller(robot, [posture], [wbc.JointVelocityLimits(), wbc.LinearConstraint(still)])
    assert _kinematics_rows(compiled) == 1
    assert _kinematics_rows(guarded) == 0
    target = q.copy()
    target[-2] += 0.3  # a posture error, so the command depends on this tick's Jacobians
    posture.set_target(target)
    bent = q.copy()
    bent[-3] += 0.4
    for configuration in (q, bent):  # fresh kinematics every tick: the same command as the compiled stack
        np.testing.assert_allclose(guarded.step(configuration), compiled.step(configuration), atol=1e-9)


_OP_MODULE = '''
from numba import njit

from wbc.runtime.compiled_op import CompiledOp


@njit(nogil=True)
def scale(x, n, dt):
    for i in range(n):
        x[i] *= FACTOR * dt


SCALE = CompiledOp("SCALE", scale, (("x", ("n",)), ("n", None)))
'''

_RUN_OP = '''
import sys

import numpy as np

import scaled_op
from wbc.runtime.program import TickProgram

x = np.ones(3)
program = TickProgram()
program.add(scaled_op.SCALE, x=x, n=3)
program.run(0.5)
print(x[0], scaled_op.SCALE._callback.cache_hits)
'''


def _run_op(tmp_path, factor: float) -> tuple[float, int]:
    """Run ``_OP_MODULE`` (its kernel multiplying by ``factor * dt``) in a fresh process: (x[0] after
    one run from 1, the cache hits of the op's callback)."""
    (tmp_path / "scaled_op.py").write_text(_OP_MODULE.replace("FACTOR", repr(factor)))
    script = tmp_path / "run_op.py"
    script.write_text(_RUN_OP)
    env = {**child_environment(tmp_path), "NUMBA_CACHE_DIR": str(tmp_path / "cache")}
    out = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, env=env,
                         check=True).stdout.split()
    return float(out[0]), int(out[1])


@pytest.mark.slow  # three fresh processes (~4 s each)
def test_a_compiled_op_of_a_module_is_cached_and_recompiled_when_its_folder_changes(tmp_path):
    """The callback of a module-level kernel is compiled by the first process, loaded from numba's
    cache by the next, and compiled again -- not loaded stale -- after the kernel's file changes."""
    assert _run_op(tmp_path, 2.0) == (1.0, 0)  # 1 * 2 * 0.5, compiled
    assert _run_op(tmp_path, 2.0) == (1.0, 1)  # loaded from the cache
    value, hits = _run_op(tmp_path, 3.0)  # the kernel's file edited
    assert (value, hits) == (1.5, 0)
    generated = list((tmp_path / "cache").rglob("wbc_compiled_op_SCALE_*.py"))
    assert len(generated) == 1  # the stale source was deleted


def test_a_compiled_op_of_a_local_function_is_compiled_in_memory():
    from numba import njit

    @njit(nogil=True)
    def add_dt(x, n, dt):
        for i in range(n):
            x[i] += dt

    op = CompiledOp("ADD_DT", add_dt, (("x", ("n",)), ("n", None)))
    assert not hasattr(op._module(), "__file__")  # no file: nothing cached for it
    x = np.zeros(2)
    program = TickProgram()
    program.add(op, x=x, n=2)
    program.run(0.25)
    np.testing.assert_array_equal(x, [0.25, 0.25])
