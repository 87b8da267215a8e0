"""Compiled (numba) kernels of the control tick.

In CPython every numpy call on a small array costs 0.25-1 us, whatever it computes; the
QP of one youBot tick needs ~40 of them. The kernels below do the arithmetic of the
hottest tasks and constraints, and of the QP assembly, in one native call each (~0.2 us
to enter). Pinocchio still computes the kinematics: the kernels read its joint
placements and joint Jacobians in place (see :class:`wbc.kinematics.Kinematics`).

Each kernel has one explicit signature (float64 arrays of any memory layout), so all are
compiled when this module is imported -- never inside a control tick -- and cached on disk
(``cache=True``): only the first import after an install pays the compilation (~10 s);
later imports load the machine code (~0.3 s). They live in this one module on purpose:
numba invalidates a cached function when *its* source file changes, not when a callee in
another file does, so kernels that call each other share a file.

Conventions: as in :mod:`wbc.robot` -- world-aligned axes, twists (linear; angular),
rotation matrices row-major 3x3.
"""

from __future__ import annotations

import math

import numpy as np
from numba import carray, njit, types
from numba.extending import intrinsic

# -------------------------------------------------------------------- SO(3)


@njit("void(float64[:], float64[:])", cache=True, nogil=True)
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

#: results of :func:`pose_defect`
POSE_OK, POSE_NOT_FINITE, POSE_LAST_ROW, POSE_NOT_ROTATION = range(4)


@njit("int64(float64[:, :], float64)", cache=True, nogil=True)
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

@njit("void(float64[:, :], float64[:, :], float64[:], float64[:], float64[:], float64[:, :], float64[:])", cache=True,
      nogil=True)
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


#: layout of the FrameTask settings vector (owned by the task, shared by its controllers)
FRAME_TARGET_ROTATION = slice(0, 9)  # target orientation R* (row-major)
FRAME_TARGET_POSITION = slice(9, 12)  # target position p* [m]
FRAME_WEIGHTS = slice(12, 18)  # W = sqrt(cost), (linear; angular)
FRAME_WEIGHTED_FEEDFORWARD = slice(18, 24)  # W xi* (zero without feed-forward)
FRAME_GAIN, FRAME_MAX_SPEED, FRAME_MAX_ANGULAR_SPEED = 24, 25, 26  # gain in (0, 1], [m/s], [rad/s]
FRAME_SETTINGS = 27
#: layout of a frame's placement data (one vector per controller and frame, see frame_in_joint)
FRAME_LOCAL = slice(0, 12)  # frame placement in its parent joint: rotation (row-major), translation [m]
FRAME_DATA = 24  # 12:24 is the kernels' scratch (R* R^T, then the frame origin)


@njit("void(float64[:, :], float64[:], float64[:])", cache=True, nogil=True)
def set_frame_target(pose: np.ndarray, twist: np.ndarray, settings: np.ndarray) -> None:
    """FrameTask target: R* and p* from the (validated) ``pose``, ``W twist`` (``twist`` of
    length 6, or empty for none) into the settings vector (layout ``FRAME_*``)."""
    for a in range(3):
        for b in range(3):
            settings[3 * a + b] = pose[a, b]
        settings[9 + a] = pose[a, 3]
    for a in range(6):
        settings[18 + a] = settings[12 + a] * twist[a] if len(twist) == 6 else 0.0


@njit("void(float64[:, :], float64[:, :], float64[:], float64[:], float64[:], float64[:], float64, float64[:], "
      "float64[:, :], float64[:])", cache=True, nogil=True)
def frame_task_rows(joint_jacobians: np.ndarray, joint_rotation: np.ndarray, joint_translation: np.ndarray,
                    support: np.ndarray, settings: np.ndarray, frame: np.ndarray, dt: float, error: np.ndarray,
                    jacobian: np.ndarray, target: np.ndarray) -> None:
    """Rows of :class:`~wbc.FrameTask` from Pinocchio's joint placement and joint Jacobians.

    Frame placement ``R = R_i R_f``, ``p = R_i p_f + p_i`` (``R_i, p_i``: parent joint;
    ``R_f, p_f``: frame in the joint); the Jacobian is :func:`frame_jacobian`'s. Writes
    ``error = (p* - p, log3(R* R^T))``,
    ``jacobian = W J`` and ``target = W sat(gain/dt * error) + W xi*`` (layouts: the
    ``FRAME_*`` settings and the frame data of this module).
    """
    Rt, pt = settings[0:9], settings[9:12]
    weights, feedforward = settings[12:18], settings[18:24]
    gain, max_speed, max_angular_speed = settings[24] / dt, settings[25], settings[26]
    Rf, relative, origin = frame[0:9], frame[12:21], frame[21:24]
    Ri = joint_rotation
    frame_jacobian(joint_jacobians, joint_rotation, joint_translation, frame[0:12], support, jacobian, origin)
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
            target[a] = weights[a] * (scale * error[a]) + feedforward[a]


#: layout of the PositionTask settings vector (owned by the task, shared by its controllers)
POSITION_TARGET = slice(0, 3)  # p* [m]
POSITION_WEIGHTS = slice(3, 6)  # W = sqrt(cost)
POSITION_FEEDFORWARD = slice(6, 9)  # pdot* [m/s]
POSITION_GAIN, POSITION_MAX_SPEED = 9, 10  # gain in (0, 1], [m/s]
POSITION_SETTINGS = 11


@njit("void(float64[:, :], float64[:, :], float64[:], float64[:], float64[:], float64[:], float64, float64[:], "
      "float64[:, :], float64[:], float64[:, :])", cache=True, nogil=True)
def position_task_rows(joint_jacobians: np.ndarray, joint_rotation: np.ndarray, joint_translation: np.ndarray,
                       support: np.ndarray, settings: np.ndarray, frame: np.ndarray, dt: float, error: np.ndarray,
                       jacobian: np.ndarray, target: np.ndarray, frame_jacobian_scratch: np.ndarray) -> None:
    """Rows of :class:`~wbc.PositionTask`: ``error = p* - p``, ``jacobian = W J_lin``,
    ``target = W (sat(gain/dt * error) + pdot*)`` (layouts: ``POSITION_*`` settings, frame data)."""
    origin = frame[21:24]
    frame_jacobian(joint_jacobians, joint_rotation, joint_translation, frame[0:12], support,
                   frame_jacobian_scratch, origin)
    weights, feedforward = settings[3:6], settings[6:9]
    gain, max_speed = settings[9] / dt, settings[10]
    norm = 0.0
    for a in range(3):
        error[a] = settings[a] - origin[a]
        norm += error[a] * error[a]
    norm = math.sqrt(norm) * gain
    scale = gain if norm <= max_speed else max_speed / norm * gain
    for a in range(3):
        for k in range(jacobian.shape[1]):
            jacobian[a, k] = weights[a] * frame_jacobian_scratch[a, k]
        target[a] = weights[a] * (scale * error[a] + feedforward[a])


@njit("void(float64[:], float64[:], float64[:], float64[:], float64, float64[:], float64[:])", cache=True,
      nogil=True)
def posture_rows(q: np.ndarray, reference: np.ndarray, weights: np.ndarray, settings: np.ndarray, dt: float,
                 error: np.ndarray, target: np.ndarray) -> None:
    """:class:`~wbc.PostureTask` on a block of 1-DOF joints: ``e = q* - q``, ``target = W gain/dt e``
    (``settings = (gain,)``)."""
    scale = settings[0] / dt
    for i in range(len(q)):
        error[i] = reference[i] - q[i]
        target[i] = weights[i] * scale * error[i]


@njit("void(float64[:], float64[:], int64, int64, int64, float64[:], float64, float64[:], float64[:], float64[:])",
      cache=True, nogil=True)
def steering_row(preview: np.ndarray, q: np.ndarray, x: int, y: int, heading: int, parameters: np.ndarray,
                 dt: float, error: np.ndarray, jacobian: np.ndarray, target: np.ndarray) -> None:
    """Row of :class:`~wbc.SteeringTask` from the holonomic ``preview`` velocity:
    ``delta = wrap_[-pi/2, pi/2)(atan2(ydot, xdot) - heading)``, weight
    ``sqrt(cost) min(1, speed / speed_scale)``; ``parameters = (sqrt(cost), gain, speed_scale)``."""
    xdot, ydot = preview[x], preview[y]
    speed = math.sqrt(xdot * xdot + ydot * ydot)
    delta = 0.0
    if speed > 0.0:
        delta = math.atan2(ydot, xdot) - q[heading]
        delta = (delta + math.pi / 2) % math.pi - math.pi / 2  # drive forward or backward
    weight = parameters[0] * min(1.0, speed / parameters[2])
    error[0] = delta
    for k in range(len(jacobian)):
        jacobian[k] = 0.0
    jacobian[heading] = weight
    target[0] = weight * parameters[1] * delta / dt


# ------------------------------------------------------------- constraints


@njit("void(float64[:], float64[:], float64[:], float64, float64, float64[:], float64[:])", cache=True, nogil=True)
def position_limit_bounds(q: np.ndarray, lower_limit: np.ndarray, upper_limit: np.ndarray, gain: float,
                          dt: float, lower: np.ndarray, upper: np.ndarray) -> None:
    """Velocity-damper bounds of :class:`~wbc.JointPositionLimits`: inside the limits the
    fraction ``gain`` of each margin per tick; outside them the full margins (``gain = 1``),
    so the joint may land on the violated limit in one tick and ``lower <= upper`` holds
    whatever the gain (a small gain on one side only would exclude the way back)."""
    for i in range(len(q)):
        low = (lower_limit[i] - q[i]) / dt
        high = (upper_limit[i] - q[i]) / dt
        scale = gain if low <= 0.0 <= high else 1.0
        lower[i] = scale * low
        upper[i] = scale * high


@njit("void(float64[:, :], float64[:, :], float64[:], int64, float64[:, :], int64, int64)", cache=True, nogil=True)
def heading_rows(cos_part: np.ndarray, sin_part: np.ndarray, q: np.ndarray, heading: int, G: np.ndarray,
                 x: int, y: int) -> None:
    """Base-frame rows: columns ``x, y`` of ``G`` = ``cos(q[heading]) A + sin(q[heading]) B``."""
    c, s = math.cos(q[heading]), math.sin(q[heading])
    for r in range(G.shape[0]):
        G[r, x] = c * cos_part[r, 0] + s * sin_part[r, 0]
        G[r, y] = c * cos_part[r, 1] + s * sin_part[r, 1]


# --------------------------------------------------------------- assembly


@njit("void(float64[:, :], int64, int64, boolean, float64[:, :])", cache=True, nogil=True)
def normal_equations(stack_t: np.ndarray, first: int, last: int, reset: bool, Hc: np.ndarray) -> None:
    """``Hc = [H; c]`` of the least-squares stack ``A = [W J | W r]`` stored transposed.

    ``stack_t`` is ``A^T`` ((nv + 1) x rows); rows ``first:last`` of ``A`` are used:
    ``H = sum_rows (WJ)_r^T (WJ)_r``, ``c = -sum_rows (WJ)_r^T (W r)_r``, one rank-1 update
    per row over its non-zero entries only -- posture and damping rows have one, so the cost
    grows with the dense rows (nv^2 each), not with nv^2 times every row. ``reset=False``
    adds to ``Hc`` instead of overwriting it (the preview rows).
    """
    nv = Hc.shape[1]
    if reset:
        for i in range(nv + 1):
            for j in range(nv):
                Hc[i, j] = 0.0
    nonzero = np.empty(nv, dtype=np.int64)
    for r in range(first, last):
        count = 0
        for i in range(nv):
            if stack_t[i, r] != 0.0:
                nonzero[count] = i
                count += 1
        target = stack_t[nv, r]
        for a in range(count):
            i = nonzero[a]
            value = stack_t[i, r]
            for b in range(a, count):
                j = nonzero[b]
                Hc[i, j] += value * stack_t[j, r]
            Hc[nv, i] -= target * value
    for i in range(nv):  # mirror the upper triangle
        for j in range(i):
            Hc[i, j] = Hc[j, i]


@njit("boolean(float64[:, :], float64[:, :], float64[:])", cache=True, nogil=True)
def preview_solve(Hc: np.ndarray, factor: np.ndarray, preview: np.ndarray) -> bool:
    """Holonomic relaxation ``preview = -H^-1 c`` by Cholesky (``factor``: nv x nv scratch).
    Returns False, with ``preview = 0``, when H is not positive definite (no damping)."""
    nv = Hc.shape[1]
    for j in range(nv):
        pivot = Hc[j, j]
        for p in range(j):
            pivot -= factor[j, p] * factor[j, p]
        if not pivot > 0.0:
            for i in range(nv):
                preview[i] = 0.0
            return False
        factor[j, j] = math.sqrt(pivot)
        for a in range(j + 1, nv):
            total = Hc[a, j]
            for p in range(j):
                total -= factor[a, p] * factor[j, p]
            factor[a, j] = total / factor[j, j]
    for a in range(nv):  # L y = -c
        total = -Hc[nv, a]
        for p in range(a):
            total -= factor[a, p] * preview[p]
        preview[a] = total / factor[a, a]
    for a in range(nv - 1, -1, -1):  # L^T x = y
        total = preview[a]
        for p in range(a + 1, nv):
            total -= factor[p, a] * preview[p]
        preview[a] = total / factor[a, a]
    return True


@njit("void(float64[:], float64[:], float64[:], float64[:], float64[:], float64[:])", cache=True, nogil=True)
def clip_bounds(soft_upper: np.ndarray, soft_lower: np.ndarray, hard_upper: np.ndarray, hard_lower: np.ndarray,
                upper: np.ndarray, lower: np.ndarray) -> None:
    """Soft bounds clipped into the hard ones: ``clip(soft, hard_lower, hard_upper)``, both sides."""
    for i in range(len(upper)):
        upper[i] = min(max(soft_upper[i], hard_lower[i]), hard_upper[i])
        lower[i] = min(max(soft_lower[i], hard_lower[i]), hard_upper[i])


@njit("void(float64[:, :], float64, float64)", cache=True, nogil=True)
def normalise_cost(Hc: np.ndarray, damping: float, damping_floor: float) -> None:
    """Scale ``[H; c]`` so that ``max_i H_ii = 1`` (the minimiser is unchanged), then raise the
    damping to at least ``damping_floor`` of that scale.

    Costs far from 1 (a weight of 1e11, or 1e-12 everywhere) otherwise meet absolute
    tolerances inside the solvers: DAQP then returned answers violating hard rows by O(1).
    ``damping`` is the part of ``H_ii`` that is damping: where it is below ``damping_floor``
    times the scale, ``H`` is numerically singular in double precision (costs 1e12 over a
    damping of 1e-3) and the floor is added, a regularisation below every solver's tolerance."""
    n = Hc.shape[1]
    scale = 0.0
    for i in range(n):
        scale = max(scale, Hc[i, i])
    if scale > 0.0 and math.isfinite(scale):
        inverse = 1.0 / scale
        for i in range(n + 1):
            for j in range(n):
                Hc[i, j] *= inverse
        missing = damping_floor - damping * inverse
        if missing > 0.0:
            for i in range(n):
                Hc[i, i] += missing


@njit("float64(float64[:, :], float64[:], float64[:], float64[:])", cache=True, nogil=True)
def constraint_defect(C: np.ndarray, upper: np.ndarray, lower: np.ndarray, x: np.ndarray) -> float:
    """Largest relative violation of ``lower <= (x; C x) <= upper`` (the layout of
    :class:`wbc.qp.QP`): each violation is divided by ``max(1, |bound|, sum_j |C_rj x_j|)``,
    the size of the numbers it was computed from. NaN in ``x`` gives inf."""
    n = x.shape[0]
    worst = 0.0
    for i in range(upper.shape[0]):
        if i < n:
            value = x[i]
            size = abs(value)
        else:
            value = 0.0
            size = 0.0
            for j in range(n):
                term = C[i - n, j] * x[j]
                value += term
                size += abs(term)
        if not math.isfinite(value):
            return math.inf
        excess = max(value - upper[i], lower[i] - value)
        if excess > 0.0:
            bound = upper[i] if value > upper[i] else lower[i]
            worst = max(worst, excess / max(1.0, abs(bound), size))
    return worst


@njit("float64(float64[::1], int64, int64, float64[:])", cache=True, nogil=True)
def qp_defect(data: np.ndarray, n: int, rows: int, x: np.ndarray) -> float:
    """:func:`constraint_defect` of ``x`` on the QP stored in ``data`` (:class:`wbc.qp.QP`'s
    flat buffer: H, c, C, upper, lower) with ``n`` variables and ``rows`` rows: the check run
    on every answer, with two array arguments instead of four."""
    start = n * n + n
    m = n + rows
    C = data[start:start + rows * n].reshape((rows, n))
    upper = data[start + rows * n:start + rows * n + m]
    lower = data[start + rows * n + m:start + rows * n + 2 * m]
    return constraint_defect(C, upper, lower, x)


# ---------------------------------------------------------- manipulability

#: closed form accepted while det(gram) > GRAM_CONDITION * (mean eigenvalue)^size
GRAM_CONDITION = 1e-8


@njit("void(float64[:, :], float64[:, :])", cache=True, nogil=True)
def _jacobi_eigenvectors(A: np.ndarray, V: np.ndarray) -> None:
    """Cyclic Jacobi on the symmetric ``A`` (overwritten, ends diagonal): eigenvectors into the
    columns of ``V``. Accurate to ~eps / (eigenvalue gap) in the vectors, like LAPACK, and
    much cheaper for the 3 x 3 to 6 x 6 Gram matrices met here."""
    n = A.shape[0]
    for a in range(n):
        for b in range(n):
            V[a, b] = 1.0 if a == b else 0.0
    scale = 0.0
    for a in range(n):
        scale += A[a, a] * A[a, a]
    for _ in range(30):
        off = 0.0
        for p in range(n):
            for r in range(p + 1, n):
                off += A[p, r] * A[p, r]
        if off <= 1e-34 * scale:
            return
        for p in range(n - 1):
            for r in range(p + 1, n):
                apr = A[p, r]
                if apr == 0.0:
                    continue
                theta = (A[r, r] - A[p, p]) / (2.0 * apr)
                t = 1.0 / (abs(theta) + math.sqrt(theta * theta + 1.0))
                if theta < 0.0:
                    t = -t
                c = 1.0 / math.sqrt(t * t + 1.0)
                s = t * c
                for k in range(n):
                    akp, akr = A[k, p], A[k, r]
                    A[k, p], A[k, r] = c * akp - s * akr, s * akp + c * akr
                for k in range(n):
                    apk, ark = A[p, k], A[r, k]
                    A[p, k], A[r, k] = c * apk - s * ark, s * apk + c * ark
                for k in range(n):
                    vkp, vkr = V[k, p], V[k, r]
                    V[k, p], V[k, r] = c * vkp - s * vkr, s * vkp + c * vkr


@njit("float64(float64[:, :], float64[:, :], boolean, float64[:, :])", cache=True, nogil=True)
def _svd_weights(selected: np.ndarray, gram: np.ndarray, wide: bool, weights: np.ndarray) -> float:
    """``G = sum_l c_l u_l v_l^T`` (``c_l``: product of the other singular values) near a
    singularity; returns ``m``. The singular vectors on the Gram side come from its
    eigenvectors; the singular values and the other side from ``J^T u_l`` (wide) or
    ``J v_l`` (tall), whose norms carry ``s_l`` to ~eps |J| absolute accuracy (the Gram's
    eigenvalues only to eps |J|^2), relatively ~eps |J| / s_l. Where some ``s_l`` is below 1e-7 |J|
    (relative error above ~1e-9): LAPACK's SVD then."""
    rows, nv = selected.shape
    size = gram.shape[0]
    A = gram.copy()
    vectors = np.empty((size, size))
    _jacobi_eigenvectors(A, vectors)
    other = nv if wide else rows
    projected = np.zeros((other, size))  # column l: J^T u_l (wide) or J v_l (tall)
    for l in range(size):
        for k in range(other):
            total = 0.0
            for a in range(size):
                total += (selected[a, k] if wide else selected[k, a]) * vectors[a, l]
            projected[k, l] = total
    singular = np.empty(size)
    largest = 0.0
    for l in range(size):
        norm = 0.0
        for k in range(other):
            norm += projected[k, l] * projected[k, l]
        singular[l] = math.sqrt(norm)
        largest = max(largest, singular[l])
    smallest = singular.min()
    if smallest <= 1e-7 * largest:
        u, s, vt = np.linalg.svd(selected, full_matrices=False)
        value = 1.0
        for l in range(len(s)):
            value *= s[l]
        for l in range(len(s)):
            others = 1.0
            for p in range(len(s)):
                if p != l:
                    others *= s[p]
            for a in range(rows):
                for k in range(nv):
                    weights[a, k] += others * u[a, l] * vt[l, k]
        return value
    value = 1.0
    for l in range(size):
        value *= singular[l]
    for l in range(size):
        others = 1.0
        for p in range(size):
            if p != l:
                others *= singular[p]
        factor = others / singular[l]  # c_l / s_l: the projection has norm s_l
        for a in range(rows):
            for k in range(nv):
                if wide:
                    weights[a, k] += factor * vectors[a, l] * projected[k, l]
                else:
                    weights[a, k] += factor * projected[a, l] * vectors[k, l]
    return value


@njit("float64(float64[:, :], float64[:, :], float64[:], float64[:], float64[:, :], int64, int64, float64[:])",
      cache=True, nogil=True)
def manipulability_gradient(joint_jacobians: np.ndarray, jacobian: np.ndarray, origin: np.ndarray,
                            support: np.ndarray, ancestor: np.ndarray, first_row: int, last_row: int,
                            gradient: np.ndarray) -> float:
    """Yoshikawa's ``m`` of rows ``first_row:last_row`` of the frame Jacobian ``jacobian``
    (from :func:`frame_jacobian`) and ``grad m`` into ``gradient``; returns ``m``.

    ``dm/dq_i = <G, dJ/dq_i>`` with ``G = m (J J^T)^-1 J`` (wide) / ``m J (J^T J)^-1`` (tall)
    while the Gram matrix is well conditioned (Cholesky), else ``G = U diag(c) V^T`` from the
    SVD, ``c_l`` the product of the other singular values (see :mod:`wbc.manipulability`).

    Row selections are ``0:6``, ``0:3`` or ``3:6``. ``dJ/dq_i`` for a chain of 1-DOF joints, from the joint
    columns ``S_k = (v_k; w_k)`` (spatial, world origin): moving ``q_i`` moves the subtree of joint i rigidly, so
    ``dS_k/dq_i = (w_i x v_k + v_i x w_k; w_i x w_k)`` when i is a strict ancestor of k
    (``ancestor[i, k] = 1``), else 0, and the frame origin moves by ``dp_i = v_i + w_i x p``
    (the linear part of column i of ``jacobian``). The world-aligned column
    ``J_k = (v_k + w_k x p; w_k)`` then changes by ``(dv_k + dw_k x p + w_k x dp_i; dw_k)``.
    """
    nv = jacobian.shape[1]
    rows = last_row - first_row
    selected = np.ascontiguousarray(jacobian[first_row:last_row])
    wide = rows <= nv
    size = rows if wide else nv
    gram = selected @ selected.T if wide else selected.T @ selected
    trace = 0.0
    for a in range(size):
        trace += gram[a, a]
    # Cholesky gram = L L^T (in place, lower triangle); det(gram) = prod(L_aa)^2
    factor = gram.copy()
    determinant = 1.0
    positive = True
    for j in range(size):
        pivot = factor[j, j]
        for p in range(j):
            pivot -= factor[j, p] * factor[j, p]
        if pivot <= 0.0:
            positive = False
            break
        factor[j, j] = math.sqrt(pivot)
        determinant *= pivot
        for a in range(j + 1, size):
            total = factor[a, j]
            for p in range(j):
                total -= factor[a, p] * factor[j, p]
            factor[a, j] = total / factor[j, j]
    weights = np.zeros((rows, nv))  # G
    if positive and determinant > GRAM_CONDITION * (trace / size) ** size:
        value = math.sqrt(determinant)
        # solve gram X = B by forward / back substitution; wide: B = J, G = m X;
        # tall: B = J^T, G = m X^T
        columns = nv if wide else rows
        y = np.empty(size)
        for col in range(columns):
            for a in range(size):
                total = selected[a, col] if wide else selected[col, a]
                for p in range(a):
                    total -= factor[a, p] * y[p]
                y[a] = total / factor[a, a]
            for a in range(size - 1, -1, -1):
                total = y[a]
                for p in range(a + 1, size):
                    total -= factor[p, a] * y[p]
                y[a] = total / factor[a, a]
            for a in range(size):
                if wide:
                    weights[a, col] = value * y[a]
                else:
                    weights[col, a] = value * y[a]
    else:
        value = _svd_weights(selected, gram, wide, weights)
    # contraction with dJ/dq_i
    px, py, pz = origin[0], origin[1], origin[2]
    linear, angular = first_row == 0, last_row == 6
    offset = 3 - first_row  # row of G holding the first angular row
    for i in range(nv):
        gradient[i] = 0.0
        if support[i] == 0.0:
            continue
        vi0, vi1, vi2 = joint_jacobians[0, i], joint_jacobians[1, i], joint_jacobians[2, i]
        wi0, wi1, wi2 = joint_jacobians[3, i], joint_jacobians[4, i], joint_jacobians[5, i]
        dp0, dp1, dp2 = jacobian[0, i], jacobian[1, i], jacobian[2, i]
        total = 0.0
        for k in range(nv):
            if support[k] == 0.0:
                continue
            vk0, vk1, vk2 = joint_jacobians[0, k], joint_jacobians[1, k], joint_jacobians[2, k]
            wk0, wk1, wk2 = joint_jacobians[3, k], joint_jacobians[4, k], joint_jacobians[5, k]
            if ancestor[i, k] != 0.0:
                dw0, dw1, dw2 = wi1 * wk2 - wi2 * wk1, wi2 * wk0 - wi0 * wk2, wi0 * wk1 - wi1 * wk0
                dv0 = wi1 * vk2 - wi2 * vk1 + vi1 * wk2 - vi2 * wk1
                dv1 = wi2 * vk0 - wi0 * vk2 + vi2 * wk0 - vi0 * wk2
                dv2 = wi0 * vk1 - wi1 * vk0 + vi0 * wk1 - vi1 * wk0
            else:
                dw0 = dw1 = dw2 = dv0 = dv1 = dv2 = 0.0
            if linear:
                d0 = dv0 + dw1 * pz - dw2 * py + wk1 * dp2 - wk2 * dp1
                d1 = dv1 + dw2 * px - dw0 * pz + wk2 * dp0 - wk0 * dp2
                d2 = dv2 + dw0 * py - dw1 * px + wk0 * dp1 - wk1 * dp0
                total += weights[0, k] * d0 + weights[1, k] * d1 + weights[2, k] * d2
            if angular:
                total += weights[offset, k] * dw0 + weights[offset + 1, k] * dw1 + weights[offset + 2, k] * dw2
        gradient[i] = total
    return value


@njit("void(float64[:, :], float64[:, :], float64[:], float64[:], float64[:], float64[:, :], float64[:, :], "
      "float64[:], float64[:], float64[:], float64[:], float64[:], float64[:], int64, int64, float64)",
      cache=True, nogil=True)
def barrier_row(joint_jacobians: np.ndarray, joint_rotation: np.ndarray, joint_translation: np.ndarray,
                local: np.ndarray, support: np.ndarray, ancestor: np.ndarray, jacobian: np.ndarray,
                origin: np.ndarray, gradient: np.ndarray, G: np.ndarray, h: np.ndarray, settings: np.ndarray,
                value: np.ndarray, first_row: int, last_row: int, dt: float) -> None:
    """Row of :class:`~wbc.ManipulabilityBarrier`: ``-grad m . v <= gain (m - m_min) / dt``;
    ``settings = (gain, m_min)``, ``m`` written to ``value[0]``."""
    frame_jacobian(joint_jacobians, joint_rotation, joint_translation, local, support, jacobian, origin)
    m = manipulability_gradient(joint_jacobians, jacobian, origin, support, ancestor, first_row, last_row,
                                gradient)
    value[0] = m
    for i in range(len(gradient)):
        G[i] = -gradient[i]
    h[0] = settings[0] * (m - settings[1]) / dt


@njit("boolean(float64[:])", cache=True, nogil=True)
def has_nan(data: np.ndarray) -> bool:
    """True when some entry of ``data`` is NaN (infinite entries are allowed: open bounds)."""
    for value in data:
        if math.isnan(value):
            return True
    return False


# ------------------------------------------------------------- tick program
#
# One compiled call runs every compiled part of a tick. Its operands are registered once
# (wbc.program.TickProgram) as C-contiguous float64 arrays and handed over by address:
# entering a numba function costs ~0.1 us per array argument, a dozen arrays would cost
# more than the arithmetic. Each program row is [opcode, operands...] (array indices and
# sizes); the layouts are those of the kernels above.

(OP_FRAME_TASK, OP_POSTURE, OP_POSITION_LIMITS, OP_NORMAL_EQUATIONS, OP_CLIP_BOUNDS, OP_HAS_NAN, OP_HEADING_ROWS,
 OP_MANIPULABILITY_BARRIER, OP_POSITION_TASK, OP_PREVIEW, OP_STEERING, OP_NORMALISE_COST) = range(1, 13)


@intrinsic
def _as_pointer(typingctx, address):
    """The float64 pointer at integer ``address`` (registered arrays only: see TickProgram)."""
    signature = types.CPointer(types.float64)(types.int64)

    def codegen(context, builder, signature, args):
        return builder.inttoptr(args[0], context.get_value_type(types.CPointer(types.float64)))

    return signature, codegen


@njit(inline="always")
def _vector(addresses: np.ndarray, index: int, size: int) -> np.ndarray:
    return carray(_as_pointer(addresses[index]), (size,))


@njit(inline="always")
def _matrix(addresses: np.ndarray, index: int, rows: int, columns: int) -> np.ndarray:
    return carray(_as_pointer(addresses[index]), (rows, columns))


@njit("boolean(int64[:, :], int64[:], float64)", cache=True, nogil=True)
def run_program(program: np.ndarray, addresses: np.ndarray, dt: float) -> bool:
    """Run the rows of ``program`` in order; returns True when a HAS_NAN row found a NaN.

    Rows (array operands by index into ``addresses``):

    * FRAME_TASK: J^T (nv x 6), R^T (3 x 3), p (3), support (nv), settings, frame data, error (6),
      stack A^T ((nv + 1) x rows), first row, nv, rows
    * POSTURE: q (dim), reference (dim), W (dim), settings (gain), error (dim), stack, first row, dim, nv, rows
    * POSITION_LIMITS: q (k), lower limit, upper limit, gain (1), lower out, upper out, k
    * NORMAL_EQUATIONS: stack, nv, rows, first row, last row, reset (0/1), Hc ((nv + 1) x nv)
    * PREVIEW: Hc, factor scratch (nv x nv), preview (nv), nv
    * STEERING: preview (nv), q (nq), x, y, heading, parameters (3), error (1), stack, first row,
      nv, rows, nq
    * CLIP_BOUNDS: soft upper, soft lower, hard upper, hard lower, ub, lb, n
    * HAS_NAN: data, size
    * NORMALISE_COST: Hc ((nv + 1) x nv), (damping, damping floor), nv
    * HEADING_ROWS: cos part (rows x 2), sin part, q (nq), heading index, G (rows x nv), rows, nq, nv, x, y
    * POSITION_TASK: J^T, R^T, p, support (nv), settings, frame data, error (3), stack, first row, nv,
      rows, Jacobian scratch (6 x nv)
    * MANIPULABILITY_BARRIER: J^T, R^T, p, frame in joint (12), support (nv), ancestor (nv x nv),
      Jacobian scratch (6 x nv), origin scratch (3), gradient (nv), G row (nv), h (1),
      settings (gain, min value), value out (1), first row, last row, nv
    """
    found_nan = False
    for r in range(program.shape[0]):
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
        elif code == OP_CLIP_BOUNDS:
            n = op[7]
            clip_bounds(_vector(addresses, op[1], n), _vector(addresses, op[2], n), _vector(addresses, op[3], n),
                        _vector(addresses, op[4], n), _vector(addresses, op[5], n), _vector(addresses, op[6], n))
        elif code == OP_HAS_NAN:
            found_nan = found_nan or has_nan(_vector(addresses, op[1], op[2]))
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
                               stack_t[nv, start:start + 3], _matrix(addresses, op[12], 6, nv))
        elif code == OP_MANIPULABILITY_BARRIER:
            nv = op[16]
            barrier_row(_matrix(addresses, op[1], nv, 6).T, _matrix(addresses, op[2], 3, 3).T,
                        _vector(addresses, op[3], 3), _vector(addresses, op[4], 12), _vector(addresses, op[5], nv),
                        _matrix(addresses, op[6], nv, nv), _matrix(addresses, op[7], 6, nv),
                        _vector(addresses, op[8], 3), _vector(addresses, op[9], nv), _vector(addresses, op[10], nv),
                        _vector(addresses, op[11], 1), _vector(addresses, op[12], 2), _vector(addresses, op[13], 1),
                        op[14], op[15], dt)
    return found_nan
