"""Compiled (numba) kernels of :class:`wbc.collision.footprint.BaseFootprintAvoidance`: a uniform
grid over 2-D obstacle points, and the tick's velocity-damper rows of the base footprint.

**Grid** (:func:`build_grid`, once per scan): the points are bucketed into square cells of side
``cell`` over their bounding box (a counting sort: ``O(N)``, no allocation); ``cell_start[c] ..
cell_start[c + 1]`` are the points of cell ``c = iy * nx + ix`` in ``ordered``. ``meta = (x0, y0,
cell, nx, ny)``. When the box would need more cells than ``cell_start`` holds, the cell side is
doubled until it fits.

**Rows** (:func:`footprint_rows`, every tick): only the cells within ``detection`` of the footprint's
bounding circle are visited (cost independent of the number of points far away). For each point p
(world) and the chassis pose (x, y, theta): ``p_b = R(theta)^T (p - (x, y))``, its signed distance d
to the footprint polygon (< 0 inside), the closest boundary point c and the unit normal
``n = grad_{p_b} d``. Each point within ``detection`` falls into one of ``capacity`` angular
sectors about the footprint's centroid; the closest point of each sector gets that sector's row::

    -d_dot = (R n) . (xdot, ydot) + omega (p_b x n)  <=  gain (d - min_distance) / dt

(``turns = 0``: a chassis that keeps its orientation, the omega column is 0). Empty sectors are
inert rows: ``G = 0``, ``h = INERT``.

Cached like :mod:`wbc.collision.kernels` (one source stamp for the package's kernel files).
"""

from __future__ import annotations

import math
from pathlib import Path

from numba import carray, njit

from ..runtime.kernels import _cache
from ..runtime.kernels._lazy import declared
from ..runtime.kernels.tick import _float64_at, _int64_at
from .avoidance import INERT  # the h of an inert row
from .layout import GRID_CELL_START, GRID_CELLS, GRID_ORDERED, GRID_POINTS

CACHE = _cache.prepare(Path(__file__).parent, ("kernels", "footprint_kernels"), cold=("footprint_kernels",)) is not None

#: columns of one sector's record: distance, normal (2), point in the base frame (2), point index
BEST_COLUMNS = 6


@njit("int64(float64[:, ::1], float64[:, ::1], int64, float64, int64[::1], int64[::1], float64[:, ::1], float64[::1])",
      cache=CACHE, nogil=True)
def build_grid(fixed, scan, n_scan, cell, cell_of, cell_start, ordered, meta):
    """Bucket ``fixed`` and ``scan[:n_scan]`` into the grid; returns the number of points, or
    ``-(i + 1)`` when scan point i is not finite (then nothing is written)."""
    n_fixed = fixed.shape[0]
    total = n_fixed + n_scan
    for i in range(n_scan):
        if not (math.isfinite(scan[i, 0]) and math.isfinite(scan[i, 1])):
            return -(i + 1)
    if total == 0:
        meta[0], meta[1], meta[2], meta[3], meta[4] = 0.0, 0.0, cell, 0.0, 0.0
        return 0
    x0 = y0 = math.inf
    x1 = y1 = -math.inf
    for i in range(total):
        px, py = (fixed[i, 0], fixed[i, 1]) if i < n_fixed else (scan[i - n_fixed, 0], scan[i - n_fixed, 1])
        x0, x1, y0, y1 = min(x0, px), max(x1, px), min(y0, py), max(y1, py)
    max_cells = cell_start.shape[0] - 1
    # the spans in cells from half spans and half cells (exact halvings: points 1e308 apart do not
    # overflow), compared as floats before they become ints (numba's math.floor returns an int64:
    # beyond its range, inf included, the conversion is undefined; int64 products wrapped round)
    half_x, half_y = 0.5 * x1 - 0.5 * x0, 0.5 * y1 - 0.5 * y0
    while True:
        across, along = half_x / (0.5 * cell), half_y / (0.5 * cell)
        if across < max_cells and along < max_cells:
            nx, ny = math.floor(across) + 1, math.floor(along) + 1
            if nx * ny <= max_cells:
                break
        cell *= 2.0
    cells = nx * ny
    for c in range(cells + 1):
        cell_start[c] = 0
    for i in range(total):
        px, py = (fixed[i, 0], fixed[i, 1]) if i < n_fixed else (scan[i - n_fixed, 0], scan[i - n_fixed, 1])
        ix = min(int((0.5 * px - 0.5 * x0) / (0.5 * cell)), nx - 1)
        iy = min(int((0.5 * py - 0.5 * y0) / (0.5 * cell)), ny - 1)
        c = iy * nx + ix
        cell_of[i] = c
        cell_start[c + 1] += 1
    for c in range(cells):
        cell_start[c + 1] += cell_start[c]
    for i in range(total):  # scatter, cell_start[c] advancing to the cell's end ...
        c = cell_of[i]
        k = cell_start[c]
        ordered[k, 0], ordered[k, 1] = ((fixed[i, 0], fixed[i, 1]) if i < n_fixed
                                        else (scan[i - n_fixed, 0], scan[i - n_fixed, 1]))
        cell_start[c] = k + 1
    for c in range(cells, 0, -1):  # ... then shifted back to its start
        cell_start[c] = cell_start[c - 1]
    cell_start[0] = 0
    meta[0], meta[1], meta[2], meta[3], meta[4] = x0, y0, cell, float(nx), float(ny)
    return total


#: columns of an edge of the footprint (:func:`edge_table`): start (2), direction e (2), 1 / (e . e),
#: e_x / e_y (the crossing test; 0 for a horizontal edge, which never crosses)
EDGE_COLUMNS = 6


@njit("void(float64[:, ::1], float64[:, ::1])", cache=CACHE, nogil=True)
def edge_table(vertices, edges):
    """``edges[i]`` of the edge from vertex i to vertex i + 1 (cyclic), see :data:`EDGE_COLUMNS`."""
    m = vertices.shape[0]
    for i in range(m):
        j = i + 1 if i + 1 < m else 0
        ex, ey = vertices[j, 0] - vertices[i, 0], vertices[j, 1] - vertices[i, 1]
        edges[i, 0], edges[i, 1], edges[i, 2], edges[i, 3] = vertices[i, 0], vertices[i, 1], ex, ey
        edges[i, 4] = 1.0 / (ex * ex + ey * ey)
        edges[i, 5] = ex / ey if ey != 0.0 else 0.0


@njit(forceinline=True, no_cpython_wrapper=True, nogil=True)
def signed_distance(px, py, edges):
    """Signed distance of the point (px, py) to the simple polygon of ``edges`` (:func:`edge_table`
    of its counter-clockwise vertices; < 0 inside), the closest boundary point and the unit normal
    ``grad d``: ``(d, cx, cy, nx, ny)``."""
    best = math.inf
    cx = cy = 0.0
    edge = 0
    inside = False
    for i in range(edges.shape[0]):
        ax, ay, ex, ey = edges[i, 0], edges[i, 1], edges[i, 2], edges[i, 3]
        t = ((px - ax) * ex + (py - ay) * ey) * edges[i, 4]
        t = 0.0 if t < 0.0 else (1.0 if t > 1.0 else t)
        qx, qy = ax + t * ex, ay + t * ey
        dist2 = (px - qx) * (px - qx) + (py - qy) * (py - qy)
        if dist2 < best:
            best, cx, cy, edge = dist2, qx, qy, i
        if (ay > py) != (ay + ey > py) and px < ax + (py - ay) * edges[i, 5]:
            inside = not inside
    dist = math.sqrt(best)
    if dist > 1e-12:
        nx, ny = (px - cx) / dist, (py - cy) / dist
        if inside:
            return -dist, cx, cy, -nx, -ny
        return dist, cx, cy, nx, ny
    length = math.sqrt(edges[edge, 2] * edges[edge, 2] + edges[edge, 3] * edges[edge, 3])
    return 0.0, cx, cy, edges[edge, 3] / length, -edges[edge, 2] / length  # on the boundary: the edge's normal


def diamond_angle(x: float, y: float) -> float:
    """A monotone stand-in for the angle of (x, y) from -pi, in [0, 4): the angle of (-x, -y) in
    [0, 2 pi) mapped onto the diamond ``|x| + |y| = 1`` (no trigonometry)."""
    x, y = -x, -y
    if y >= 0.0:
        return y / (x + y) if x >= 0.0 else 1.0 - x / (y - x)
    return 2.0 - y / (-x - y) if x < 0.0 else 3.0 + x / (x - y)


diamond = njit(forceinline=True, no_cpython_wrapper=True, nogil=True)(diamond_angle)


@njit(forceinline=True, no_cpython_wrapper=True, nogil=True)
def _floor_within(x, low, high):
    """``floor(x)`` clamped to [low, high] (ints) before it becomes an int: a float beyond int64 (a
    base ~1e19 cells off the grid, an inf) converts to nothing defined."""
    if not x > low:
        return low
    if x >= high:
        return high
    return int(math.floor(x))


@njit(forceinline=True, no_cpython_wrapper=True, nogil=True)
def _footprint_rows(ordered, cell_start, meta, n_points, edges, shape, pose, turns, settings, dt, columns, sectors,
                    best, G, h):
    """:func:`footprint_rows`' work, inlined into it and into the tick program's op
    (:func:`footprint_op`): the op makes no call of its own (a call of the declared kernel, with
    its arrays, cost the collision op ~0.3 us a tick)."""
    detection, min_distance, gain = settings[0], settings[1], settings[2]
    capacity = best.shape[0]
    for k in range(capacity):
        best[k, 0] = math.inf
    c, s = math.cos(pose[2]), math.sin(pose[2])
    if n_points > 0:
        reach = shape[2] + detection  # points farther from the centroid are farther than detection
        centre_x = pose[0] + c * shape[0] - s * shape[1]
        centre_y = pose[1] + s * shape[0] + c * shape[1]
        x0, y0, cell = meta[0], meta[1], meta[2]
        nx, ny = int(meta[3]), int(meta[4])
        ix0 = _floor_within((centre_x - reach - x0) / cell, 0, nx)  # (a base far off the grid: empty ranges)
        ix1 = _floor_within((centre_x + reach - x0) / cell, -1, nx - 1)
        iy0 = _floor_within((centre_y - reach - y0) / cell, 0, ny)
        iy1 = _floor_within((centre_y + reach - y0) / cell, -1, ny - 1)
        for iy in range(iy0, iy1 + 1):
            for ix in range(ix0, ix1 + 1):
                cell_index = iy * nx + ix
                for i in range(cell_start[cell_index], cell_start[cell_index + 1]):
                    wx, wy = ordered[i, 0] - pose[0], ordered[i, 1] - pose[1]
                    rx, ry = ordered[i, 0] - centre_x, ordered[i, 1] - centre_y
                    if rx * rx + ry * ry > reach * reach:
                        continue
                    bx, by = c * wx + s * wy, -s * wx + c * wy  # p_b = R^T (p - (x, y))
                    d, _, _, gx, gy = signed_distance(bx, by, edges)
                    if d >= detection:
                        continue
                    if bx == shape[0] and by == shape[1]:
                        k = 0  # the centroid itself: any sector
                    else:  # the sector of the angle: sectors[k] <= its diamond angle < sectors[k + 1]
                        angle = diamond(bx - shape[0], by - shape[1])
                        low, high = 0, capacity
                        while high - low > 1:
                            middle = (low + high) // 2
                            if sectors[middle] <= angle:
                                low = middle
                            else:
                                high = middle
                        k = low
                    if d < best[k, 0]:
                        best[k, 0], best[k, 1], best[k, 2], best[k, 3], best[k, 4] = d, gx, gy, bx, by
                        best[k, 5] = i
    active = 0
    jx, jy, jh = columns[0], columns[1], columns[2]
    for k in range(capacity):
        d = best[k, 0]
        if d < detection:
            gx, gy, bx, by = best[k, 1], best[k, 2], best[k, 3], best[k, 4]
            G[k, jx] = c * gx - s * gy  # R n
            G[k, jy] = s * gx + c * gy
            G[k, jh] = turns * (bx * gy - by * gx)  # p_b x n
            h[k] = gain * (d - min_distance) / dt
            active += 1
        else:
            G[k, jx] = G[k, jy] = G[k, jh] = 0.0
            h[k] = INERT
    return active


@declared("int64(float64[:, ::1], int64[::1], float64[::1], int64, float64[:, ::1], float64[::1], float64[::1], "
          "float64, float64[::1], float64, int64[::1], float64[::1], float64[:, ::1], float64[:, :], float64[:])",
          cache=CACHE, nogil=True)
def footprint_rows(ordered, cell_start, meta, n_points, edges, shape, pose, turns, settings, dt, columns, sectors,
                   best, G, h):
    """This tick's rows (one per sector, see the module docstring); returns the number of sectors
    with a point within the detection distance. ``edges``: the footprint's :func:`edge_table`;
    ``shape = (centroid x, y, bounding radius about it)`` of the footprint; ``pose = (x, y, theta)``
    of the chassis; ``settings = (detection, min_distance, gain)``; ``columns`` the velocity indices
    of (x, y, heading); ``sectors`` the diamond angles (:func:`diamond_angle`) of the sector
    boundaries ``-pi + 2 pi k / capacity``; ``best`` (capacity x :data:`BEST_COLUMNS`) receives each
    sector's closest point."""
    return _footprint_rows(ordered, cell_start, meta, n_points, edges, shape, pose, turns, settings, dt, columns,
                           sectors, best, G, h)


@njit(cache=CACHE, nogil=True)
def footprint_op(grid, meta, edges, shape, q, pose, settings, columns, sectors, best, G, h, vertices, capacity, nv,
                 nq, dt):
    """:func:`footprint_rows` as an op of the tick program (:class:`wbc.runtime.compiled_op.CompiledOp`,
    declared by :func:`wbc.collision.footprint.footprint_op`): the chassis pose from ``q`` (the
    program's configuration) at ``columns`` (x, y, heading), its heading times ``pose[3]`` (1, or 0
    for a synchro drive's chassis), into ``pose[:3]``; the points through ``grid`` (addresses and
    counts, :data:`wbc.collision.layout.GRID_ORDERED` ...: read every tick, so a new scan's buffers
    are the ones used). The int operands size the arrays only."""
    pose[0], pose[1], pose[2] = q[columns[0]], q[columns[1]], q[columns[2]] * pose[3]
    n_points = grid[GRID_POINTS]
    ordered = carray(_float64_at(grid[GRID_ORDERED]), (max(n_points, 1), 2))
    cell_start = carray(_int64_at(grid[GRID_CELL_START]), (grid[GRID_CELLS],))
    _footprint_rows(ordered, cell_start, meta, n_points, edges, shape, pose[:3], pose[3], settings, dt, columns,
                    sectors, best, G, h)
