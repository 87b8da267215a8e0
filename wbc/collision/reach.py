"""Configuration-independent bounds of how fast a joint velocity coordinate moves a shape: the
first test of :func:`wbc.collision.kernels._out_of_reach`, decided by one comparison per pair.

A pair (a, b) is out of reach when no command with ``|v_k| <= speed_k`` changes its distance at
``margin = gain (bound - d_min) / dt`` or faster; the kernel's bound on ``|d_dot|`` is, this tick::

    S(q) = sum_k speed_k (|v_O,k + w_k x c_x| + |w_k| r_x)

over the coordinates k that move only one shape x of the pair (bounding sphere centre ``c_x``,
radius ``r_x``). :func:`lever_bounds` gives, once per pair and coordinate, a number ``L`` with
``|v_O,k + w_k x c_x| + |w_k| r_x <= L`` at *every* configuration, so ``sum_k speed_k L < margin``
decides most pairs before ``S(q)`` (a loop over the coordinates, two square roots each) is formed.

Why it is a bound. Let J be the joint of coordinate k, ``o_J`` its origin, ``S_k = (s_lin, s_ang)``
its motion subspace column in J's frame. The velocity of the world point ``c_x`` that coordinate
k gives at unit speed is ``R_J (s_lin + s_ang x (c_x - o_J)_J)``, so::

    |v_O,k + w_k x c_x| + |w_k| r_x <= |s_lin| + |s_ang| (|c_x - o_J| + r_x).

``S_k`` is constant for the joints of :data:`CONSTANT_SUBSPACE` (revolute, prismatic, planar,
free-flyer, spherical, translation). ``|c_x - o_J|`` is bounded by the chain: every joint i after
J down to x's joint whose transform is a pure rotation about its own origin (:data:`ROTATIONS`)
keeps ``|o_i - o_parent(i)| = |t_i|`` (its placement's translation) whatever the configuration, so::

    |c_x - o_J| <= sum_i |t_i| + |c_x in the frame of x's joint|

(J's own motion moves ``o_J`` and ``c_x`` together). Any other joint on that path, or a joint of
another kind for J (helical, mimic, spherical ZYX ...), gives ``L = inf``: the pair is then
decided by ``S(q)``, as without these bounds.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from .layout import BOUND_CENTER, BOUND_RADIUS, JOINT, PAIR_A, PAIR_B, ROTATION, TRANSLATION

_REVOLUTE = ("RX", "RY", "RZ", "RevoluteUnaligned", "RUBX", "RUBY", "RUBZ", "RevoluteUnboundedUnaligned")
#: joints whose transform is a rotation about their origin at every configuration
ROTATIONS = frozenset(f"JointModel{name}" for name in (*_REVOLUTE, "Spherical", "SphericalZYX"))
#: joints whose motion subspace, in their own frame, is the same at every configuration
CONSTANT_SUBSPACE = frozenset(f"JointModel{name}" for name in (
    *_REVOLUTE, "PX", "PY", "PZ", "PrismaticUnaligned", "Planar", "FreeFlyer", "Spherical", "Translation"))


def lever_bounds(model: pin.Model, table: NDArray[np.float64], pairs: NDArray[np.int64],
                 support: NDArray[np.float64]) -> NDArray[np.float64]:
    """``L[p, k]``: for pair p (rows of ``pairs`` into the shape ``table``) and velocity coordinate k
    that moves exactly one of its shapes (``support[joint, k] != 0``, :func:`wbc.collision.distances._support`),
    a bound of ``|v_O,k + w_k x c| + |w_k| r`` [m per unit of v_k] over every configuration (c, r:
    that shape's bounding sphere); 0 for the coordinates that move both shapes or neither; ``inf``
    where the chain gives no such bound (see the module docstring). The bound depends on the
    shape and the coordinate only: it is formed once per shape of the pairs, then picked per pair."""
    owner = np.zeros(model.nv, dtype=np.int64)
    for joint in range(1, model.njoints):
        owner[model.idx_vs[joint]:model.idx_vs[joint] + model.nvs[joint]] = joint
    subspace = _subspace_norms(model)
    a, b = pairs[:, PAIR_A].astype(np.int64), pairs[:, PAIR_B].astype(np.int64)
    shape_levers = np.zeros((table.shape[0], model.nv))
    for shape in np.unique(np.concatenate([a, b])):
        joint = int(table[shape, JOINT])
        for k in np.flatnonzero(support[joint]):
            linear, angular = subspace[k]
            shape_levers[shape, k] = linear if angular == 0.0 else linear + angular * (
                _chain_length(model, int(owner[k]), joint, table, int(shape)) + table[shape, BOUND_RADIUS])
    on_a, on_b = support[table[a, JOINT].astype(np.int64)] != 0.0, support[table[b, JOINT].astype(np.int64)] != 0.0
    return np.where(on_a & ~on_b, shape_levers[a], np.where(on_b & ~on_a, shape_levers[b], 0.0))


def _subspace_norms(model: pin.Model) -> list[tuple[float, float]]:
    """Per velocity coordinate: ``(|s_lin|, |s_ang|)`` of its motion subspace column (its joint's
    frame), ``(inf, inf)`` when that column may change with the configuration."""
    norms: list[tuple[float, float]] = [(np.inf, np.inf)] * model.nv
    neutral = pin.neutral(model)
    for joint in range(1, model.njoints):
        joint_model = model.joints[joint]
        if joint_model.nv == 0 or joint_model.shortname() not in CONSTANT_SUBSPACE:
            continue
        joint_data = joint_model.createData()
        joint_model.calc(joint_data, neutral[joint_model.idx_q:joint_model.idx_q + joint_model.nq])
        columns = np.asarray(joint_data.S).reshape(6, joint_model.nv)
        for i in range(joint_model.nv):
            norms[joint_model.idx_v + i] = (float(np.linalg.norm(columns[:3, i])),
                                            float(np.linalg.norm(columns[3:, i])))
    return norms


def _chain_length(model: pin.Model, origin: int, joint: int, table: NDArray[np.float64], shape: int) -> float:
    """A bound of ``|c - o_origin|`` over every configuration, c the bounding-sphere centre of
    ``shape`` (carried by ``joint``, ``origin`` or a descendant of it); ``inf`` when a joint after
    ``origin`` on the way translates or is not an ancestor."""
    centre = table[shape, TRANSLATION] + table[shape, ROTATION].reshape(3, 3) @ table[shape, BOUND_CENTER]
    length = float(np.linalg.norm(centre))
    while joint != origin:
        if joint == 0 or model.joints[joint].shortname() not in ROTATIONS:
            return np.inf
        length += float(np.linalg.norm(model.jointPlacements[joint].translation))
        joint = model.parents[joint]
    return length
