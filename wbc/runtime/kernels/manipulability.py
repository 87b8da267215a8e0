"""Yoshikawa manipulability: its analytic gradient and the ManipulabilityBarrier row
(math in docs/manipulability.md and :mod:`wbc.model.manipulability`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from . import BARRIER_GAIN, BARRIER_MIN_VALUE, BARRIER_SETTINGS, GRAM_CONDITION, prepare_cache
from ._lazy import declared
from .frames import frame_jacobian
from .ops import Op

CACHE = prepare_cache()  # before the first @njit below compiles; False: no writable cache (see wbc.runtime.kernels)

@declared("void(float64[:, :], float64[:, :])", cache=CACHE, nogil=True)
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


@declared("float64(float64[:, :], float64[:, :], boolean, float64[:, :])", cache=CACHE, nogil=True)
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


@declared("float64(float64[:, :], float64[:, :], float64[:], float64[:], float64[:, :], int64, int64, float64[:])",
          cache=CACHE, nogil=True)
def manipulability_gradient(joint_jacobians: np.ndarray, jacobian: np.ndarray, origin: np.ndarray,
                            support: np.ndarray, ancestor: np.ndarray, first_row: int, last_row: int,
                            gradient: np.ndarray) -> float:
    """Yoshikawa's ``m`` of rows ``first_row:last_row`` of the frame Jacobian ``jacobian``
    (from :func:`frame_jacobian`) and ``grad m`` into ``gradient``; returns ``m``.

    ``dm/dq_i = <G, dJ/dq_i>`` with ``G = m (J J^T)^-1 J`` (wide) / ``m J (J^T J)^-1`` (tall)
    while the Gram matrix is well conditioned (Cholesky), else ``G = U diag(c) V^T`` from the
    SVD, ``c_l`` the product of the other singular values (see :mod:`wbc.model.manipulability`).

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


@declared("void(float64[:, :], float64[:, :], float64[:], float64[:], float64[:], float64[:, :], float64[:, :], "
          "float64[:], float64[:], float64[:], float64[:], float64[:], float64[:], int64, int64, float64)",
          cache=CACHE, nogil=True)
def barrier_row(joint_jacobians: np.ndarray, joint_rotation: np.ndarray, joint_translation: np.ndarray,
                local: np.ndarray, support: np.ndarray, ancestor: np.ndarray, jacobian: np.ndarray,
                origin: np.ndarray, gradient: np.ndarray, G: np.ndarray, h: np.ndarray, settings: np.ndarray,
                value: np.ndarray, first_row: int, last_row: int, dt: float) -> None:
    """Row of :class:`~wbc.ManipulabilityBarrier`: ``-grad m . v <= gain (m - m_min) / dt``;
    settings layout ``BARRIER_*``, ``m`` written to ``value[0]``."""
    frame_jacobian(joint_jacobians, joint_rotation, joint_translation, local, support, jacobian, origin)
    m = manipulability_gradient(joint_jacobians, jacobian, origin, support, ancestor, first_row, last_row,
                                gradient)
    value[0] = m
    for i in range(len(gradient)):
        G[i] = -gradient[i]
    h[0] = settings[BARRIER_GAIN] * (m - settings[BARRIER_MIN_VALUE]) / dt


# ------------------------------------------------------- tick-program ops


@njit(inline="always")
def _manipulability_barrier(joint_jacobians_t: np.ndarray, rotation_t: np.ndarray, translation: np.ndarray,
                            local: np.ndarray, support: np.ndarray, ancestor: np.ndarray, jacobian: np.ndarray,
                            origin: np.ndarray, gradient: np.ndarray, G: np.ndarray, h: np.ndarray,
                            settings: np.ndarray, value: np.ndarray, first: int, last: int, nv: int,
                            dt: float) -> None:
    barrier_row(joint_jacobians_t.T, rotation_t.T, translation, local, support, ancestor, jacobian, origin, gradient,
                G, h, settings, value, first, last, dt)


#: ManipulabilityBarrier's row G v <= h (Jacobian rows first:last)
MANIPULABILITY_BARRIER = Op("MANIPULABILITY_BARRIER", _manipulability_barrier, (
    ("joint_jacobians_t", ("nv", 6)), ("rotation_t", (3, 3)), ("translation", (3,)), ("local", (12,)),
    ("support", ("nv",)), ("ancestor", ("nv", "nv")), ("jacobian", (6, "nv")), ("origin", (3,)),
    ("gradient", ("nv",)), ("G", ("nv",)), ("h", (1,)), ("settings", (BARRIER_SETTINGS,)), ("value", (1,)),
    ("first", None), ("last", None), ("nv", None)), checks=("0 <= first < last <= 6",))
