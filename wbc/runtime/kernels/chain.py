"""Forward kinematics of chains of 1-DOF joints (revolute, prismatic, any axis): the joint
placements and joint Jacobians of :class:`wbc.model.kinematics.Kinematics` in its native mode,
in the layouts the other kernels read (Pinocchio's, see ``CHAIN_*`` in :mod:`wbc.runtime.kernels`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from . import CHAIN_COLUMNS, CHAIN_PRISMATIC, prepare_cache
from ._lazy import declared
from .ops import Op

CACHE = prepare_cache()  # before the first @njit below compiles; False: no writable cache (see wbc.runtime.kernels)


# inlined by LLVM (forceinline), not by numba's IR inlining: compiled once, not copied into each caller's IR
# (a first start compiles ~0.1-0.2 s sooner, benchmarks/README.md section 8; the ticks are alike)
@njit(forceinline=True, no_cpython_wrapper=True)
def _forward_kinematics_of(q: np.ndarray, chain: np.ndarray, placements: np.ndarray, jacobians_t: np.ndarray) -> None:
    """World placement and Jacobian column of every joint of ``chain`` at configuration ``q``.

    ``chain`` row j >= 1 (row 0 is the universe): parent joint, kind (revolute / CHAIN_PRISMATIC),
    q index, v index, unit axis (3, joint frame), placement in the parent (rotation row-major
    (9), translation (3)); parents come before children. ``M_j = M_parent L_j X_j(q)`` with
    ``X_j`` the rotation about the axis by q (revolute) or the translation along it
    (prismatic). Writes ``placements[j] = (R_j column-major (9), p_j (3))`` and column
    ``v index`` of the joint Jacobians, as ``jacobians_t[v] = (v_O; w)``: the joint's motion
    at the world origin in world axes -- revolute ``w = R_j a``, ``v_O = p_j x w``; prismatic
    ``v_O = R_j a``, ``w = 0`` (Pinocchio's ``data.oMi`` and ``data.J``).
    """
    for a in range(12):
        placements[0, a] = 0.0
    placements[0, 0] = placements[0, 4] = placements[0, 8] = 1.0
    for j in range(1, chain.shape[0]):
        row = chain[j]
        parent, kind, iv = int(row[0]), row[1], int(row[3])
        ax, ay, az = row[4], row[5], row[6]
        Rp = placements[parent]  # Rp[3 b + a] = R_parent[a, b]; Rp[9:12] = p_parent
        # R1 = R_parent L_R (L_R row-major in row[7:16]), p = R_parent L_p + p_parent: scalars, no allocation
        r00 = Rp[0] * row[7] + Rp[3] * row[10] + Rp[6] * row[13]
        r01 = Rp[0] * row[8] + Rp[3] * row[11] + Rp[6] * row[14]
        r02 = Rp[0] * row[9] + Rp[3] * row[12] + Rp[6] * row[15]
        r10 = Rp[1] * row[7] + Rp[4] * row[10] + Rp[7] * row[13]
        r11 = Rp[1] * row[8] + Rp[4] * row[11] + Rp[7] * row[14]
        r12 = Rp[1] * row[9] + Rp[4] * row[12] + Rp[7] * row[15]
        r20 = Rp[2] * row[7] + Rp[5] * row[10] + Rp[8] * row[13]
        r21 = Rp[2] * row[8] + Rp[5] * row[11] + Rp[8] * row[14]
        r22 = Rp[2] * row[9] + Rp[5] * row[12] + Rp[8] * row[15]
        px = Rp[0] * row[16] + Rp[3] * row[17] + Rp[6] * row[18] + Rp[9]
        py = Rp[1] * row[16] + Rp[4] * row[17] + Rp[7] * row[18] + Rp[10]
        pz = Rp[2] * row[16] + Rp[5] * row[17] + Rp[8] * row[18] + Rp[11]
        # the axis in world axes (the joint's own motion leaves it unchanged)
        wx = r00 * ax + r01 * ay + r02 * az
        wy = r10 * ax + r11 * ay + r12 * az
        wz = r20 * ax + r21 * ay + r22 * az
        out = placements[j]
        value = q[int(row[2])]
        if kind == CHAIN_PRISMATIC:
            out[0], out[1], out[2] = r00, r10, r20
            out[3], out[4], out[5] = r01, r11, r21
            out[6], out[7], out[8] = r02, r12, r22
            out[9], out[10], out[11] = px + wx * value, py + wy * value, pz + wz * value
            jacobians_t[iv, 0], jacobians_t[iv, 1], jacobians_t[iv, 2] = wx, wy, wz
            jacobians_t[iv, 3] = jacobians_t[iv, 4] = jacobians_t[iv, 5] = 0.0
            continue
        # R = R1 X, X the rotation about the axis by q (Rodrigues)
        c, s = math.cos(value), math.sin(value)
        t = 1.0 - c
        x00, x01, x02 = c + t * ax * ax, t * ax * ay - s * az, t * ax * az + s * ay
        x10, x11, x12 = t * ay * ax + s * az, c + t * ay * ay, t * ay * az - s * ax
        x20, x21, x22 = t * az * ax - s * ay, t * az * ay + s * ax, c + t * az * az
        out[0] = r00 * x00 + r01 * x10 + r02 * x20
        out[1] = r10 * x00 + r11 * x10 + r12 * x20
        out[2] = r20 * x00 + r21 * x10 + r22 * x20
        out[3] = r00 * x01 + r01 * x11 + r02 * x21
        out[4] = r10 * x01 + r11 * x11 + r12 * x21
        out[5] = r20 * x01 + r21 * x11 + r22 * x21
        out[6] = r00 * x02 + r01 * x12 + r02 * x22
        out[7] = r10 * x02 + r11 * x12 + r12 * x22
        out[8] = r20 * x02 + r21 * x12 + r22 * x22
        out[9], out[10], out[11] = px, py, pz
        jacobians_t[iv, 0] = py * wz - pz * wy
        jacobians_t[iv, 1] = pz * wx - px * wz
        jacobians_t[iv, 2] = px * wy - py * wx
        jacobians_t[iv, 3], jacobians_t[iv, 4], jacobians_t[iv, 5] = wx, wy, wz


@declared("void(float64[:], float64[:, :], float64[:, :], float64[:, :])", cache=CACHE, nogil=True)
def forward_kinematics(q: np.ndarray, chain: np.ndarray, placements: np.ndarray, jacobians_t: np.ndarray) -> None:
    """:func:`_forward_kinematics_of` on arrays of any strides (called from Python)."""
    _forward_kinematics_of(q, chain, placements, jacobians_t)


# ------------------------------------------------------- tick-program ops


@njit(inline="always")
def _forward_kinematics(q: np.ndarray, chain: np.ndarray, placements: np.ndarray, jacobians_t: np.ndarray, nq: int,
                        joints: int, nv: int, dt: float) -> None:
    _forward_kinematics_of(q, chain, placements, jacobians_t)  # compiled here for the program's C-contiguous arrays


#: the joint placements and joint Jacobians of a chain of 1-DOF joints (wbc.model.kinematics' native mode)
FORWARD_KINEMATICS = Op("FORWARD_KINEMATICS", _forward_kinematics, (
    ("q", ("nq",)), ("chain", ("joints", CHAIN_COLUMNS)), ("placements", ("joints", 12)),
    ("jacobians_t", ("nv", 6)), ("nq", None), ("joints", None), ("nv", None)), checks=("1 <= joints",))
