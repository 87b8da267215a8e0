"""Compiled (numba) distances between the shapes of :mod:`wbc.collision.layout`, and their
gradient rows.

One call, :func:`pair_distances`, does a tick's work for every candidate pair: the shapes' world
poses from the joint placements, the broad phase (bounding spheres: a pair whose spheres are
``detection`` apart or more costs ~10 flops), the exact signed distance of the pairs that pass
(sphere, capsule and box against each other, overlapping boxes included, and against a plane;
any other pair -- a ``COAL`` shape, two planes -- is flagged for coal), and the row
``grad d(q)^T`` of each. Nothing is allocated: the results go into the caller's arrays, at most
``capacity`` pairs (when more are within ``detection``, the closest are kept).

Conventions: joint placements and joint Jacobians in the layouts of
:class:`wbc.model.kinematics.Kinematics` (``placements[j] = (R_j column-major (9), p_j (3))``,
``jacobians_t[k] = (v_O (3), w (3))``: the motion of velocity coordinate k at the world origin, world
axes, Pinocchio's ``data.J``). For a pair (a, b): ``d`` is the signed distance (< 0: penetration
depth), ``normal`` the unit vector from a to b along which d grows when b moves, witness points
``w_a`` on a and ``w_b`` on b with ``w_b - w_a = d * normal``, and the row

    grad d . v = normal . (v_b(w_b) - v_a(w_a)),   v_x(p) = sum_{k in support(x)} (v_O,k + w_k x p) v_k

(``normal . (w_k x p) = w_k . (p x normal)``). The first-order change of the distance of two
rigid shapes is that of the witness points along the normal (any point on the normal line of
either body gives the same value), so this is the exact gradient wherever d is differentiable.

All jitted code of the collision package lives in this one file, and its cache follows the cache
rule of :mod:`wbc.runtime.kernels` applied to this package's folder: numba keys a cached function on its
own source file only, so the constants it reads from :mod:`wbc.collision.layout` are covered by a
hash of every ``*.py`` file of ``wbc/collision/`` (:func:`wbc.runtime.kernels._cache.prepare`): any edit
there recompiles these kernels.

Importing this file compiles nothing. The kernels Python calls are declared
(:mod:`wbc.runtime.kernels._lazy`) and compiled when an object that calls them is built -- a
:class:`~wbc.collision.Distances`, or a controller computing a
:class:`~wbc.collision.CollisionAvoidance` in Python
(:meth:`~wbc.constraints.constraint.ConstraintData.prepare_compute`) -- and the tick program's op
when a controller first adds it; :func:`wbc.collision.warm_up.warm_up` compiles all of them. The helpers are inlined by
LLVM (``forceinline``), not by numba's IR inliner, which copied each helper's IR into every caller
(the first start after an install with a :class:`~wbc.collision.CollisionAvoidance` took ~4 min).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from numba import njit

from ..runtime.kernels import _cache
from ..runtime.kernels._lazy import declared
from .layout import (
    BOUND_CENTER,
    BOUND_RADIUS,
    BOX,
    CAPSULE,
    COAL,
    DETECTION,
    GAIN,
    HALF_EXTENTS,
    HALF_LENGTH,
    JOINT,
    KIND,
    MIN_DISTANCE,
    PAIR_A,
    PAIR_B,
    PLANE,
    RADIUS,
    SCRATCH,
    SPHERE,
)

CACHE = _cache.prepare(Path(__file__).parent, ("kernels", "footprint_kernels"), cold=("kernels",)) is not None

_HX, _BC = HALF_EXTENTS.start, BOUND_CENTER.start
#: columns of a shape's world pose: rotation row-major (9), translation (3), bounding-sphere centre (3)
POSE_COLUMNS = 15


@declared("void(float64[:, ::1], float64[:, ::1], float64[:, ::1])", cache=CACHE, nogil=True)
def world_poses(table, placements, world):
    """``world[s] = (R row-major (9), p (3), bounding centre (3))``: each shape's world pose (a
    shape of the world, joint 0 -- an obstacle --: its table pose as it is, joint 0's placement
    being the identity)."""
    for s in range(table.shape[0]):
        j = int(table[s, JOINT])
        shape, pose = table[s], world[s]
        if j == 0:
            for a in range(12):
                pose[a] = shape[2 + a]
        else:  # R = R_j R_local, p = R_j p_local + p_j (R_j column-major in the placement, R_local row-major)
            P = placements[j]
            r0, r1, r2, r3, r4, r5, r6, r7, r8 = P[0], P[1], P[2], P[3], P[4], P[5], P[6], P[7], P[8]
            for b in range(3):
                x, y, z = shape[2 + b], shape[5 + b], shape[8 + b]
                pose[b] = r0 * x + r3 * y + r6 * z
                pose[3 + b] = r1 * x + r4 * y + r7 * z
                pose[6 + b] = r2 * x + r5 * y + r8 * z
            x, y, z = shape[11], shape[12], shape[13]
            pose[9] = r0 * x + r3 * y + r6 * z + P[9]
            pose[10] = r1 * x + r4 * y + r7 * z + P[10]
            pose[11] = r2 * x + r5 * y + r8 * z + P[11]
        x, y, z = shape[_BC], shape[_BC + 1], shape[_BC + 2]
        for a in range(3):
            pose[12 + a] = pose[9 + a] + pose[3 * a] * x + pose[3 * a + 1] * y + pose[3 * a + 2] * z


@njit(forceinline=True, no_cpython_wrapper=True, nogil=True)
def _segment(table, world, s):
    """The core segment of a sphere (a point) or capsule ``s``, world: (x0, y0, z0, x1, y1, z1)."""
    half = table[s, HALF_LENGTH] if table[s, KIND] == CAPSULE else 0.0
    ux, uy, uz = world[s, 2] * half, world[s, 5] * half, world[s, 8] * half
    return (world[s, 9] - ux, world[s, 10] - uy, world[s, 11] - uz,
            world[s, 9] + ux, world[s, 10] + uy, world[s, 11] + uz)


@njit(forceinline=True, no_cpython_wrapper=True, nogil=True)
def _clamp01(x):
    return 0.0 if x < 0.0 else (1.0 if x > 1.0 else x)


@njit(forceinline=True, no_cpython_wrapper=True, nogil=True)
def segment_segment(p, ra, q, rb, out):
    """Signed distance of two sphere-swept segments ``p = (x0, y0, z0, x1, y1, z1)`` (radius ra, a)
    and ``q`` (rb, b): ``out[0:10] = (d, w_a (3), w_b (3), normal (3))``. Closest points of the
    segments as in Ericson, Real-Time Collision Detection, section 5.1.9."""
    d1x, d1y, d1z = p[3] - p[0], p[4] - p[1], p[5] - p[2]
    d2x, d2y, d2z = q[3] - q[0], q[4] - q[1], q[5] - q[2]
    rx, ry, rz = p[0] - q[0], p[1] - q[1], p[2] - q[2]
    a = d1x * d1x + d1y * d1y + d1z * d1z
    e = d2x * d2x + d2y * d2y + d2z * d2z
    f = d2x * rx + d2y * ry + d2z * rz
    if a <= 1e-24 and e <= 1e-24:
        s = t = 0.0
    elif a <= 1e-24:
        s, t = 0.0, _clamp01(f / e)
    else:
        c = d1x * rx + d1y * ry + d1z * rz
        if e <= 1e-24:
            s, t = _clamp01(-c / a), 0.0
        else:
            b = d1x * d2x + d1y * d2y + d1z * d2z
            denom = a * e - b * b
            s = _clamp01((b * f - c * e) / denom) if denom > 1e-14 * a * e else 0.0
            t = (b * s + f) / e
            if t < 0.0:
                t, s = 0.0, _clamp01(-c / a)
            elif t > 1.0:
                t, s = 1.0, _clamp01((b - c) / a)
    ax, ay, az = p[0] + s * d1x, p[1] + s * d1y, p[2] + s * d1z
    bx, by, bz = q[0] + t * d2x, q[1] + t * d2y, q[2] + t * d2z
    nx, ny, nz = bx - ax, by - ay, bz - az
    dist = math.sqrt(nx * nx + ny * ny + nz * nz)
    if dist > 1e-12:
        nx, ny, nz = nx / dist, ny / dist, nz / dist
    else:  # the cores meet: a direction across both (no unique normal there)
        nx, ny, nz = d1y * d2z - d1z * d2y, d1z * d2x - d1x * d2z, d1x * d2y - d1y * d2x
        norm = math.sqrt(nx * nx + ny * ny + nz * nz)
        if norm <= 1e-12:
            ux, uy, uz = (d1x, d1y, d1z) if a > 1e-24 else (d2x, d2y, d2z)
            nx, ny, nz = (0.0, -uz, uy) if abs(ux) < 0.9 else (-uy, ux, 0.0)
            norm = math.sqrt(nx * nx + ny * ny + nz * nz)
            if norm <= 1e-12:
                nx, ny, nz, norm = 0.0, 0.0, 1.0, 1.0
        nx, ny, nz = nx / norm, ny / norm, nz / norm
    out[0] = dist - ra - rb
    out[1], out[2], out[3] = ax + ra * nx, ay + ra * ny, az + ra * nz
    out[4], out[5], out[6] = bx - rb * nx, by - rb * ny, bz - rb * nz
    out[7], out[8], out[9] = nx, ny, nz


@njit(forceinline=True, no_cpython_wrapper=True, nogil=True)
def _box_sd(x, y, z, h):
    """Signed distance of the point (x, y, z) to the box |x_i| <= h_i (local frame)."""
    ex, ey, ez = abs(x) - h[0], abs(y) - h[1], abs(z) - h[2]
    if ex <= 0.0 and ey <= 0.0 and ez <= 0.0:
        return max(ex, max(ey, ez))
    ex, ey, ez = max(ex, 0.0), max(ey, 0.0), max(ez, 0.0)
    return math.sqrt(ex * ex + ey * ey + ez * ez)


@njit(forceinline=True, no_cpython_wrapper=True, nogil=True)
def _segment_box_parameter(a, d, h, scratch):
    """The t in [0, 1] that minimises the box's signed distance along a + t d (box frame;
    a, d, h: 3-tuples; scratch: >= 40 floats).

    The signed distance of a convex set is convex, so along the segment it is a convex piecewise
    smooth function of t: its minimum lies at an end, a kink or a stationary point of a smooth
    piece. Kinks: the face planes x_i = +-h_i (6) and, inside, where two of the six linear
    functions +-x_i(t) - h_i are equal (15); outside, each piece between consecutive face
    crossings is the root of a quadratic (its vertex). All candidates are evaluated."""
    n = 2
    scratch[0] = 0.0
    scratch[1] = 1.0
    for i in range(3):
        if d[i] != 0.0:
            for sign in (-1.0, 1.0):
                t = (sign * h[i] - a[i]) / d[i]
                if 0.0 < t < 1.0:
                    scratch[n] = t
                    n += 1
    crossings = n
    # outside pieces: the crossings sorted with the ends (insertion sort, at most 8 values) ...
    for k in range(1, crossings):
        value = scratch[k]
        m = k - 1
        while m >= 0 and scratch[m] > value:
            scratch[m + 1] = scratch[m]
            m -= 1
        scratch[m + 1] = value
    # ... and on each, the vertex of |x - clamp(x)|^2 (a quadratic in t)
    for k in range(crossings - 1):
        low, high = scratch[k], scratch[k + 1]
        if high <= low:
            continue
        middle = 0.5 * (low + high)
        num = 0.0
        den = 0.0
        for i in range(3):
            x = a[i] + middle * d[i]
            if x > h[i]:
                num += (a[i] - h[i]) * d[i]
                den += d[i] * d[i]
            elif x < -h[i]:
                num += (a[i] + h[i]) * d[i]
                den += d[i] * d[i]
        if den > 0.0:
            t = -num / den
            scratch[n] = low if t < low else (high if t > high else t)
            n += 1
    # inside: where two of the six distances s x_i(t) - h_i (s = +-1) are equal
    for k in range(6):
        i, s = k // 2, 1.0 - 2.0 * (k % 2)
        for m in range(k + 1, 6):
            j, u = m // 2, 1.0 - 2.0 * (m % 2)
            slope = s * d[i] - u * d[j]
            if slope != 0.0:
                t = (u * a[j] - h[j] - s * a[i] + h[i]) / slope
                if 0.0 < t < 1.0:
                    scratch[n] = t
                    n += 1
    best_t, best = 0.0, np.inf
    for k in range(n):
        t = scratch[k]
        value = _box_sd(a[0] + t * d[0], a[1] + t * d[1], a[2] + t * d[2], h)
        if value < best:
            best, best_t = value, t
    return best_t


@njit(forceinline=True, no_cpython_wrapper=True, nogil=True)
def box_segment(table, world, box, p, radius, out, scratch):
    """Signed distance of box ``box`` (a) and the sphere-swept segment ``p`` of ``radius`` (b,
    world): ``out`` as in :func:`segment_segment`."""
    h = (table[box, _HX], table[box, _HX + 1], table[box, _HX + 2])
    cx, cy, cz = world[box, 9], world[box, 10], world[box, 11]
    # a = R^T (p0 - c), d = R^T (p1 - p0)
    a = (world[box, 0] * (p[0] - cx) + world[box, 3] * (p[1] - cy) + world[box, 6] * (p[2] - cz),
         world[box, 1] * (p[0] - cx) + world[box, 4] * (p[1] - cy) + world[box, 7] * (p[2] - cz),
         world[box, 2] * (p[0] - cx) + world[box, 5] * (p[1] - cy) + world[box, 8] * (p[2] - cz))
    ux, uy, uz = p[3] - p[0], p[4] - p[1], p[5] - p[2]
    d = (world[box, 0] * ux + world[box, 3] * uy + world[box, 6] * uz,
         world[box, 1] * ux + world[box, 4] * uy + world[box, 7] * uz,
         world[box, 2] * ux + world[box, 5] * uy + world[box, 8] * uz)
    t = _segment_box_parameter(a, d, h, scratch)
    x, y, z = a[0] + t * d[0], a[1] + t * d[1], a[2] + t * d[2]
    sd = _box_sd(x, y, z, h)
    qx, qy, qz = min(max(x, -h[0]), h[0]), min(max(y, -h[1]), h[1]), min(max(z, -h[2]), h[2])
    if sd > 0.0:
        nx, ny, nz = (x - qx) / sd, (y - qy) / sd, (z - qz) / sd
    else:  # inside: out through the nearest face
        ex, ey, ez = abs(x) - h[0], abs(y) - h[1], abs(z) - h[2]
        nx = ny = nz = 0.0
        if ex >= ey and ex >= ez:
            nx = 1.0 if x >= 0.0 else -1.0
            qx = nx * h[0]
        elif ey >= ez:
            ny = 1.0 if y >= 0.0 else -1.0
            qy = ny * h[1]
        else:
            nz = 1.0 if z >= 0.0 else -1.0
            qz = nz * h[2]
    out[0] = sd - radius
    for m in range(3):
        normal = world[box, 3 * m] * nx + world[box, 3 * m + 1] * ny + world[box, 3 * m + 2] * nz
        out[1 + m] = (world[box, 9 + m] + world[box, 3 * m] * qx + world[box, 3 * m + 1] * qy
                      + world[box, 3 * m + 2] * qz)
        out[4 + m] = p[m] + t * (p[3 + m] - p[m]) - radius * normal
        out[7 + m] = normal


@njit(forceinline=True, no_cpython_wrapper=True, nogil=True)
def segment_plane(p, radius, world, plane, out):
    """A sphere-swept segment ``p`` (a) and the half-space below plane ``plane`` (b): ``out`` as above."""
    nx, ny, nz = world[plane, 2], world[plane, 5], world[plane, 8]
    ox, oy, oz = world[plane, 9], world[plane, 10], world[plane, 11]
    ha = nx * (p[0] - ox) + ny * (p[1] - oy) + nz * (p[2] - oz)
    hb = nx * (p[3] - ox) + ny * (p[4] - oy) + nz * (p[5] - oz)
    k, height = (0, ha) if ha <= hb else (3, hb)
    out[0] = height - radius
    out[1], out[2], out[3] = p[k] - radius * nx, p[k + 1] - radius * ny, p[k + 2] - radius * nz
    out[4], out[5], out[6] = p[k] - height * nx, p[k + 1] - height * ny, p[k + 2] - height * nz
    out[7], out[8], out[9] = -nx, -ny, -nz


@njit(forceinline=True, no_cpython_wrapper=True, nogil=True)
def box_plane(table, world, box, plane, out):
    """Box ``box`` (a) and the half-space below plane ``plane`` (b): the box's vertex deepest
    along -normal, ``c - sum_i h_i sign(n . R_i) R_i``."""
    nx, ny, nz = world[plane, 2], world[plane, 5], world[plane, 8]
    for m in range(3):
        out[1 + m] = world[box, 9 + m]
    for i in range(3):
        along = nx * world[box, i] + ny * world[box, 3 + i] + nz * world[box, 6 + i]
        step = -table[box, _HX + i] if along > 0.0 else table[box, _HX + i]
        for m in range(3):
            out[1 + m] += step * world[box, 3 * m + i]
    height = nx * (out[1] - world[plane, 9]) + ny * (out[2] - world[plane, 10]) + nz * (out[3] - world[plane, 11])
    out[0] = height
    out[4], out[5], out[6] = out[1] - height * nx, out[2] - height * ny, out[3] - height * nz
    out[7], out[8], out[9] = -nx, -ny, -nz


@njit(forceinline=True, no_cpython_wrapper=True, nogil=True)
def _flip(out):
    """Swap the roles of a and b in ``out``."""
    for m in range(3):
        out[1 + m], out[4 + m] = out[4 + m], out[1 + m]
        out[7 + m] = -out[7 + m]


#: |a_i x b_j| below this: the two edge directions are parallel and their cross product is no
#: axis (a face axis of either box then separates, or measures the overlap, as well)
_PARALLEL = 1e-6
#: |n . axis| at most this: n is orthogonal to the box's axis (support point: a face's or edge's middle)
_TIE = 1e-9
#: an edge-edge axis must beat the face axes by this much [m]: faces win ties (and rounding)
_EDGE_BIAS = 1e-12


@njit(forceinline=True, no_cpython_wrapper=True, nogil=True)
def _support(table, world, box, nx, ny, nz, toward, skip, out, at):
    """``out[at:at + 3]``: the point of ``box`` farthest along ``toward * n`` (``toward`` = +-1),
    ``c + sum_i h_i sign(toward n . R_i) R_i`` over the axes i != ``skip``. An axis with
    ``|n . R_i| <= _TIE`` contributes 0: the middle of the farthest edge or face, the point that
    moves least as n turns through the tie."""
    for m in range(3):
        out[at + m] = world[box, 9 + m]
    for i in range(3):
        along = toward * (nx * world[box, i] + ny * world[box, 3 + i] + nz * world[box, 6 + i])
        if i != skip and abs(along) > _TIE:
            step = table[box, _HX + i] if along > 0.0 else -table[box, _HX + i]
            for m in range(3):
                out[at + m] += step * world[box, 3 * m + i]


@njit(cache=CACHE, nogil=True)  # not inlined: rare (boxes in contact), and large
def box_penetration(table, world, a, b, out):
    """Two overlapping boxes: ``out`` as in :func:`segment_segment`, by the separating-axis
    theorem. Along a unit axis L the boxes' projections overlap by::

        o(L) = r_a(L) + r_b(L) - |L . (c_b - c_a)|,   r_x(L) = sum_i h_x,i |L . R_x,i|,

    and the smallest translation that separates two convex polytopes is along one of 15 axes: the
    3 face normals of each box and the 9 cross products ``a_i x b_j`` of their edge directions
    (normalised; skipped when ``|a_i x b_j| < _PARALLEL``, where a face axis covers the pair). So
    ``d = -min_L o(L)``, n is that L pointing from a to b (``sign(L . (c_b - c_a)) L``) and the
    witnesses are

    - a face of a (L = a_i): ``w_b`` the point of b deepest along -n (:func:`_support`: a vertex,
      or the middle of the deepest edge or face on a tie), ``w_a = w_b - d n`` on a's face plane;
      a face of b: the same with the roles swapped, ``w_a`` the point of a farthest along n;
    - two edges (L ~ a_i x b_j): the edge of a along a_i farthest along n and the edge of b along
      b_j deepest along -n; ``w_a`` the point of a's edge closest to b's edge's line (clamped to
      the edge), ``w_b = w_a + d n``.

    Face axes win ties (an edge axis must be ``_EDGE_BIAS`` smaller). The row of the module
    docstring is d's gradient here too: d is a minimum of support functions (envelope theorem),
    and ``w_a``, ``w_b`` lie on the normal line through the support points."""
    tx, ty, tz = world[b, 9] - world[a, 9], world[b, 10] - world[a, 10], world[b, 11] - world[a, 11]
    best, which, nx, ny, nz = np.inf, -1, 0.0, 0.0, 0.0
    for axis in range(15):
        if axis < 6:
            box = a if axis < 3 else b
            lx, ly, lz = world[box, axis % 3], world[box, 3 + axis % 3], world[box, 6 + axis % 3]
            bias = 0.0
        else:
            i, j = (axis - 6) // 3, (axis - 6) % 3
            ax, ay, az = world[a, i], world[a, 3 + i], world[a, 6 + i]
            bx, by, bz = world[b, j], world[b, 3 + j], world[b, 6 + j]
            lx, ly, lz = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
            norm = math.sqrt(lx * lx + ly * ly + lz * lz)
            if norm < _PARALLEL:
                continue
            lx, ly, lz = lx / norm, ly / norm, lz / norm
            bias = _EDGE_BIAS
        overlap = -abs(lx * tx + ly * ty + lz * tz)
        for i in range(3):
            overlap += (table[a, _HX + i] * abs(lx * world[a, i] + ly * world[a, 3 + i] + lz * world[a, 6 + i])
                        + table[b, _HX + i] * abs(lx * world[b, i] + ly * world[b, 3 + i] + lz * world[b, 6 + i]))
        if overlap + bias < best:
            sign = 1.0 if lx * tx + ly * ty + lz * tz >= 0.0 else -1.0
            best, which, nx, ny, nz = overlap, axis, sign * lx, sign * ly, sign * lz
    d = -best
    out[0], out[7], out[8], out[9] = d, nx, ny, nz
    if which < 3:
        _support(table, world, b, nx, ny, nz, -1.0, -1, out, 4)
        for m in range(3):
            out[1 + m] = out[4 + m] - d * out[7 + m]
        return
    if which < 6:
        _support(table, world, a, nx, ny, nz, 1.0, -1, out, 1)
    else:
        i, j = (which - 6) // 3, (which - 6) % 3
        _support(table, world, a, nx, ny, nz, 1.0, i, out, 1)  # the middle of a's edge
        _support(table, world, b, nx, ny, nz, -1.0, j, out, 4)  # the middle of b's edge
        # the point a_mid + s a_i closest to the line b_mid + u b_j: s = (c f - e) / (1 - c^2)
        c = world[a, i] * world[b, j] + world[a, 3 + i] * world[b, 3 + j] + world[a, 6 + i] * world[b, 6 + j]
        e = f = 0.0
        for m in range(3):
            e += world[a, 3 * m + i] * (out[1 + m] - out[4 + m])
            f += world[b, 3 * m + j] * (out[1 + m] - out[4 + m])
        s = min(max((c * f - e) / (1.0 - c * c), -table[a, _HX + i]), table[a, _HX + i])
        for m in range(3):
            out[1 + m] += s * world[a, 3 * m + i]
    for m in range(3):
        out[4 + m] = out[1 + m] + d * out[7 + m]


@njit(forceinline=True, no_cpython_wrapper=True, nogil=True)
def _box_edge(world, src, axis, corner, half):
    """Edge ``corner`` (0..3) along ``axis`` of box ``src`` (half extents ``half``): its middle c and
    half-vector u (world), the edge from c - u to c + u."""
    j, k = (axis + 1) % 3, (axis + 2) % 3
    local_j = half[j] * (1.0 if corner & 1 else -1.0)
    local_k = half[k] * (1.0 if corner & 2 else -1.0)
    cx = world[src, 9] + world[src, j] * local_j + world[src, k] * local_k
    cy = world[src, 10] + world[src, 3 + j] * local_j + world[src, 3 + k] * local_k
    cz = world[src, 11] + world[src, 6 + j] * local_j + world[src, 6 + k] * local_k
    return (cx, cy, cz, world[src, axis] * half[axis], world[src, 3 + axis] * half[axis],
            world[src, 6 + axis] * half[axis])


@njit(forceinline=True, no_cpython_wrapper=True, nogil=True)
def _edge_bound(x, y, z, ux, uy, uz, hx, hy, hz):
    """A lower bound of the distance of the box ``|x_i| <= h_i`` to the edge of middle m = (x, y,
    z) and half-vector u (both in the box's frame): the box's signed distance f is convex, so along
    the edge ``f(m + s u) >= f(m) + s g . u >= f(m) - |g . u|`` with g a subgradient of f at m (the
    unit vector from the box to m outside, the normal of the nearest face inside): nearly f(m) for
    an edge across g, f(m) - |u| at worst."""
    ex, ey, ez = abs(x) - hx, abs(y) - hy, abs(z) - hz
    if ex <= 0.0 and ey <= 0.0 and ez <= 0.0:  # inside: f = the largest e_i, g = that face's normal
        if ex >= ey and ex >= ez:
            return ex - abs(ux)
        return ey - abs(uy) if ey >= ez else ez - abs(uz)
    ex, ey, ez = max(ex, 0.0), max(ey, 0.0), max(ez, 0.0)
    f = math.sqrt(ex * ex + ey * ey + ez * ez)  # > 0; g_i = (|x_i| - h_i)+ sign(x_i) / f
    along = ex * (ux if x >= 0.0 else -ux) + ey * (uy if y >= 0.0 else -uy) + ez * (uz if z >= 0.0 else -uz)
    return f - abs(along) / f


@njit(forceinline=True, no_cpython_wrapper=True, nogil=True)
def box_box(table, world, a, b, out, scratch):
    """Two boxes: ``out`` as in :func:`segment_segment`. Apart, the closest points of two disjoint
    convex polytopes include a point on an edge of one of them (vertex-face, edge-edge; a
    face-face contact contains an edge's point too), so the distance is the smallest of the 24
    edge-to-box distances (:func:`box_segment` with radius 0, exact); when that is <= 0 the boxes
    touch or overlap (then an edge of one meets the other) and :func:`box_penetration` measures the
    depth. Best first: every edge's lower bound (:func:`_edge_bound`, in the other box's frame)
    into ``scratch[64:88]``, then the edges in increasing order of their bounds, measured (~0.1 us
    each) until the next bound is not below the best distance (on the youBot's platform against a
    crate 1 to 3 of the 24); at a tie the edge measured first gives the witness points.
    ``scratch``: >= 96 floats."""
    edge, bounds, frame = scratch[32:42], scratch[64:88], scratch[88:96]
    for which in range(2):  # the edges of src (a, then b) in the frame of box: M = R_box^T R_src, t
        src, box = (a, b) if which == 0 else (b, a)
        for r in range(3):
            for col in range(3):
                frame[3 * r + col] = (world[box, r] * world[src, col] + world[box, 3 + r] * world[src, 3 + col]
                                      + world[box, 6 + r] * world[src, 6 + col])
        dx, dy, dz = world[src, 9] - world[box, 9], world[src, 10] - world[box, 10], world[src, 11] - world[box, 11]
        tx = world[box, 0] * dx + world[box, 3] * dy + world[box, 6] * dz
        ty = world[box, 1] * dx + world[box, 4] * dy + world[box, 7] * dz
        tz = world[box, 2] * dx + world[box, 5] * dy + world[box, 8] * dz
        hx, hy, hz = table[box, _HX], table[box, _HX + 1], table[box, _HX + 2]
        for axis in range(3):
            j, k = (axis + 1) % 3, (axis + 2) % 3
            half, half_j, half_k = table[src, _HX + axis], table[src, _HX + j], table[src, _HX + k]
            ux, uy, uz = frame[axis] * half, frame[3 + axis] * half, frame[6 + axis] * half
            for corner in range(4):
                lj = half_j if corner & 1 else -half_j
                lk = half_k if corner & 2 else -half_k
                bounds[12 * which + 4 * axis + corner] = _edge_bound(
                    tx + frame[j] * lj + frame[k] * lk, ty + frame[3 + j] * lj + frame[3 + k] * lk,
                    tz + frame[6 + j] * lj + frame[6 + k] * lk, ux, uy, uz, hx, hy, hz)
    best = np.inf
    for _ in range(24):
        index, bound = -1, best
        for k in range(24):
            if bounds[k] < bound:
                index, bound = k, bounds[k]
        if index < 0:  # no edge left whose bound is below the best distance
            break
        bounds[index] = np.inf  # measured
        which, axis, corner = index // 12, (index // 4) % 3, index % 4
        src, box = (a, b) if which == 0 else (b, a)
        half = (table[src, _HX], table[src, _HX + 1], table[src, _HX + 2])
        c = _box_edge(world, src, axis, corner, half)
        p = (c[0] - c[3], c[1] - c[4], c[2] - c[5], c[0] + c[3], c[1] + c[4], c[2] + c[5])
        box_segment(table, world, box, p, 0.0, edge, scratch)  # (d, on box, on edge, box -> edge)
        if edge[0] < best:
            best = edge[0]
            for m in range(10):
                out[m] = edge[m]
            if which == 0:  # the edge is on a: make it (d, w_a, w_b, a -> b)
                _flip(out)
    if best <= 0.0:
        box_penetration(table, world, a, b, out)


@njit(forceinline=True, no_cpython_wrapper=True, nogil=True)
def pair_distance(table, world, a, b, out, scratch):
    """Signed distance of shapes a and b (rows of ``table``, world poses in ``world``) into ``out``;
    returns False for a pair that has no compiled distance (coal measures it): a shape of kind
    ``COAL`` (cylinder, mesh) or two planes. Every pair of spheres, capsules and boxes, apart or
    overlapping, and each of them against a plane, is measured here."""
    ka, kb = table[a, KIND], table[b, KIND]
    swapped = ka > kb
    if swapped:
        a, b, ka, kb = b, a, kb, ka
    if kb == COAL or ka == PLANE:
        return False
    if ka == BOX and kb == BOX:
        box_box(table, world, a, b, out, scratch)
    elif ka == BOX:  # against a plane
        box_plane(table, world, a, b, out)
    else:
        p = _segment(table, world, a)
        if kb == BOX:
            box_segment(table, world, b, p, table[a, RADIUS], out, scratch)
            _flip(out)
        elif kb == PLANE:
            segment_plane(p, table[a, RADIUS], world, b, out)
        else:
            segment_segment(p, table[a, RADIUS], _segment(table, world, b), table[b, RADIUS], out)
    if swapped:
        _flip(out)
    return True


@njit(forceinline=True, no_cpython_wrapper=True, nogil=True)
def bound_distance(table, world, a, b):
    """A lower bound of the distance of shapes a and b from their bounding spheres (a plane: its
    half-space; a box: the box itself against the other's bounding sphere, much tighter for a
    flat box such as a mobile platform)."""
    if table[b, KIND] == PLANE:
        a, b = b, a
    if table[a, KIND] == PLANE:
        height = (world[a, 2] * (world[b, 12] - world[a, 9]) + world[a, 5] * (world[b, 13] - world[a, 10])
                  + world[a, 8] * (world[b, 14] - world[a, 11]))
        return height - table[b, BOUND_RADIUS]
    dx, dy, dz = world[b, 12] - world[a, 12], world[b, 13] - world[a, 13], world[b, 14] - world[a, 14]
    bound = math.sqrt(dx * dx + dy * dy + dz * dz) - table[a, BOUND_RADIUS] - table[b, BOUND_RADIUS]
    if table[b, KIND] == BOX:
        a, b = b, a
    if table[a, KIND] == BOX:
        # the other's bounding centre in the box frame: R^T (c - p)
        cx, cy, cz = world[b, 12] - world[a, 9], world[b, 13] - world[a, 10], world[b, 14] - world[a, 11]
        h = (table[a, _HX], table[a, _HX + 1], table[a, _HX + 2])
        inside = _box_sd(world[a, 0] * cx + world[a, 3] * cy + world[a, 6] * cz,
                         world[a, 1] * cx + world[a, 4] * cy + world[a, 7] * cz,
                         world[a, 2] * cx + world[a, 5] * cy + world[a, 8] * cz, h) - table[b, BOUND_RADIUS]
        bound = max(bound, inside)
    return bound


@njit(forceinline=True, no_cpython_wrapper=True, nogil=True)
def gradient_row(joint_a, joint_b, slot, witness_a, witness_b, normal, support, jacobians_t, rows):
    """``rows[slot] = normal . (J_b(w_b) - J_a(w_a))`` (see the module docstring)."""
    nx, ny, nz = normal[slot, 0], normal[slot, 1], normal[slot, 2]
    pax, pay, paz = witness_a[slot, 0], witness_a[slot, 1], witness_a[slot, 2]
    pbx, pby, pbz = witness_b[slot, 0], witness_b[slot, 1], witness_b[slot, 2]
    ax, ay, az = pay * nz - paz * ny, paz * nx - pax * nz, pax * ny - pay * nx  # w_a x n
    bx, by, bz = pby * nz - pbz * ny, pbz * nx - pbx * nz, pbx * ny - pby * nx  # w_b x n
    for k in range(rows.shape[1]):
        on_a, on_b = support[joint_a, k], support[joint_b, k]
        value = 0.0
        if on_a != 0.0 or on_b != 0.0:
            linear = nx * jacobians_t[k, 0] + ny * jacobians_t[k, 1] + nz * jacobians_t[k, 2]
            if on_b != 0.0:
                value += linear + jacobians_t[k, 3] * bx + jacobians_t[k, 4] * by + jacobians_t[k, 5] * bz
            if on_a != 0.0:
                value -= linear + jacobians_t[k, 3] * ax + jacobians_t[k, 4] * ay + jacobians_t[k, 5] * az
        rows[slot, k] = value


@njit(forceinline=True, no_cpython_wrapper=True, nogil=True)
def _claim(value, count, distance):
    """The entry a pair at ``value`` takes: the next free one, else (full) the farthest entry when
    the pair is closer than it; -1 when the pair is not kept."""
    if count < distance.size:
        return count
    slot = 0
    for m in range(1, distance.size):
        if distance[m] > distance[slot]:
            slot = m
    return slot if value < distance[slot] else -1


@njit(cache=CACHE, nogil=True)
def _write(k, entry, slot, table, pairs, support, jacobians_t, slot_pair, distance, witness_a, witness_b, normal,
           rows):
    """Entry ``slot`` = pair ``k`` with ``entry = (d, w_a (3), w_b (3), normal (3))``, and its row."""
    slot_pair[slot] = k
    distance[slot] = entry[0]
    for m in range(3):
        witness_a[slot, m] = entry[1 + m]
        witness_b[slot, m] = entry[4 + m]
        normal[slot, m] = entry[7 + m]
    gradient_row(int(table[pairs[k, PAIR_A], JOINT]), int(table[pairs[k, PAIR_B], JOINT]), slot, witness_a,
                 witness_b, normal, support, jacobians_t, rows)


@njit(forceinline=True, no_cpython_wrapper=True, nogil=True)
def _store(k, entry, count, table, pairs, support, jacobians_t, slot_pair, distance, witness_a, witness_b, normal,
           rows):
    """Keep pair ``k`` with ``entry = (d, w_a (3), w_b (3), normal (3))`` if it is among the closest;
    returns the new count."""
    slot = _claim(entry[0], count, distance)
    if slot < 0:
        return count
    _write(k, entry, slot, table, pairs, support, jacobians_t, slot_pair, distance, witness_a, witness_b, normal,
           rows)
    return count + 1 if slot == count else count


@njit(forceinline=True, no_cpython_wrapper=True, nogil=True)
def _spheres_apart(table, world, a, b, cutoff):
    """True when the bounding spheres of shapes a and b (neither a plane) are ``cutoff`` apart
    or more: ``|c_b - c_a|^2 > (r_a + r_b + cutoff)^2`` (with a relative 1e-9 to spare, so
    rounding never skips a pair that :func:`bound_distance` would keep below ``cutoff``). ~5
    flops, no square root: what rejects most pairs."""
    if table[a, KIND] == PLANE or table[b, KIND] == PLANE:
        return False
    dx, dy, dz = world[b, 12] - world[a, 12], world[b, 13] - world[a, 13], world[b, 14] - world[a, 14]
    reach = table[a, BOUND_RADIUS] + table[b, BOUND_RADIUS] + cutoff
    return dx * dx + dy * dy + dz * dz > reach * reach * (1.0 + 1e-9)


@njit(forceinline=True, no_cpython_wrapper=True, nogil=True)
def _cutoff(detection, d_min, pair_reach, inverse_rate):
    """The distance from which pair p needs no row at any configuration: ``detection``, or, when
    smaller, ``d_min + reach_p / rate``, where its damper asks ``d_dot >= -rate (d - d_min)``
    faster than its reach at every configuration (``pair_reach``: ``reach[nv + p]`` of
    :func:`_refresh_reach`; ``inverse_rate = dt / gain``). With it the bounding spheres alone
    (:func:`_spheres_apart`, no square root) reject the pairs that the reach rejects after
    :func:`bound_distance` (~20 ns a pair): the youBot's self pairs on every tick. A pair whose
    spheres are apart by more than the cutoff (and the 1e-9 spare of :func:`_spheres_apart`, which
    covers the rounding of ``1 / rate``) is one that ``not bound < detection`` or
    ``reach_p < rate (bound - d_min)`` leaves out; at the cutoff itself the reach rule keeps it, and
    so do the spheres. NaN or inf: ``detection``."""
    limit = d_min + pair_reach * inverse_rate
    return limit if limit < detection else detection


@njit(forceinline=True, no_cpython_wrapper=True, nogil=True)
def _out_of_reach(table, world, a, b, bound, support, jacobians_t, speed, margin):
    """True when no v with ``|v_k| <= speed[k]`` changes the distance d of shapes a and b at
    ``margin = gain (bound - d_min) / dt`` [m/s] or faster (``bound``: a lower bound of d): their
    damper ``d_dot >= -gain (d - d_min) / dt`` -- and every corner row of the pair, whose
    distances are d or more -- then holds for every such v.

    Why it is a bound: ``d_dot = n . (v_b(w_b) - v_a(w_a))`` with ``w_b - w_a = d n``; a
    coordinate k that moves both shapes moves them rigidly together (``v_O,k + w_k x p`` on
    both), adding ``n . (w_k x (w_b - w_a)) = 0``; one that moves only shape x adds at most
    ``|v_k| |v_O,k + w_k x w_x| <= speed_k (|v_O,k + w_k x c_x| + |w_k| r_x)``, the witness
    ``w_x`` lying within x's bounding sphere (centre ``c_x``, radius ``r_x``). So
    ``|d_dot| <= sum_k speed_k (...)``, and the pair is out of reach when that sum is below
    ``margin`` (an infinite speed on such a coordinate: never)."""
    if not margin > 0.0:  # (the pair within d_min, or penetrating: always a row)
        return False
    return _pair_reach(table, world, a, b, support, jacobians_t, speed, margin) < margin  # (False for inf, NaN)


@njit(forceinline=True, no_cpython_wrapper=True, nogil=True)
def _pair_reach(table, world, a, b, support, jacobians_t, speed, enough):
    """``sum_k speed_k (|v_O,k + w_k x c_x| + |w_k| r_x)`` over the coordinates k that move only one
    of shapes a and b (x that one): the bound on ``|d_dot|`` of :func:`_out_of_reach`, which holds
    for the distance of any two points of the shapes' bounding spheres [m/s]; the sum stops once
    it reaches ``enough`` (inf: the whole sum)."""
    joint_a, joint_b = int(table[a, JOINT]), int(table[b, JOINT])
    reach = 0.0
    for k in range(speed.size):
        on_a, on_b = support[joint_a, k] != 0.0, support[joint_b, k] != 0.0
        if on_a == on_b:
            continue
        s = a if on_a else b
        wx, wy, wz = jacobians_t[k, 3], jacobians_t[k, 4], jacobians_t[k, 5]
        cx, cy, cz = world[s, 12], world[s, 13], world[s, 14]
        vx = jacobians_t[k, 0] + wy * cz - wz * cy
        vy = jacobians_t[k, 1] + wz * cx - wx * cz
        vz = jacobians_t[k, 2] + wx * cy - wy * cx
        spin = math.sqrt(wx * wx + wy * wy + wz * wz)
        lever = math.sqrt(vx * vx + vy * vy + vz * vz) + spin * table[s, BOUND_RADIUS]
        if lever > 0.0:
            reach += speed[k] * lever
            if not reach < enough:  # (also inf, NaN)
                return reach
    return reach


@njit(forceinline=True, no_cpython_wrapper=True, nogil=True)
def _refresh_reach(levers, speed, reach):
    """``reach[nv + p] = sum_k speed_k levers[p, k]`` (1e-9 relative to spare, so rounding never
    decides a pair :func:`_pair_reach` would keep): pair p's reach at every configuration
    (:func:`wbc.collision.reach.lever_bounds`), formed again only when ``speed`` differs from the
    one it was formed for (``reach[:nv]``; NaN there: never formed)."""
    nv = speed.size
    same = True
    for k in range(nv):
        same &= reach[k] == speed[k]
    if same:
        return
    for p in range(levers.shape[0]):
        total = 0.0
        for k in range(nv):
            if levers[p, k] > 0.0:  # (0 inf is not 0)
                total += speed[k] * levers[p, k]
        reach[nv + p] = total * (1.0 + 1e-9)
    for k in range(nv):  # (not reach[:nv] = speed: numba's slice assignment compiles for ~2 s)
        reach[k] = speed[k]


@njit(forceinline=True, no_cpython_wrapper=True, nogil=True)
def _pair_distances(table, pairs, placements, jacobians_t, support, world, detection, speed, levers, reach, rate,
                    d_min, slot_pair, distance, witness_a, witness_b, normal, rows, pending, scratch):
    """(``speed``: the bound on each |v_k|, empty for none; ``levers``, ``reach``: the
    configuration-independent reach of each pair and its cache (:func:`_refresh_reach`), read
    only with ``speed``; ``rate`` = gain / dt.)"""
    world_poses(table, placements, world)
    nv = speed.size
    if nv > 0:
        _refresh_reach(levers, speed, reach)
    count = 0
    n_pending = 0
    out = scratch[48:58]
    inverse_rate = 1.0 / rate if rate > 0.0 else math.inf  # (rate = gain / dt > 0 from a controller)
    for k in range(pairs.shape[0]):
        a, b = pairs[k, PAIR_A], pairs[k, PAIR_B]
        cutoff = _cutoff(detection, d_min, reach[nv + k], inverse_rate) if nv > 0 else detection
        if _spheres_apart(table, world, a, b, cutoff):
            continue
        bound = bound_distance(table, world, a, b)
        if not bound < detection:
            continue
        if nv > 0:  # out of reach: at every configuration (one comparison), else at this one
            margin = rate * (bound - d_min)
            if reach[nv + k] < margin or _out_of_reach(table, world, a, b, bound, support, jacobians_t, speed, margin):
                continue
        if not pair_distance(table, world, a, b, out, scratch):
            pending[n_pending] = k
            n_pending += 1
        elif out[0] < detection:
            if count < distance.size:  # (written out here, not through _store: half the cost per pair)
                _write(k, out, count, table, pairs, support, jacobians_t, slot_pair, distance, witness_a, witness_b,
                       normal, rows)
                count += 1
            else:  # full: the closest are kept
                count = _store(k, out, count, table, pairs, support, jacobians_t, slot_pair, distance, witness_a,
                               witness_b, normal, rows)
    return count + (distance.size + 1) * n_pending


@declared("int64(float64[:, ::1], int64[:, ::1], float64[:, ::1], float64[:, ::1], float64[:, ::1], "
          "float64[:, ::1], float64, int64[::1], float64[::1], float64[:, ::1], float64[:, ::1], float64[:, ::1], "
          "float64[:, ::1], int64[::1], float64[::1])", cache=CACHE, nogil=True)
def pair_distances(table, pairs, placements, jacobians_t, support, world, detection,
                   slot_pair, distance, witness_a, witness_b, normal, rows, pending, scratch):
    """Every candidate pair within ``detection``: distances, witness points, normals and rows.

    Writes entries 0..count-1 of the output arrays (capacity = their length; when more pairs are
    within ``detection``, the closest are kept) and returns ``count + (capacity + 1) * n_pending``:
    ``pending[:n_pending]`` lists the pairs (indices of ``pairs``) that passed the broad phase
    but have no compiled distance; coal measures them and :func:`insert_pair` adds them.
    ``pending``: one entry per pair; ``scratch``: >= 64 floats.
    """
    return _pair_distances(table, pairs, placements, jacobians_t, support, world, detection, scratch[:0], rows[:0],
                           scratch[:0], 0.0, 0.0, slot_pair, distance, witness_a, witness_b, normal, rows, pending,
                           scratch)


#: ``h`` of an unused row (its ``G`` row is zero): ``0 <= 1`` holds for every v and is never active
INERT = 1.0


@njit(forceinline=True, no_cpython_wrapper=True, nogil=True)
def _damper_rows(count, written, distance, rows, G, h, settings, dt):
    scale = settings[GAIN] / dt
    for i in range(count):
        for k in range(G.shape[1]):
            G[i, k] = -rows[i, k]
        h[i] = scale * (distance[i] - settings[MIN_DISTANCE])
    for i in range(count, min(written, G.shape[0])):
        for k in range(G.shape[1]):
            G[i, k] = 0.0
        h[i] = INERT


@declared("void(int64, int64, float64[::1], float64[:, ::1], float64[:, ::1], float64[::1], float64[::1], float64)",
          cache=CACHE, nogil=True)
def damper_rows(count, written, distance, rows, G, h, settings, dt):
    """The velocity dampers ``-grad d . v <= gain (d - d_min) / dt`` of entries ``0..count-1`` in
    ``G``, ``h`` (``settings = (detection, d_min, gain)``); the rows after them inert (``0 <= 1``):
    written up to ``written`` -- the rows the last tick wrote (its pairs and corner rows): those
    after it are inert already, and only these kernels write them."""
    _damper_rows(count, written, distance, rows, G, h, settings, dt)


#: an end of a capsule closer than this fraction of its segment's length to the pair's witness
#: (across the normal) gets no row of its own: the row would nearly repeat the pair's (two almost
#: parallel rows, a degenerate active set the solvers answer badly: DAQP returned infeasible or
#: rows violated by up to 44 % on random obstacles), and the witness row already models that end
END_ZONE = 0.1
#: an end's row whose cosine with the pair's row exceeds this is left out (for the same reason)
PARALLEL = 1.0 - 1e-3


@njit(forceinline=True, no_cpython_wrapper=True, nogil=True)
def _across(ex, ey, ez, nx, ny, nz):
    """The length of (ex, ey, ez) across the unit normal n."""
    along = nx * ex + ny * ey + nz * ez
    ex, ey, ez = ex - along * nx, ey - along * ny, ez - along * nz
    return math.sqrt(ex * ex + ey * ey + ez * ez)


@njit(forceinline=True, no_cpython_wrapper=True, nogil=True)
def _swept_distance(table, segment, radius, world, other, out, scratch):
    """The distance of the capsule of ``radius`` around ``segment`` (p0, p1: a sphere when they
    are the same point, a box's edge with radius 0) to shape ``other`` into ``out`` as in
    :func:`segment_segment` (a: the capsule); False for a shape measured by coal."""
    kind = table[other, KIND]
    if kind == SPHERE or kind == CAPSULE:
        segment_segment(segment, radius, _segment(table, world, other), table[other, RADIUS], out)
    elif kind == BOX:
        box_segment(table, world, other, segment, radius, out, scratch)
        _flip(out)
    elif kind == PLANE:
        segment_plane(segment, radius, world, other, out)
    else:
        return False
    return True


@njit(forceinline=True, no_cpython_wrapper=True, nogil=True)
def _end_point(table, world, capsule, end):
    """The point at parameter ``end`` in [-1, 1] of ``capsule``'s segment."""
    half = table[capsule, HALF_LENGTH] * end
    return (world[capsule, 9] + world[capsule, 2] * half, world[capsule, 10] + world[capsule, 5] * half,
            world[capsule, 11] + world[capsule, 8] * half)


@njit(forceinline=True, no_cpython_wrapper=True, nogil=True)
def _vertex(world, box, corner, hx, hy, hz):
    """Vertex ``corner`` (0-7: bit k the sign of the box's axis k) of ``box`` (half extents h)."""
    sx = hx if corner & 1 else -hx
    sy = hy if corner & 2 else -hy
    sz = hz if corner & 4 else -hz
    return (world[box, 9] + world[box, 0] * sx + world[box, 1] * sy + world[box, 2] * sz,
            world[box, 10] + world[box, 3] * sx + world[box, 4] * sy + world[box, 5] * sz,
            world[box, 11] + world[box, 6] * sx + world[box, 7] * sy + world[box, 8] * sz)


@njit(forceinline=True, no_cpython_wrapper=True, nogil=True)
def _cannot_tie(segment, witness, away, behind, centre, far):
    """Whether a box's feature ``segment`` (p0, p1; a vertex twice) is certainly too far from the
    other shape to tie with the pair's witness, without its distance: every point of it lies more
    than ``behind`` back along ``away`` (the pair's normal from the box's side) from the plane
    through the ``witness`` (its first 3 floats) -- the other shape lies beyond that plane (both
    convex), so a point p is at least ``d + away . (w - p)`` from it -- or farther than
    ``sqrt(far)`` from ``centre``, the other shape's bounding sphere's centre."""
    wx, wy, wz = witness[0], witness[1], witness[2]
    px, py, pz, qx, qy, qz = segment
    if min(away[0] * (wx - px) + away[1] * (wy - py) + away[2] * (wz - pz),
           away[0] * (wx - qx) + away[1] * (wy - qy) + away[2] * (wz - qz)) > behind:
        return True
    ex, ey, ez = qx - px, qy - py, qz - pz  # the centre's squared distance to the segment
    t = _clamp01(((centre[0] - px) * ex + (centre[1] - py) * ey + (centre[2] - pz) * ez)
                 / max(ex * ex + ey * ey + ez * ez, 1e-300))
    return (px + t * ex - centre[0]) ** 2 + (py + t * ey - centre[1]) ** 2 + (pz + t * ez - centre[2]) ** 2 > far


@njit(forceinline=True, no_cpython_wrapper=True, nogil=True)
def _overhang(table, world, box, capsule, witness, out):
    """Into ``out`` (2): the parameters in (-1, 1) of ``capsule``'s segment (``c + t half axis``)
    where it leaves the slab of the box's feature that holds ``witness`` (a face: the two axes
    along it, an edge: the axis along it), 2.0 where it does not. Where the segment lies (nearly)
    parallel to that face or edge, its distance is nearly flat over the slab and ties between the
    slab's ends: an end of the segment or such an overhang point."""
    half = table[capsule, HALF_LENGTH]
    lo, hi = -1.0, 1.0
    for k in range(3):
        extent = table[box, _HX + k]
        wk = (world[box, k] * (witness[0] - world[box, 9]) + world[box, 3 + k] * (witness[1] - world[box, 10])
              + world[box, 6 + k] * (witness[2] - world[box, 11]))
        if abs(wk) >= extent - 1e-9:  # the witness is on this axis's boundary: not along the feature
            continue
        a = (world[box, k] * (world[capsule, 9] - world[box, 9])
             + world[box, 3 + k] * (world[capsule, 10] - world[box, 10])
             + world[box, 6 + k] * (world[capsule, 11] - world[box, 11]))
        b = half * (world[box, k] * world[capsule, 2] + world[box, 3 + k] * world[capsule, 5]
                    + world[box, 6 + k] * world[capsule, 8])
        if abs(b) < 1e-12:
            continue
        t0, t1 = (-extent - a) / b, (extent - a) / b
        lo, hi = max(lo, min(t0, t1)), min(hi, max(t0, t1))
    out[0] = lo if -1.0 < lo < hi else 2.0
    out[1] = hi if lo < hi < 1.0 else 2.0


@njit(forceinline=True, no_cpython_wrapper=True, nogil=True)
def _parallel(G, a, b):
    """Whether rows ``a`` and ``b`` of ``G`` point the same way to within :data:`PARALLEL`."""
    dot, norm_a, norm_b = 0.0, 0.0, 0.0
    for k in range(G.shape[1]):
        dot += G[a, k] * G[b, k]
        norm_a += G[a, k] * G[a, k]
        norm_b += G[b, k] * G[b, k]
    return dot > 0.0 and dot * dot > PARALLEL * PARALLEL * norm_a * norm_b


@njit(forceinline=True, no_cpython_wrapper=True, nogil=True)
def _tie_row(table, world, segment, radius, other, side, witness, near, d, i, first, row, joint_a, joint_b, support,
             jacobians_t, G, h, scale, d_min, speed, dt, scratch):
    """The damper of the capsule of ``radius`` around ``segment`` (a sphere: a point twice; a box's
    edge: radius 0) of the pair ``i``'s shape on ``side`` (0 for its a) against shape ``other`` in
    row ``row``: 1 if written, 0 if it gets none (no compiled distance, its closest point within
    ``near`` of the pair's ``witness`` across its normal (witness point, normal: 6 floats; ``near``
    < 0: not checked), too far beyond ``d`` or too loose to bind, or the pair's own row to within
    :data:`PARALLEL`), -1 if ``G`` has no row left. A row that points the way of one of
    the pair's tie rows written before it (rows ``first:row``) is one of the two: the tighter one
    is kept, in that earlier row (two vertices of a box's edge along which the base moves; the ends
    of a capsule parallel to a face)."""
    if row >= G.shape[0]:
        return -1
    out = scratch[40:50]
    if not _swept_distance(table, segment, radius, world, other, out, scratch):
        return 0
    gap = out[0]
    if gap - d > speed * dt or scale * (gap - d_min) > speed:
        return 0
    if near >= 0.0 and _across(out[1] - witness[0], out[2] - witness[1], out[3] - witness[2], witness[3], witness[4],
                               witness[5]) <= near:
        return 0
    if side == 1:  # the point is b's
        _flip(out)
    points = scratch[50:59].reshape(3, 3)  # w_a, w_b, normal of the point's pair
    for m in range(3):
        points[0, m], points[1, m], points[2, m] = out[1 + m], out[4 + m], out[7 + m]
    gradient_row(joint_a, joint_b, 0, points[0:1], points[1:2], points[2:3], support, jacobians_t, G[row:row + 1])
    for k in range(G.shape[1]):
        G[row, k] = -G[row, k]
    if _parallel(G, row, i):  # adds no direction to the pair's own row, only degeneracy: inert
        for k in range(G.shape[1]):
            G[row, k] = 0.0
        return 0
    bound = scale * (gap - d_min)
    for earlier in range(first, row):
        if _parallel(G, row, earlier):  # one of the two: the tighter (per unit of row length)
            norm_new, norm_old = 0.0, 0.0
            for k in range(G.shape[1]):
                norm_new += G[row, k] * G[row, k]
                norm_old += G[earlier, k] * G[earlier, k]
            if bound * math.sqrt(norm_old) < h[earlier] * math.sqrt(norm_new):
                for k in range(G.shape[1]):
                    G[earlier, k] = G[row, k]
                h[earlier] = bound
            for k in range(G.shape[1]):
                G[row, k] = 0.0
            return 0
    h[row] = bound
    return 1


@njit(forceinline=True, no_cpython_wrapper=True, nogil=True)
def _corner_rows(table, pairs, world, support, jacobians_t, count, slot_pair, distance, witness_a, witness_b,
                 normal, G, h, settings, dt, speed, bound, corner_slot, scratch):
    """The dampers of the capsule ends and box features that nearly tie with a pair's witness, in rows
    ``count, count + 1, ...`` of ``G``, ``h`` (at most ``corner_slot.size``; the pair of each in
    ``corner_slot``); returns how many. ``scratch``: >= 63 floats.

    Why: where a capsule lies parallel to the other shape's face or edge, or along another capsule,
    its closest point ties between points far apart. Its distance is ``d = min(d_0, d_1, d_inner)``,
    ``d_e`` the distance of the sphere at end e (smooth where the shapes are apart), and its
    first-order change is the minimum over the pieces that tie (Danskin), not the change at the one
    point the distance routine returned. A single row lets the QP turn the witness away while an
    end approaches; the next tick the witness jumps to that end and the command reverses: a
    full-speed two-tick chatter that creeps into the margin (the witness at one end; also with the
    witness inside, when the capsule is nearly parallel: the wrist reversing at 1.57 rad/s, 2.3 mm
    into the margin). So each end of a capsule in a pair gets a damper of its own, with its own
    witness points and normal, and so does, against a box, each point where the segment leaves the
    slab of the witness's face or edge (a capsule lying on a face and overhanging its edge ties
    between an end and the overhang point: :func:`_overhang`), unless the point is the witness
    (within :data:`END_ZONE` of the segment's length, across the normal) or its row is the pair's
    own to within :data:`PARALLEL`::

        d_e_dot = n_e . (J_b(w_b,e) - J_a(w_a,e)) v  >=  -gain (d_e - d_min) / dt

    d_e >= d, so the row is looser than the pair's own the farther the point is; with the witness
    row it is the first-order model of d at the tie.
    ``speed`` [m/s]: a point with ``d_e - d > speed dt`` cannot overtake the witness within a tick,
    one with ``gain (d_e - d_min) / dt > speed`` has a row that never binds: neither gets a row;
    the closest pairs get theirs first. With bounds on the commands (``bound``: ``|v_k| <=
    bound[k]``, empty for none) a pair's own speed is at most twice its reach S
    (:func:`_pair_reach`, which bounds ``|d_dot|`` and every ``|d_e_dot|`` alike): then the gap
    ``d_e - d`` closes by at most ``2 S dt`` in a tick and a row binds only if
    ``gain (d_e - d_min) / dt <= S`` -- both criteria hold for sure, not only for speeds up to
    ``speed``. Penetrating pairs (d <= 0) and ends against a shape
    measured by coal get none.

    A box's closest feature jumps between its vertices and edges as it turns (a platform yawing
    against a wall or a crate: 3.5 mm into the margin in one tick), so a box in a pair gets the
    same rows for its 8 vertices and its 12 edges (each a segment of radius 0: its own closest
    point and normal), with the same criteria. A row that points the way of one of the pair's
    rows written before it (to within :data:`PARALLEL`: a vertex of a level box and the vertex above
    it against a wall, an edge whose closest point is its end) keeps only the tighter of the two:
    parallel rows add no direction, only a degenerate active set."""
    n_rows, scale, d_min = 0, settings[GAIN] / dt, settings[MIN_DISTANCE]
    last, i = -np.inf, -1
    for _ in range(count):  # the pairs in order of distance (ties by entry): the closest get the rows first
        d, nxt = np.inf, -1
        for m in range(count):
            if (distance[m] > last or (distance[m] == last and m > i)) and distance[m] < d:
                d, nxt = distance[m], m
        if nxt < 0:
            break
        i, last = nxt, d
        if not d > 0.0:
            continue
        if scale * (d - d_min) > speed:  # every end is at d or farther: no row binds, here or for the farther pairs
            break
        ends = (pairs[slot_pair[i], PAIR_A], pairs[slot_pair[i], PAIR_B])
        pair_speed = speed
        if bound.size > 0:
            pair_speed = min(speed, 2.0 * _pair_reach(table, world, ends[0], ends[1], support, jacobians_t, bound,
                                                      0.5 * speed))
            if scale * (d - d_min) > pair_speed:  # (the pair's ends cannot bind either)
                continue
        nx, ny, nz = normal[i, 0], normal[i, 1], normal[i, 2]
        joint_a, joint_b = int(table[ends[0], JOINT]), int(table[ends[1], JOINT])
        first = count + n_rows  # the pair's tie rows: from here on
        for side in range(2):
            s = ends[side]
            kind = table[s, KIND]
            if kind != CAPSULE and kind != BOX:
                continue
            # where the witness is (across the normal: a capsule's radius lies along it)
            wx, wy, wz = ((witness_a[i, 0], witness_a[i, 1], witness_a[i, 2]) if side == 0
                          else (witness_b[i, 0], witness_b[i, 1], witness_b[i, 2]))
            zone = (wx, wy, wz, nx, ny, nz)
            other = ends[1 - side]
            if kind == CAPSULE:
                # its ends, and on a box the ends of the stretch that lies over the witness's face or
                # edge (where the segment overhangs it)
                half, radius, features = table[s, HALF_LENGTH], table[s, RADIUS], 4
                ux, uy, uz = world[s, 2] * half, world[s, 5] * half, world[s, 8] * half
                cx, cy, cz = world[s, 9] - wx, world[s, 10] - wy, world[s, 11] - wz
                near = END_ZONE * 2.0 * half  # a point this close to the witness (across n) would repeat its row
                points = scratch[59:63]
                points[0], points[1], points[2], points[3] = -1.0, 1.0, 2.0, 2.0
                if table[other, KIND] == BOX:
                    _overhang(table, world, other, s, witness_b[i] if side == 0 else witness_a[i], points[2:4])
            else:  # a box's vertices and edges: its closest feature jumps between them as it turns
                hx, hy, hz = table[s, _HX], table[s, _HX + 1], table[s, _HX + 2]
                radius, features = 0.0, 20
                near = END_ZONE * 2.0 * min(hx, hy, hz)
                # a feature farther back than this along m (the normal from the box's side) gets no row
                away = (nx, ny, nz) if side == 0 else (-nx, -ny, -nz)
                behind = min(pair_speed * dt, d_min + pair_speed / scale - d)
                # nor one farther than sqrt(far) from the other shape's bounding sphere's centre (a plane has none)
                centre = (world[other, 12], world[other, 13], world[other, 14])
                far = (math.inf if table[other, KIND] == PLANE
                       else (d + behind + table[other, BOUND_RADIUS]) ** 2 * (1.0 + 1e-9))  # (rounding spared)
            for feature in range(features):
                checked = -1.0  # (a point: checked before its distance; an edge: its closest point, after)
                if kind == CAPSULE:
                    t = points[feature]
                    if not -1.0 <= t <= 1.0 or _across(cx + t * ux, cy + t * uy, cz + t * uz, nx, ny, nz) <= near:
                        continue
                    px, py, pz = _end_point(table, world, s, t)
                    segment = (px, py, pz, px, py, pz)
                elif feature < 8:  # vertex `feature`
                    px, py, pz = _vertex(world, s, feature, hx, hy, hz)
                    segment = (px, py, pz, px, py, pz)
                    if (_cannot_tie(segment, zone, away, behind, centre, far)
                            or _across(px - wx, py - wy, pz - wz, nx, ny, nz) <= near):
                        continue
                else:  # 12 edges, 4 along each axis: from the corner with the axis's bit clear
                    axis, edge = (feature - 8) // 4, (feature - 8) % 4
                    low = (edge << 1) if axis == 0 else ((edge & 1) | ((edge & 2) << 1) if axis == 1 else edge)
                    px, py, pz = _vertex(world, s, low, hx, hy, hz)
                    qx, qy, qz = _vertex(world, s, low | (1 << axis), hx, hy, hz)
                    segment = (px, py, pz, qx, qy, qz)
                    if _cannot_tie(segment, zone, away, behind, centre, far):
                        continue
                    checked = near
                if n_rows == corner_slot.size:  # the budget is spent: no row is written past it
                    return n_rows
                added = _tie_row(table, world, segment, radius, other, side, zone, checked, d, i, first,
                                 count + n_rows, joint_a, joint_b, support, jacobians_t, G, h, scale, d_min,
                                 pair_speed, dt, scratch)
                if added < 0:
                    return n_rows
                if added:
                    corner_slot[n_rows] = i
                    n_rows += 1
    return n_rows


@declared("int64(float64[:, ::1], int64[:, ::1], float64[:, ::1], float64[:, ::1], float64[:, ::1], int64, "
          "int64[::1], float64[::1], float64[:, ::1], float64[:, ::1], float64[:, ::1], float64[:, ::1], "
          "float64[::1], float64[::1], float64, float64, float64[::1], int64[::1], float64[::1])", cache=CACHE,
          nogil=True)
def corner_rows(table, pairs, world, support, jacobians_t, count, slot_pair, distance, witness_a, witness_b,
                normal, G, h, settings, dt, speed, bound, corner_slot, scratch):
    """:func:`_corner_rows` (the tie rows of capsule ends and box features), compiled: after the coal path's
    rows."""
    return _corner_rows(table, pairs, world, support, jacobians_t, count, slot_pair, distance, witness_a, witness_b,
                        normal, G, h, settings, dt, speed, bound, corner_slot, scratch)


#: slots of the tick vector of :func:`avoidance_rows`: the tick [s] and the corner speed [m/s]
DT, SPEED = 0, 1


@njit(cache=CACHE, nogil=True)
def avoidance_op(table, pairs, placements, jacobians_t, support, world, index, distance, points, rows, scratch, G, h,
                 settings, tick, corner_slot, speed, counts, levers, reach, shapes, candidates, joints, nv, capacity,
                 pending, inequalities, corners, dt):
    """:func:`avoidance_rows` as an op of the tick program (:class:`wbc.runtime.compiled_op.CompiledOp`,
    declared by :func:`wbc.collision.avoidance.avoidance_op`): ``dt`` into ``tick``, then (the entries,
    the corner rows) into ``counts``. Only for pairs that all have a compiled distance (the op is not
    used otherwise), so nothing is left for coal. The int operands size the arrays only.

    The work of both, compiled once: :func:`avoidance_rows` calls this function, and the op's
    callback calls it directly (it had called :func:`avoidance_rows`, twenty arrays and numbers
    through one more call: ~0.3 us a tick, an op without pairs 0.42 -> 0.14 us in the tick program)."""
    tick[DT] = dt
    entries = distance.size  # (the capacity; the int operands are not read)
    slot_pair, waiting = index[:entries], index[entries:]
    witness_a, witness_b, normal = points[0], points[1], points[2]
    packed = _pair_distances(table, pairs, placements, jacobians_t, support, world, settings[DETECTION], speed,
                             levers, reach, settings[GAIN] / dt, settings[MIN_DISTANCE], slot_pair, distance,
                             witness_a, witness_b, normal, rows, waiting, scratch)
    if packed > entries:
        return packed, 0
    _damper_rows(packed, counts[0] + counts[1], distance, rows, G, h, settings, dt)
    corners = _corner_rows(table, pairs, world, support, jacobians_t, packed, slot_pair, distance, witness_a,
                           witness_b, normal, G, h, settings, dt, tick[SPEED], speed, corner_slot, scratch)
    counts[0], counts[1] = packed, corners
    return packed, corners


@declared("UniTuple(int64, 2)(float64[:, ::1], int64[:, ::1], float64[:, ::1], float64[:, ::1], float64[:, ::1], "
          "float64[:, ::1], int64[::1], float64[::1], float64[:, :, ::1], float64[:, ::1], float64[::1], "
          "float64[:, ::1], float64[::1], float64[::1], float64[::1], int64[::1], float64[::1], int64[::1], "
          "float64[:, ::1], float64[::1])", cache=CACHE, nogil=True)
def avoidance_rows(table, pairs, placements, jacobians_t, support, world, index, distance, points, rows, scratch,
                   G, h, settings, tick, corner_slot, speed, counts, levers, reach):
    """A tick's rows in one call: :func:`pair_distances` and, when no pair waits for coal,
    :func:`damper_rows` and :func:`corner_rows` after them. Fewer arguments than those (each costs
    the call ~40 ns): ``index`` = (the entries' pairs (capacity), pending (one per pair)), ``points``
    = (witness_a, witness_b, normal), ``settings`` = (detection, d_min, gain), ``tick`` = (dt,
    corner speed). ``speed``: ``|v_k| <= speed[k]`` for every command (``inf``: unbounded); a
    pair that no such v could bring to its damper's bound gets no entry (:func:`_out_of_reach`;
    first at every configuration: ``levers`` (pairs x nv, :func:`wbc.collision.reach.lever_bounds`)
    and ``reach`` (nv + pairs, NaN at first), the cache of :func:`_refresh_reach`), and
    a pair's tie rows use twice its reach as their speed when that is below the corner speed
    (:func:`_corner_rows`).
    ``counts``: (entries, corner rows) of the rows last written, read (the rows after them are
    inert: :func:`damper_rows` leaves them) and, when rows are written, set to this tick's.
    Returns (what :func:`pair_distances` returns, the number of corner rows)."""
    size = distance.size  # (the op's int operands size its arrays only)
    return avoidance_op(table, pairs, placements, jacobians_t, support, world, index, distance, points, rows, scratch,
                        G, h, settings, tick, corner_slot, speed, counts, levers, reach, size, size, size, size, size,
                        size, size, size, tick[DT])


@declared("int64(int64, float64[::1], int64, float64[:, ::1], int64[:, ::1], float64[:, ::1], float64[:, ::1], "
          "int64[::1], float64[::1], float64[:, ::1], float64[:, ::1], float64[:, ::1], float64[:, ::1])",
          cache=CACHE, nogil=True)
def insert_pair(k, entry, count, table, pairs, support, jacobians_t, slot_pair, distance, witness_a, witness_b,
                normal, rows):
    """Add pair ``k`` measured by coal (``entry`` as in :func:`segment_segment`) to the first
    ``count`` entries, keeping the closest; returns the new count."""
    return _store(k, entry, count, table, pairs, support, jacobians_t, slot_pair, distance, witness_a, witness_b,
                  normal, rows)


@declared("float64(float64[:, ::1], float64[:, ::1], int64, int64, float64[::1], float64[::1])", cache=CACHE,
          nogil=True)
def distance_of(table, world, a, b, out, scratch):
    """The signed distance of one pair (world poses already in ``world``) into ``out``; NaN when the
    pair has no compiled distance. For the tests (``scratch``: at least ``SCRATCH`` floats)."""
    if scratch.shape[0] < SCRATCH or out.shape[0] < 10:
        raise ValueError("distance_of: out needs 10 floats, scratch layout.SCRATCH")
    if pair_distance(table, world, a, b, out, scratch):
        return out[0]
    return np.nan


@declared("float64(float64[:, ::1], float64[:, ::1], int64, int64)", cache=CACHE, nogil=True)
def bound_of(table, world, a, b):
    """:func:`bound_distance`, compiled for the tests."""
    return bound_distance(table, world, a, b)
