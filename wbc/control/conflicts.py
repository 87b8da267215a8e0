"""Which constraints conflict, when a tick's QP had no solution (``Controller.last.conflicts``).

The tick's constraints -- the merged bounds ``lb <= v <= ub`` (each labelled by the constraint
that set it), the inequality rows ``G v <= h`` and the equality rows ``A v = b`` -- are written
as one system of rows ``g_i . x <= h_i`` (an equality as two rows; every row scaled to a unit
normal, so violations compare in [unit/s]). Its least-squares relaxation::

    min  eps/2 |x|^2 + 1/2 |s|^2    s.t.   g_i . x - s_i <= h_i,   s >= 0

has ``s = 0`` exactly when the system is feasible. Otherwise its slacks are a Farkas certificate
(as ``eps -> 0``, ``sum_i s_i g_i = 0`` while ``sum_i s_i h_i < 0``): the rows with a slack form
an infeasible subsystem. A deletion filter then drops each row whose removal leaves the rest
infeasible (each check one DAQP solve), leaving an irreducible infeasible subsystem: every
named constraint takes part in the conflict, and removing any one of them resolves it. It is
minimal, not necessarily the smallest such set.

For a controller in the reduced form (``reduced=True``) the rows are mapped through the input
map, ``x = u`` and ``v = S(q) u``: the no-slip rows hold by construction there and are not named.
Computed only when read, on ticks that did not succeed; a few small QPs.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from .tick_buffers import TickBuffers

#: relaxation slack [unit/s] above which a row counts as violated
SLACK_TOLERANCE = 1e-7
#: weight of ``|x|^2`` in the relaxation (keeps its Hessian positive definite)
_EPS = 1e-9
_INFEASIBLE = -1  # DAQP's exit flag


def find_conflicts(buffers: TickBuffers) -> list[str]:
    """Labels of an irreducible set of this tick's constraints that cannot hold together
    (``[]`` when they can, or when the tick's data is not finite)."""
    rows, bounds, labels = _system(buffers)
    if not (np.all(np.isfinite(rows)) and not np.any(np.isnan(bounds))):
        return []
    violated = _violated(rows, bounds)
    if violated.size == 0 or not _infeasible(rows[violated], bounds[violated]):
        return []
    kept = list(violated)
    for row in list(kept):
        trial = [i for i in kept if i != row]
        if trial and _infeasible(rows[trial], bounds[trial]):
            kept = trial
    return list(dict.fromkeys(labels[i] for i in kept))  # an equality's two rows, named once


def _system(buffers: TickBuffers) -> tuple[NDArray[np.float64], NDArray[np.float64], list[str]]:
    """The tick's constraints as unit rows ``g_i . x <= h_i`` and their labels."""
    qp, layout = buffers.qp, buffers.constraints
    n = qp.n
    identity = np.eye(n)
    pieces: list[NDArray[np.float64]] = []
    limits: list[NDArray[np.float64]] = []
    labels: list[str] = []
    for side, merged, sign in ((0, qp.ub, 1.0), (1, qp.lb, -1.0)):
        for j in np.flatnonzero(np.isfinite(merged)):
            pieces.append(sign * identity[j])
            limits.append(np.array([sign * merged[j]]))
            labels.append(_bound_label(buffers, side, int(j), float(merged[j])))
    row_labels = layout.row_labels
    if qp.n_ineq:
        pieces += list(qp.G)
        limits.append(qp.h.copy())
        labels += row_labels[:qp.n_ineq]
    if qp.n_eq:
        pieces += list(qp.A) + list(-qp.A)
        limits += [qp.b.copy(), -qp.b]
        labels += 2 * row_labels[qp.n_ineq:]
    rows = np.array(pieces, dtype=float).reshape(-1, n)
    h = np.concatenate(limits) if limits else np.zeros(0)
    if buffers.reduction is not None:  # over the real inputs: v = S u
        rows = rows @ buffers.input_map
    norms = np.linalg.norm(rows, axis=1)
    scale = np.where(norms > 0.0, 1.0 / np.where(norms > 0.0, norms, 1.0), 1.0)
    return rows * scale[:, None], h * scale, labels


def _bound_label(buffers: TickBuffers, side: int, j: int, value: float) -> str:
    """The label of the constraint whose bound the merged bound ``value`` of coordinate ``j`` is
    (hard constraints first: a soft bound clipped into a hard one is the hard one's)."""
    policy, layout = buffers.bounds, buffers.constraints
    for k in range(policy.bounds.shape[0]):
        if policy.bounds[k, side, j] == value:
            return layout.bound_labels[k][side * buffers.nv + j]
    return layout.bound_labels[0][side * buffers.nv + j]


def _violated(rows: NDArray[np.float64], h: NDArray[np.float64]) -> NDArray[np.intp]:
    """Indices of the rows with a slack in the least-squares relaxation (module docstring)."""
    import daqp

    m, n = rows.shape
    hessian = np.diag(np.concatenate([np.full(n, _EPS), np.ones(m)]))
    constraints = np.hstack([rows, -np.eye(m)])
    upper = np.concatenate([np.full(n + m, np.inf), h])
    lower = np.concatenate([np.full(n, -np.inf), np.zeros(m), np.full(m, -np.inf)])
    z, _, exitflag, _ = daqp.solve(hessian, np.zeros(n + m), constraints, upper, lower,
                                   np.zeros(n + 2 * m, dtype=np.int32))
    if exitflag < 1 or not np.all(np.isfinite(z)):
        return np.zeros(0, dtype=np.intp)
    return np.flatnonzero(z[n:] > SLACK_TOLERANCE)


def _infeasible(rows: NDArray[np.float64], h: NDArray[np.float64]) -> bool:
    """Whether DAQP proves ``rows x <= h`` infeasible."""
    import daqp

    m, n = rows.shape
    _, _, exitflag, _ = daqp.solve(np.eye(n), np.zeros(n), np.ascontiguousarray(rows), np.asarray(h, dtype=float),
                                   np.full(m, -np.inf), np.zeros(m, dtype=np.int32))
    return bool(exitflag == _INFEASIBLE)
