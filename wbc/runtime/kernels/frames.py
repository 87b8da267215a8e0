"""SO(3), pose validation, frame Jacobians and the rows of FrameTask / PositionTask.

Conventions: as in :mod:`wbc.model.robot` -- world-aligned axes, twists (linear; angular),
rotation matrices row-major 3x3; layouts: the ``FRAME_*``, ``POSITION_*`` and ``POSE_*``
constants of :mod:`wbc.runtime.kernels`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from . import (
    FRAME_DATA,
    FRAME_FEEDFORWARD,
    FRAME_GAIN,
    FRAME_HAS_TARGET,
    FRAME_LOCAL,
    FRAME_LOCAL_ROTATION,
    FRAME_MAX_ANGULAR_SPEED,
    FRAME_MAX_SPEED,
    FRAME_ORIGIN,
    FRAME_RELATIVE,
    FRAME_SETTINGS,
    FRAME_TARGET_POSITION,
    FRAME_TARGET_ROTATION,
    FRAME_WEIGHTS,
    POSE_LAST_ROW,
    POSE_NOT_FINITE,
    POSE_NOT_ROTATION,
    POSE_OK,
    POSE_SHAPE,
    POSITION_FEEDFORWARD,
    POSITION_GAIN,
    POSITION_MAX_SPEED,
    POSITION_SETTINGS,
    POSITION_TARGET,
    POSITION_WEIGHTS,
    ROTATION_TOLERANCE,
    prepare_cache,
)
from ._lazy import ENTRY, declared
from .ops import STACK, Op

CACHE = prepare_cache()  # before the first @njit below compiles; False: no writable cache (see wbc.runtime.kernels)

# -------------------------------------------------------------------- SO(3)


@declared("void(float64[:], float64[:])", cache=CACHE, nogil=True)
def log3(R: np.ndarray, out: np.ndarray) -> None:
    """``out = log(R)``: the rotation vector (axis * angle, angle in [0, pi]) of the rotation
    ``R`` given row-major as 9 numbers.

    ``angle = atan2(|w|, (tr R - 1) / 2)`` with ``w = vee(R - R^T) / 2 = sin(angle) axis`` is
    accurate over the whole range. The axis is ``w / sin(angle)`` up to 90 deg; beyond, where
    ``w`` loses relative accuracy (it vanishes at 180 deg), it comes from the symmetric part
    ``(R + R^T) / 2 - cos(angle) I = (1 - cos(angle)) axis axis^T`` (its column with the
    largest diagonal), signed like ``w``.
    """
    wx = 0.5 * (R[7] - R[5])
    wy = 0.5 * (R[2] - R[6])
    wz = 0.5 * (R[3] - R[1])
    cosine = 0.5 * (R[0] + R[4] + R[8] - 1.0)
    sine = math.sqrt(wx * wx + wy * wy + wz * wz)
    angle = math.atan2(sine, cosine)
    if cosine >= 0.0:
        # angle / sin(angle) -> 1 + angle^2 / 6 as the angle vanishes (no 0 / 0)
        scale = angle / sine if sine > 1e-8 else 1.0 + angle * angle / 6.0
        out[0], out[1], out[2] = scale * wx, scale * wy, scale * wz
        return
    i = 0
    if R[4] > R[4 * i]:
        i = 1
    if R[8] > R[4 * i]:
        i = 2
    ax = 0.5 * (R[3 * i] + R[i]) - (cosine if i == 0 else 0.0)
    ay = 0.5 * (R[3 * i + 1] + R[3 + i]) - (cosine if i == 1 else 0.0)
    az = 0.5 * (R[3 * i + 2] + R[6 + i]) - (cosine if i == 2 else 0.0)
    norm = math.sqrt(ax * ax + ay * ay + az * az)
    if ax * wx + ay * wy + az * wz < 0.0:
        norm = -norm
    scale = angle / norm
    out[0], out[1], out[2] = scale * ax, scale * ay, scale * az



# ------------------------------------------------------------- validation


@declared("int64(float64[:, :], float64)", cache=CACHE, nogil=True)
def pose_defect(pose: np.ndarray, tolerance: float) -> int:
    """What is wrong with the 4x4 homogeneous transform ``pose``: POSE_OK, POSE_NOT_FINITE,
    POSE_LAST_ROW (not [0, 0, 0, 1] within 1e-12) or POSE_NOT_ROTATION
    (``|R^T R - I|_max`` or ``|det R - 1|`` above ``tolerance``)."""
    for a in range(4):
        for b in range(4):
            if not math.isfinite(pose[a, b]):
                return POSE_NOT_FINITE
    for b in range(4):
        if abs(pose[3, b] - (1.0 if b == 3 else 0.0)) > 1e-12:
            return POSE_LAST_ROW
    for a in range(3):
        for b in range(3):
            gram = pose[0, a] * pose[0, b] + pose[1, a] * pose[1, b] + pose[2, a] * pose[2, b]
            if abs(gram - (1.0 if a == b else 0.0)) > tolerance:
                return POSE_NOT_ROTATION
    determinant = (pose[0, 0] * (pose[1, 1] * pose[2, 2] - pose[1, 2] * pose[2, 1])
                   - pose[0, 1] * (pose[1, 0] * pose[2, 2] - pose[1, 2] * pose[2, 0])
                   + pose[0, 2] * (pose[1, 0] * pose[2, 1] - pose[1, 1] * pose[2, 0]))
    if abs(determinant - 1.0) > tolerance:
        return POSE_NOT_ROTATION
    return POSE_OK


# ------------------------------------------------------------------- tasks

@declared("void(float64[:, :], float64[:, :], float64[:], float64[:], float64[:], float64[:, :], float64[:])",
          cache=CACHE, nogil=True)
def frame_jacobian(joint_jacobians: np.ndarray, joint_rotation: np.ndarray, joint_translation: np.ndarray,
                   local: np.ndarray, support: np.ndarray, jacobian: np.ndarray, origin: np.ndarray) -> None:
    """World-aligned Jacobian (6 x nv) at the origin ``p = R_i p_f + p_i`` of a frame placed at
    ``local`` (rotation row-major, then translation) in its parent joint ``(R_i, p_i)``; the
    origin goes to ``origin``. ``joint_jacobians`` (6 x nv) holds every joint's columns as
    spatial velocities at the world origin (Pinocchio's ``data.J``); at the frame origin,
    world-aligned, a column is ``(v + w x p; w)``, kept where ``support`` is 1 (the joints
    between the root and the frame), zero elsewhere."""
    Ri, pf = joint_rotation, local[9:12]
    px = Ri[0, 0] * pf[0] + Ri[0, 1] * pf[1] + Ri[0, 2] * pf[2] + joint_translation[0]
    py = Ri[1, 0] * pf[0] + Ri[1, 1] * pf[1] + Ri[1, 2] * pf[2] + joint_translation[1]
    pz = Ri[2, 0] * pf[0] + Ri[2, 1] * pf[1] + Ri[2, 2] * pf[2] + joint_translation[2]
    origin[0], origin[1], origin[2] = px, py, pz
    for k in range(joint_jacobians.shape[1]):
        if support[k] == 0.0:
            for a in range(6):
                jacobian[a, k] = 0.0
            continue
        wx, wy, wz = joint_jacobians[3, k], joint_jacobians[4, k], joint_jacobians[5, k]
        jacobian[0, k] = joint_jacobians[0, k] + wy * pz - wz * py
        jacobian[1, k] = joint_jacobians[1, k] + wz * px - wx * pz
        jacobian[2, k] = joint_jacobians[2, k] + wx * py - wy * px
        jacobian[3, k], jacobian[4, k], jacobian[5, k] = wx, wy, wz


# the setter holds the GIL: releasing it would cost ~0.05 us of a ~0.2 us call
@declared("int64(float64[:, :], float64[:])", cache=CACHE, **ENTRY)
def set_frame_pose(pose: np.ndarray, settings: np.ndarray) -> int:
    """FrameTask target: R* and p* from ``pose`` and a zero feed-forward twist into the settings
    vector (layout ``FRAME_*``; its ``FRAME_HAS_TARGET`` flag set) -- when ``pose`` is 4 x 4 (else
    POSE_SHAPE) and passes :func:`pose_defect` with the library's ``ROTATION_TOLERANCE``; returns
    its verdict (nothing written unless POSE_OK): the control loop's ``set_target(pose)`` is one
    call. (A feed-forward twist is written by the caller after it: ``FrameTask.set_target``.)"""
    if pose.shape[0] != 4 or pose.shape[1] != 4:
        return POSE_SHAPE
    defect = pose_defect(pose, ROTATION_TOLERANCE)
    if defect == POSE_OK:
        rotation, position, feedforward = settings[FRAME_TARGET_ROTATION], settings[FRAME_TARGET_POSITION], \
            settings[FRAME_FEEDFORWARD]
        for a in range(3):
            for b in range(3):
                rotation[3 * a + b] = pose[a, b]
            position[a] = pose[a, 3]
        for a in range(6):
            feedforward[a] = 0.0
        settings[FRAME_HAS_TARGET] = 1.0
    return defect


# inlined by LLVM (forceinline), not by numba's IR inlining: compiled once, not copied into each caller's IR
# (a first start compiles ~0.1-0.2 s sooner, benchmarks/README.md section 8; the ticks are alike)
@njit(forceinline=True, no_cpython_wrapper=True)
def _frame_task_rows_of(joint_jacobians: np.ndarray, joint_rotation: np.ndarray, joint_translation: np.ndarray,
                        support: np.ndarray, settings: np.ndarray, frame: np.ndarray, dt: float, error: np.ndarray,
                        jacobian: np.ndarray, target: np.ndarray, weighted_feedforward: np.ndarray) -> None:
    """Rows of :class:`~wbc.FrameTask` from Pinocchio's joint placement and joint Jacobians.

    Frame placement ``R = R_i R_f``, ``p = R_i p_f + p_i`` (``R_i, p_i``: parent joint;
    ``R_f, p_f``: frame in the joint); the Jacobian is :func:`frame_jacobian`'s. Writes
    ``error = (p* - p, log3(R* R^T))``,
    ``jacobian = W J`` and ``target = W sat(gain/dt * error) + W xi*``, its feed-forward part
    ``W xi*`` (with this tick's W) into ``weighted_feedforward`` (layouts: the ``FRAME_*``
    settings and the frame data of this module).
    """
    Rt, pt = settings[FRAME_TARGET_ROTATION], settings[FRAME_TARGET_POSITION]
    weights, feedforward = settings[FRAME_WEIGHTS], settings[FRAME_FEEDFORWARD]
    gain = settings[FRAME_GAIN] / dt
    max_speed, max_angular_speed = settings[FRAME_MAX_SPEED], settings[FRAME_MAX_ANGULAR_SPEED]
    Rf, relative, origin = frame[FRAME_LOCAL_ROTATION], frame[FRAME_RELATIVE], frame[FRAME_ORIGIN]
    Ri = joint_rotation
    frame_jacobian(joint_jacobians, joint_rotation, joint_translation, frame[FRAME_LOCAL], support, jacobian, origin)
    for a in range(6):
        for k in range(jacobian.shape[1]):
            jacobian[a, k] *= weights[a]
    error[0], error[1], error[2] = pt[0] - origin[0], pt[1] - origin[1], pt[2] - origin[2]
    # orientation error log3(R* R^T) with R = R_i R_f: (R* R^T)_ab = sum_c R*_ac R_bc
    for b in range(3):
        r0 = Ri[b, 0] * Rf[0] + Ri[b, 1] * Rf[3] + Ri[b, 2] * Rf[6]  # row b of R
        r1 = Ri[b, 0] * Rf[1] + Ri[b, 1] * Rf[4] + Ri[b, 2] * Rf[7]
        r2 = Ri[b, 0] * Rf[2] + Ri[b, 1] * Rf[5] + Ri[b, 2] * Rf[8]
        for a in range(3):
            relative[3 * a + b] = Rt[3 * a] * r0 + Rt[3 * a + 1] * r1 + Rt[3 * a + 2] * r2
    log3(relative, error[3:])
    # feedback velocity gain/dt * e, each part bounded in norm (direction kept), then weighted
    for part in (0, 3):
        limit = max_speed if part == 0 else max_angular_speed
        norm = math.sqrt(error[part] ** 2 + error[part + 1] ** 2 + error[part + 2] ** 2) * gain
        scale = gain if norm <= limit else limit / norm * gain
        for a in range(part, part + 3):
            weighted_feedforward[a] = weights[a] * feedforward[a]
            target[a] = weights[a] * (scale * error[a]) + weighted_feedforward[a]


@declared("void(float64[:, :], float64[:, :], float64[:], float64[:], float64[:], float64[:], float64, float64[:], "
          "float64[:, :], float64[:], float64[:])", cache=CACHE, nogil=True)
def frame_task_rows(joint_jacobians: np.ndarray, joint_rotation: np.ndarray, joint_translation: np.ndarray,
                    support: np.ndarray, settings: np.ndarray, frame: np.ndarray, dt: float, error: np.ndarray,
                    jacobian: np.ndarray, target: np.ndarray, weighted_feedforward: np.ndarray) -> None:
    """:func:`_frame_task_rows_of` on arrays of any strides (called from Python)."""
    _frame_task_rows_of(joint_jacobians, joint_rotation, joint_translation, support, settings, frame, dt, error,
                        jacobian, target, weighted_feedforward)


@declared("void(float64[:, :], float64[:, :], float64[:], float64[:], float64[:], float64[:], float64, float64[:], "
          "float64[:, :], float64[:], float64[:, :], float64[:])", cache=CACHE, nogil=True)
def position_task_rows(joint_jacobians: np.ndarray, joint_rotation: np.ndarray, joint_translation: np.ndarray,
                       support: np.ndarray, settings: np.ndarray, frame: np.ndarray, dt: float, error: np.ndarray,
                       jacobian: np.ndarray, target: np.ndarray, frame_jacobian_scratch: np.ndarray,
                       weighted_feedforward: np.ndarray) -> None:
    """Rows of :class:`~wbc.PositionTask`: ``error = p* - p``, ``jacobian = W J_lin``,
    ``target = W (sat(gain/dt * error) + pdot*)``, and its feed-forward part ``W pdot*`` into
    ``weighted_feedforward`` (layouts: ``POSITION_*`` settings, frame data)."""
    origin = frame[FRAME_ORIGIN]
    frame_jacobian(joint_jacobians, joint_rotation, joint_translation, frame[FRAME_LOCAL], support,
                   frame_jacobian_scratch, origin)
    goal, weights, feedforward = settings[POSITION_TARGET], settings[POSITION_WEIGHTS], settings[POSITION_FEEDFORWARD]
    gain, max_speed = settings[POSITION_GAIN] / dt, settings[POSITION_MAX_SPEED]
    norm = 0.0
    for a in range(3):
        error[a] = goal[a] - origin[a]
        norm += error[a] * error[a]
    norm = math.sqrt(norm) * gain
    scale = gain if norm <= max_speed else max_speed / norm * gain
    for a in range(3):
        for k in range(jacobian.shape[1]):
            jacobian[a, k] = weights[a] * frame_jacobian_scratch[a, k]
        weighted_feedforward[a] = weights[a] * feedforward[a]
        target[a] = weights[a] * (scale * error[a]) + weighted_feedforward[a]


# ------------------------------------------------------- tick-program ops


@njit(inline="always")
def _frame_task(joint_jacobians_t: np.ndarray, rotation_t: np.ndarray, translation: np.ndarray, support: np.ndarray,
                settings: np.ndarray, frame: np.ndarray, error: np.ndarray, stack: np.ndarray, start: int, nv: int,
                rows: int, feedforward: np.ndarray, dt: float) -> None:
    # inlined (not a call of the declared kernel): an op's call passing 11 arrays cost ~0.03 us
    _frame_task_rows_of(joint_jacobians_t.T, rotation_t.T, translation, support, settings, frame, dt, error,
                        stack[:nv, start:start + 6].T, stack[nv, start:start + 6], feedforward)


#: FrameTask's rows into columns start:start + 6 of the stack (joint Jacobians and joint rotation
#: transposed: Pinocchio's column-major buffers); its weighted feed-forward out
FRAME_TASK = Op("FRAME_TASK", _frame_task, (
    ("joint_jacobians_t", ("nv", 6)), ("rotation_t", (3, 3)), ("translation", (3,)), ("support", ("nv",)),
    ("settings", (FRAME_SETTINGS,)), ("frame", (FRAME_DATA,)), ("error", (6,)), STACK,
    ("start", None), ("nv", None), ("rows", None), ("feedforward", (6,))), checks=("0 <= start", "start + 6 <= rows"))


@njit(inline="always")
def _position_task(joint_jacobians_t: np.ndarray, rotation_t: np.ndarray, translation: np.ndarray,
                   support: np.ndarray, settings: np.ndarray, frame: np.ndarray, error: np.ndarray, stack: np.ndarray,
                   start: int, nv: int, rows: int, jacobian: np.ndarray, feedforward: np.ndarray, dt: float) -> None:
    position_task_rows(joint_jacobians_t.T, rotation_t.T, translation, support, settings, frame, dt, error,
                       stack[:nv, start:start + 3].T, stack[nv, start:start + 3], jacobian, feedforward)


#: PositionTask's rows into columns start:start + 3 of the stack; its weighted feed-forward out
POSITION_TASK = Op("POSITION_TASK", _position_task, (
    ("joint_jacobians_t", ("nv", 6)), ("rotation_t", (3, 3)), ("translation", (3,)), ("support", ("nv",)),
    ("settings", (POSITION_SETTINGS,)), ("frame", (FRAME_DATA,)), ("error", (3,)), STACK,
    ("start", None), ("nv", None), ("rows", None), ("jacobian", (6, "nv")), ("feedforward", (3,))),
    checks=("0 <= start", "start + 3 <= rows"))
