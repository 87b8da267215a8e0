"""The tick program: one compiled call runs every compiled part of a tick.

Its operands are registered once (wbc.runtime.program.TickProgram) as C-contiguous float64 arrays
and handed over by address: entering a numba function costs ~0.1 us per array argument,
a dozen arrays would cost more than the arithmetic. Each program row is
[opcode, operands...] (array indices and sizes); the opcodes are the ``OP_*`` constants
of :mod:`wbc.runtime.kernels`, the layouts those of the kernels of the topic modules.
"""

from __future__ import annotations

import numpy as np
from llvmlite import ir
from numba import carray, njit, types
from numba.extending import intrinsic

from . import (
    CHAIN_COLUMNS,
    DAQP_CONTROL_DEFECT,
    DAQP_CONTROL_EXITFLAG,
    DAQP_CONTROL_SIZE,
    DAQP_PROBLEM_WORDS,
    DAQP_RESULT_WORDS,
    DAQP_SKIPPED,
    DAQP_WORKSPACE_WORDS,
    FRAME_DATA,
    FRAME_SETTINGS,
    OP_BAND,
    OP_DAQP_SOLVE,
    OP_EXTERNAL,
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
    prepare_cache,
)
from .assembly import (
    has_nan,
    has_non_finite,
    lift_qp,
    lifted_stationarity,
    lm_curvature,
    lm_damping_level,
    lm_damping_rows,
    merge_bounds,
    normal_equations,
    normalise_cost,
    preview_solve,
)
from .chain import forward_kinematics
from .frames import frame_task_rows, position_task_rows
from .hierarchy import band_rows, hierarchy_preview, level_constraints, normalise_level
from .joints import heading_rows, position_limit_bounds, posture_rows, steering_row
from .manipulability import barrier_row
from .native_qp import daqp_solve

CACHE = prepare_cache()  # before the first @njit below compiles; False: no writable cache (see wbc.runtime.kernels)

@intrinsic
def _as_pointer(typingctx, address):
    """The float64 pointer at integer ``address`` (registered arrays only: see TickProgram)."""
    signature = types.CPointer(types.float64)(types.int64)

    def codegen(context, builder, signature, args):
        return builder.inttoptr(args[0], context.get_value_type(types.CPointer(types.float64)))

    return signature, codegen


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


@njit(inline="always")
def _vector(addresses: np.ndarray, index: int, size: int) -> np.ndarray:
    return carray(_as_pointer(addresses[index]), (size,))


@njit(inline="always")
def _matrix(addresses: np.ndarray, index: int, rows: int, columns: int) -> np.ndarray:
    return carray(_as_pointer(addresses[index]), (rows, columns))


@njit("boolean(int64[::1], float64)", cache=CACHE, nogil=True)
def run_program(packed: np.ndarray, dt: float) -> bool:
    """Run the rows of a program in order; returns True when a HAS_NAN row found a NaN.

    ``packed`` = [rows, width, the rows (rows x width, row-major), the operand addresses]
    (one array: each argument of a native call costs ~0.1 us to pass).

    Rows (array operands by index into ``addresses``):

    * FRAME_TASK: J^T (nv x 6), R^T (3 x 3), p (3), support (nv), settings, frame data, error (6),
      stack A^T ((nv + 1) x rows), first row, nv, rows
    * POSTURE: q (dim), reference (dim), W (dim), settings (gain), error (dim), stack, first row, dim, nv, rows
    * POSITION_LIMITS: q (k), lower limit, upper limit, gain (1), lower out, upper out, k
    * NORMAL_EQUATIONS: stack, nv, rows, first row, last row, reset (0/1), Hc ((nv + 1) x nv)
    * PREVIEW: Hc, factor scratch (nv x nv), preview (nv), nv
    * STEERING: preview (nv), q (nq), x, y, heading, parameters (3), error (1), stack, first row,
      nv, rows, nq
    * MERGE_BOUNDS: bounds ((2 count) x nv: upper, lower of each bounded constraint), count, n_hard, nv, ub, lb
    * HAS_NAN: data, size, infinite (1: infinite entries count too)
    * LM_TASK: stack, the task's weighted feed-forward (dim), mu (1), lm_damping (1), first row, dim, nv,
      rows, reset (1: mu starts from 0); adds lm_damping times the task's lm_curvature to mu
    * LM_DAMPING_ROWS: stack, mu (1), (damping, damping floor), nv, rows, first damping row
    * LM_DAMPING_LEVEL: mu (1), the level's (damping, damping floor), Hc ((nv + 1) x nv), nv
    * NORMALISE_COST: Hc ((nv + 1) x nv), (damping, damping floor), nv
    * HEADING_ROWS: cos part (rows x 2), sin part, q (nq), heading index, G (rows x nv), rows, nq, nv, x, y
    * POSITION_TASK: J^T, R^T, p, support (nv), settings, frame data, error (3), stack, first row, nv,
      rows, Jacobian scratch (6 x nv), weighted feed-forward out (3)
    * MANIPULABILITY_BARRIER: J^T, R^T, p, frame in joint (12), support (nv), ancestor (nv x nv),
      Jacobian scratch (6 x nv), origin scratch (3), gradient (nv), G row (nv), h (1),
      settings (gain, min value), value out (1), first row, last row, nv
    * DAQP_SOLVE: DAQP problem, workspace, result (their words), control, QP data (size), x (n), n,
      size, addresses of daqp_update_ldp, daqp_solve, clock_gettime, clock id, steady mask;
      skipped (exit flag DAQP_SKIPPED) when a HAS_NAN row before it found a NaN, or a BAND row stopped
    * FORWARD_KINEMATICS: q (nq), chain (joints x CHAIN_COLUMNS), placements (joints x 12), joint
      Jacobians transposed (nv x 6), nq, joints, nv
    * EXTERNAL: address of a CompiledOp's C callback, then its operands (its own declaration)
    * LIFT: stack, diagonal (rows), source QP data, lifted QP data, (damping, floor), nv, stack rows,
      rows, k, p, e, source size, lifted size; a NaN met counts as a HAS_NAN row's
    * LIFT_CHECK: lifted QP data, x (nv + k), DAQP's multipliers, scratch (2 nv), the solve's
      control, nv, k, p, e, lifted size: after a successful solve, the defect becomes the larger
      of the answer's defect and its stationarity in v (:func:`lifted_stationarity`)
    * LEVEL_CONSTRAINTS: source QP data, target QP data, n, p, e, band rows, source size, target size
    * NORMALISE_LEVEL: Hc ((nv + 1) x nv), (damping, damping floor), nv
    * BAND: stack, first, last, first preview row, last preview row, the level's answer x (nv), lower,
      upper (nv), its DAQP control, (answer tolerance, relative band), target QP data (size), nv,
      rows, size, first band row, target rows; when the level's solve failed (exit flag < 1, or
      its answer's defect above the tolerance) nothing is written and every later DAQP_SOLVE
      row is skipped
    * HIERARCHY_PREVIEW: stack, level ranges (count), (damping, damping floor), preview (nv), nv, rows,
      count
    """
    rows, width = packed[0], packed[1]
    program = packed[2:2 + rows * width].reshape((rows, width))
    addresses = packed[2 + rows * width:]
    found_nan = False
    stopped = False  # a level of a hierarchy failed: the levels below it are not solved
    for r in range(rows):
        op = program[r]
        code = op[0]
        if code == OP_FRAME_TASK:
            nv, rows, start = op[10], op[11], op[9]
            stack_t = _matrix(addresses, op[8], nv + 1, rows)
            frame_task_rows(_matrix(addresses, op[1], nv, 6).T, _matrix(addresses, op[2], 3, 3).T,
                            _vector(addresses, op[3], 3), _vector(addresses, op[4], nv),
                            _vector(addresses, op[5], FRAME_SETTINGS), _vector(addresses, op[6], FRAME_DATA), dt,
                            _vector(addresses, op[7], 6), stack_t[:nv, start:start + 6].T, stack_t[nv, start:start + 6])
        elif code == OP_POSTURE:
            start, dim, nv, rows = op[7], op[8], op[9], op[10]
            stack_t = _matrix(addresses, op[6], nv + 1, rows)
            posture_rows(_vector(addresses, op[1], dim), _vector(addresses, op[2], dim),
                         _vector(addresses, op[3], dim), _vector(addresses, op[4], 1), dt,
                         _vector(addresses, op[5], dim), stack_t[nv, start:start + dim])
        elif code == OP_POSITION_LIMITS:
            k = op[7]
            position_limit_bounds(_vector(addresses, op[1], k), _vector(addresses, op[2], k),
                                  _vector(addresses, op[3], k), _vector(addresses, op[4], 1)[0], dt,
                                  _vector(addresses, op[5], k), _vector(addresses, op[6], k))
        elif code == OP_NORMAL_EQUATIONS:
            nv, rows = op[2], op[3]
            normal_equations(_matrix(addresses, op[1], nv + 1, rows), op[4], op[5], op[6] != 0,
                             _matrix(addresses, op[7], nv + 1, nv))
        elif code == OP_PREVIEW:
            nv = op[4]
            preview_solve(_matrix(addresses, op[1], nv + 1, nv), _matrix(addresses, op[2], nv, nv),
                          _vector(addresses, op[3], nv))
        elif code == OP_STEERING:
            nv, rows, start, nq = op[10], op[11], op[9], op[12]
            stack_t = _matrix(addresses, op[8], nv + 1, rows)
            steering_row(_vector(addresses, op[1], nv), _vector(addresses, op[2], nq), op[3], op[4], op[5],
                         _vector(addresses, op[6], 3), dt, _vector(addresses, op[7], 1), stack_t[:nv, start],
                         stack_t[nv, start:start + 1])
        elif code == OP_MERGE_BOUNDS:
            count, nv = op[2], op[4]
            merge_bounds(_matrix(addresses, op[1], 2 * count, nv), op[3], _vector(addresses, op[5], nv),
                         _vector(addresses, op[6], nv))
        elif code == OP_HAS_NAN:
            data = _vector(addresses, op[1], op[2])
            found_nan = found_nan or (has_non_finite(data) if op[3] else has_nan(data))
        elif code == OP_LM_TASK:
            start, dim, nv, rows = op[5], op[6], op[7], op[8]
            mu, lm = _vector(addresses, op[3], 1), _vector(addresses, op[4], 1)[0]
            if op[9]:
                mu[0] = 0.0
            if lm > 0.0:
                mu[0] += lm * lm_curvature(_matrix(addresses, op[1], nv + 1, rows), _vector(addresses, op[2], dim), dt,
                                           start, dim)
        elif code == OP_LM_DAMPING_ROWS:
            nv, rows, first = op[4], op[5], op[6]
            lm_damping_rows(_matrix(addresses, op[1], nv + 1, rows)[:nv, first:first + nv],
                            _vector(addresses, op[3], 2)[0], _vector(addresses, op[2], 1)[0])
        elif code == OP_LM_DAMPING_LEVEL:
            nv = op[4]
            lm_damping_level(_matrix(addresses, op[3], nv + 1, nv), _vector(addresses, op[2], 2)[0],
                             _vector(addresses, op[1], 1)[0])
        elif code == OP_NORMALISE_COST:
            nv = op[3]
            damping = _vector(addresses, op[2], 2)
            normalise_cost(_matrix(addresses, op[1], nv + 1, nv), damping[0], damping[1])
        elif code == OP_HEADING_ROWS:
            rows, nq, nv = op[6], op[7], op[8]
            heading_rows(_matrix(addresses, op[1], rows, 2), _matrix(addresses, op[2], rows, 2),
                         _vector(addresses, op[3], nq), op[4], _matrix(addresses, op[5], rows, nv), op[9], op[10])
        elif code == OP_POSITION_TASK:
            nv, rows, start = op[10], op[11], op[9]
            stack_t = _matrix(addresses, op[8], nv + 1, rows)
            position_task_rows(_matrix(addresses, op[1], nv, 6).T, _matrix(addresses, op[2], 3, 3).T,
                               _vector(addresses, op[3], 3), _vector(addresses, op[4], nv),
                               _vector(addresses, op[5], POSITION_SETTINGS), _vector(addresses, op[6], FRAME_DATA),
                               dt, _vector(addresses, op[7], 3), stack_t[:nv, start:start + 3].T,
                               stack_t[nv, start:start + 3], _matrix(addresses, op[12], 6, nv),
                               _vector(addresses, op[13], 3))
        elif code == OP_MANIPULABILITY_BARRIER:
            nv = op[16]
            barrier_row(_matrix(addresses, op[1], nv, 6).T, _matrix(addresses, op[2], 3, 3).T,
                        _vector(addresses, op[3], 3), _vector(addresses, op[4], 12), _vector(addresses, op[5], nv),
                        _matrix(addresses, op[6], nv, nv), _matrix(addresses, op[7], 6, nv),
                        _vector(addresses, op[8], 3), _vector(addresses, op[9], nv), _vector(addresses, op[10], nv),
                        _vector(addresses, op[11], 1), _vector(addresses, op[12], 2), _vector(addresses, op[13], 1),
                        op[14], op[15], dt)
        elif code == OP_LIFT:
            nv, rows = op[6], op[8]
            scaling = _vector(addresses, op[5], 2)
            found_nan = lift_qp(_matrix(addresses, op[1], nv + 1, op[7]), _vector(addresses, op[2], rows),
                                _vector(addresses, op[3], op[12]), _vector(addresses, op[4], op[13]), nv, op[9],
                                op[10], op[11], scaling[0], scaling[1]) or found_nan
        elif code == OP_LIFT_CHECK:
            nv, k, p, e = op[6], op[7], op[8], op[9]
            control = _vector(addresses, op[5], DAQP_CONTROL_SIZE)
            if control[DAQP_CONTROL_EXITFLAG] >= 1:
                stationarity = lifted_stationarity(
                    _vector(addresses, op[1], op[10]), _vector(addresses, op[2], nv + k),
                    _vector(addresses, op[3], nv + k + p + e + k), _vector(addresses, op[4], 2 * nv), nv, k, p,
                    e)
                control[DAQP_CONTROL_DEFECT] = max(control[DAQP_CONTROL_DEFECT], stationarity)
        elif code == OP_FORWARD_KINEMATICS:
            joints = op[6]
            forward_kinematics(_vector(addresses, op[1], op[5]), _matrix(addresses, op[2], joints, CHAIN_COLUMNS),
                               _matrix(addresses, op[3], joints, 12), _matrix(addresses, op[4], op[7], 6))
        elif code == OP_EXTERNAL:
            # the callback unpacks its operands, from position 2 of the row on
            _call_external(op[1], np.int64(addresses.ctypes.data), np.int64(op.ctypes.data) + np.int64(16), dt)
        elif code == OP_DAQP_SOLVE:
            control = _vector(addresses, op[4], DAQP_CONTROL_SIZE)
            if found_nan or stopped:
                control[DAQP_CONTROL_EXITFLAG] = DAQP_SKIPPED
            else:
                daqp_solve(_vector(addresses, op[1], DAQP_PROBLEM_WORDS),
                           _vector(addresses, op[2], DAQP_WORKSPACE_WORDS),
                           _vector(addresses, op[3], DAQP_RESULT_WORDS), control, _vector(addresses, op[5], op[8]),
                           _vector(addresses, op[6], op[7]), op[9], op[10], op[11], op[12], op[13])
        elif code == OP_LEVEL_CONSTRAINTS:
            level_constraints(_vector(addresses, op[1], op[7]), _vector(addresses, op[2], op[8]), op[3], op[4],
                              op[5], op[6])
        elif code == OP_NORMALISE_LEVEL:
            nv = op[3]
            scaling = _vector(addresses, op[2], 2)
            normalise_level(_matrix(addresses, op[1], nv + 1, nv), scaling[0], scaling[1])
        elif code == OP_BAND:
            nv, rows, size, row, target_rows = op[12], op[13], op[14], op[15], op[16]
            control = _vector(addresses, op[9], DAQP_CONTROL_SIZE)
            settings = _vector(addresses, op[10], 2)
            if (found_nan or stopped or control[DAQP_CONTROL_EXITFLAG] < 1
                    or not control[DAQP_CONTROL_DEFECT] <= settings[0]):
                stopped = True
            else:
                start = nv * nv + nv
                band_rows(_matrix(addresses, op[1], nv + 1, rows), op[2], op[3], op[4], op[5],
                          _vector(addresses, op[6], nv), _vector(addresses, op[7], nv), _vector(addresses, op[8], nv),
                          settings[1], _vector(addresses, op[11], size), start + row * nv,
                          start + target_rows * nv + nv + row)
        elif code == OP_HIERARCHY_PREVIEW:
            nv, rows, count = op[5], op[6], op[7]
            scaling = _vector(addresses, op[3], 2)
            hierarchy_preview(_matrix(addresses, op[1], nv + 1, rows), _vector(addresses, op[2], count), scaling[1],
                              _vector(addresses, op[4], nv))
    return found_nan
