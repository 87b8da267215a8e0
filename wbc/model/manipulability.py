"""Yoshikawa's manipulability and its analytic gradient.

For the selected rows ``J`` (k x nv) of a frame Jacobian (:meth:`wbc.Robot.frame_jacobian`
convention) with singular values ``s_1 >= ... >= s_r``, ``r = min(k, nv)``::

    m(q) = s_1 s_2 ... s_r       (= sqrt(det(J J^T)) for wide J, sqrt(det(J^T J)) for tall J)

It is zero exactly where ``J`` loses rank. Units are those of the selected rows
multiplied together (e.g. [m^3] for ``rows="position"``), so compare values of one
frame and row selection only.

Gradient (Haviland & Corke, *Manipulator Differential Kinematics II*, generalised by
the SVD): with ``J = U diag(s) V^T`` and ``ds_l = u_l^T dJ v_l``,

    dm/dq_i = < G , dJ/dq_i >_F ,   G = U diag(c) V^T ,   c_l = prod_{p != l} s_p

and ``dJ/dq_i`` from motion cross products of the joint Jacobian columns (compiled, chains
of 1-DOF joints: :func:`wbc.runtime.kernels.manipulability_gradient`) or from the kinematic
Hessian (:meth:`Kinematics.frame_hessian`: Pinocchio's where its binding has one, else the
same tensor from the frame Jacobian; joints with a constant motion subspace).
Where ``J`` has full rank, ``G = m (J^+)^T`` and the formula is the familiar
``dm/dq_i = m tr((J J^T)^-1 J (dJ/dq_i)^T)``; unlike that form it needs no inverse
and stays accurate next to a singularity. On the singular set itself m is not
differentiable (it behaves like ``|f(q)|``); the vector returned there is finite but
arbitrary. The derivative is taken along the tangent directions
of ``q`` (``pin.integrate``), so ``dm/dt = grad m . v`` for any joint type,
prismatic and planar-base joints included.

Note: ``wbc.manipulability`` is the function (exported from :mod:`wbc`); import this module's other names with
``from wbc.model.manipulability import Manipulability``.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.errors import InvalidInputError
from ..runtime import kernels
from .declared_base import joint_columns
from .kinematics import Kinematics, frame_in_joint
from .robot import Robot

ROWS = {"all": slice(0, 6), "position": slice(0, 3), "orientation": slice(3, 6)}
"""Row selections of a 6 x nv Jacobian (rows are (linear; angular))."""

Rows = Literal["all", "position", "orientation"]
"""The names of :data:`ROWS`: the ``rows`` argument of the functions and classes here."""


def row_selection(rows: str) -> slice:
    """The Jacobian rows named by ``rows`` (``"all"``, ``"position"`` or ``"orientation"``)."""
    try:
        return ROWS[rows]
    except (KeyError, TypeError):
        raise InvalidInputError(f"rows must be one of {sorted(ROWS)}, got {rows!r}") from None


class Manipulability:
    """Manipulability ``m`` and its gradient for one frame and row selection, of the whole body
    or of a chain of it (``joints``: the measure of the columns of those joints only, e.g. the
    arm of a mobile manipulator, whose whole-body measure the base keeps large while the arm
    folds).

    :meth:`compute` reads an already updated :class:`~wbc.model.kinematics.Kinematics`
    (the controller's, on the hot path) and leaves the results in :attr:`value`
    and :attr:`gradient` (size nv, overwritten in place).

    When every joint between the root and the frame has one DOF (all shipped models), the
    whole evaluation is one compiled call (:func:`wbc.runtime.kernels.manipulability_gradient`,
    ``dJ/dq`` from the joint Jacobians); otherwise the derivative comes from the kinematic
    Hessian (:meth:`wbc.model.kinematics.Kinematics.frame_hessian`).
    """

    def __init__(self, robot: Robot, frame: str, rows: Rows = "all", joints: Sequence[str] | None = None) -> None:
        self.frame = frame
        self.rows = rows
        self._rows = row_selection(rows)
        self.frame_id = robot.frame_id(frame)
        self.joints = None if joints is None else tuple(joints)
        #: the velocity coordinates of ``joints`` (None: every one)
        self.columns = None if joints is None else chain_columns(robot, self.frame_id, joints)
        self.value = 0.0  #: m at the last :meth:`compute`
        self.gradient = np.zeros(robot.nv)  #: grad m (size nv) at the last :meth:`compute`, overwritten in place
        # G^T (nv x 6): G on the selected rows, zero elsewhere, stored transposed because
        # that is the memory order Kinematics.contract_frame_hessian contracts without a copy
        self._weights_t = np.zeros((robot.nv, 6))
        self._weighted_t = self._weights_t[:, self._rows]
        width = robot.nv if self.columns is None else self.columns.size
        self._wide = (self._rows.stop - self._rows.start) <= width
        # G^T on the chain's columns (a chain's measure): scattered into the rows of _weights_t
        self._chain_t = None if self.columns is None else np.zeros((width, self._rows.stop - self._rows.start))
        model = robot.model
        self._joint_id, self._local, self._support = frame_in_joint(model, self.frame_id)
        chain = list(model.supports[self._joint_id])[1:]
        self._compiled = self.columns is None and all(model.joints[j].nv == 1 for j in chain)
        self._ancestor = np.zeros((robot.nv, robot.nv))  # 1 where joint of i is a strict ancestor of k's
        for position, joint_id in enumerate(chain):
            k = model.joints[joint_id].idx_v
            for ancestor_id in chain[:position]:
                self._ancestor[model.joints[ancestor_id].idx_v, k] = 1.0
        self._jacobian = np.zeros((6, robot.nv))
        self._origin = np.zeros(3)

    @property
    def compiled(self) -> bool:
        """True when :meth:`compute` is one compiled call (all joints up to the frame have 1 DOF)."""
        return self._compiled

    def operands(self, kin: Kinematics) -> dict[str, NDArray[np.float64]]:
        """Operands of the MANIPULABILITY_BARRIER op up to the gradient, by name (compiled only)."""
        joint_jacobians, rotation, translation = kin.joint_views(self._joint_id)
        return dict(joint_jacobians_t=joint_jacobians.T, rotation_t=rotation.T, translation=translation,
                    local=self._local, support=self._support, ancestor=self._ancestor, jacobian=self._jacobian,
                    origin=self._origin, gradient=self.gradient)

    def compute(self, kin: Kinematics) -> float:
        """Evaluate ``m`` and ``grad m`` at ``kin.q``; returns ``m``.

        Well-conditioned ``J`` (the usual case) takes the closed form ``G = m (J^+)^T``
        from one small Gram matrix (``det`` and ``solve``); near a singularity, where
        that loses accuracy, the SVD form.
        """
        if self._compiled:
            joint_jacobians, rotation, translation = kin.joint_views(self._joint_id)
            kernels.frame_jacobian(joint_jacobians, rotation, translation, self._local, self._support,
                                   self._jacobian, self._origin)
            self.value = kernels.manipulability_gradient(
                joint_jacobians, self._jacobian, self._origin, self._support, self._ancestor,
                self._rows.start, self._rows.stop, self.gradient)
            return self.value
        jacobian = kin.frame_jacobian(self.frame_id)[self._rows]  # C-contiguous rows
        if self.columns is not None:
            jacobian = jacobian[:, self.columns]
        weighted_t = self._weighted_t if self._chain_t is None else self._chain_t
        wide = self._wide
        gram = jacobian.dot(jacobian.T) if wide else jacobian.T.dot(jacobian)
        size = len(gram)
        # Cholesky gram = L L^T and the solve of the closed form below, in one LAPACK call;
        # det(gram) = prod(diag L)^2
        factor, solution, info = _lapack().dposv(gram, jacobian if wide else jacobian.T, lower=1)
        determinant = math.prod(factor.ravel(order="K")[:: size + 1].tolist()) ** 2 if info == 0 else 0.0
        flat = jacobian.ravel()
        mean_eigenvalue = flat.dot(flat) / size  # trace(gram) = |J|_F^2
        if determinant > kernels.GRAM_CONDITION * mean_eigenvalue**size:
            self.value = math.sqrt(determinant)
            # G = m (J J^T)^-1 J  (wide)  or  m J (J^T J)^-1 = m ((J^T J)^-1 J^T)^T  (tall)
            np.multiply(solution.T if wide else solution, self.value, out=weighted_t)
        else:
            u, s, vt, info = _lapack().dgesvd(jacobian, full_matrices=0)  # LAPACK directly: ~2x numpy's wrapper
            if info != 0:
                u, s, vt = np.linalg.svd(jacobian, full_matrices=False)
            values = s.tolist()
            np.matmul(vt.T, (u * _products_of_the_others(values)).T, out=weighted_t)
            self.value = math.prod(values)
        if self._chain_t is not None:  # G is zero on the other columns: dm/dq_i = <G, dJ/dq_i> over the chain's
            self._weighted_t[self.columns] = self._chain_t
        kin.contract_frame_hessian(self.frame_id, self._weights_t, self.gradient)
        return self.value

    def __repr__(self) -> str:
        chain = "" if self.joints is None else f", joints={list(self.joints)!r}"
        return f"Manipulability(frame={self.frame!r}, rows={self.rows!r}{chain})"


def check_joint_names(joints: Sequence[str]) -> Sequence[str]:
    """``joints`` if it is a non-empty list of names, else InvalidInputError naming the fix."""
    if isinstance(joints, str) or not joints or not all(isinstance(joint, str) for joint in joints):
        raise InvalidInputError(f"joints must be a non-empty list of joint names, got {joints!r}"
                                + (f"; write joints=[{joints!r}]" if isinstance(joints, str) else ""))
    return joints

def chain_columns(robot: Robot, frame_id: int, joints: Sequence[str]) -> NDArray[np.intp]:
    """The velocity coordinates of ``joints`` (every coordinate of each), each a joint that moves
    the frame (on its path from the root).

    Raises:
        InvalidInputError: not a non-empty list of names, a joint named twice or one that does not
            move the frame.
        ModelError: an unknown joint (with close names).
    """
    check_joint_names(joints)
    model = robot.model
    frame = model.frames[frame_id].name
    columns = joint_columns(model, joints, f"manipulability of '{frame}'")
    support = set(model.supports[model.frames[frame_id].parentJoint])
    for name in joints:
        if model.getJointId(name) not in support:
            raise InvalidInputError(f"joint {name!r} does not move frame '{frame}' (it is not on the frame's path "
                                    "from the root): its measure would be 0")
    return columns


def manipulability(robot: Robot, q: ArrayLike, frame: str, rows: Rows = "all",
                   joints: Sequence[str] | None = None) -> float:
    """Yoshikawa's measure ``m(q)`` of ``frame`` (product of the singular values of the selected
    rows; of the columns of ``joints`` only, when given).

    Raises:
        UnknownFrameError: no frame of that name.
        InvalidInputError: a malformed ``q``, an unknown ``rows``, ``joints`` that do not move the frame.
    """
    jacobian = robot.frame_jacobian(q, frame)[row_selection(rows)]
    if joints is not None:
        jacobian = jacobian[:, chain_columns(robot, robot.frame_id(frame), joints)]
    return float(np.prod(np.linalg.svd(jacobian, compute_uv=False)))


def manipulability_gradient(robot: Robot, q: ArrayLike, frame: str, rows: Rows = "all",
                            joints: Sequence[str] | None = None) -> NDArray[np.float64]:
    """``grad m(q)`` (size nv): ``dm/dt = (grad m)^T v`` along any joint velocity ``v`` (of the
    chain of ``joints``, when given: see :class:`Manipulability`).

    Raises:
        UnknownFrameError: no frame of that name.
        InvalidInputError: a malformed ``q``, an unknown ``rows``, ``joints`` that do not move the frame.
    """
    evaluator = Manipulability(robot, frame, rows, joints)
    kin = Kinematics(robot)
    kin.update(robot.check_configuration(q))
    evaluator.compute(kin)
    return evaluator.gradient


def _products_of_the_others(s: list[float]) -> NDArray[np.float64]:
    """``c_l = prod_{p != l} s_p`` without dividing (exact when some ``s_p`` are zero)."""
    return np.array([math.prod(s[:l]) * math.prod(s[l + 1:]) for l in range(len(s))])


__all__ = ["Manipulability", "manipulability", "manipulability_gradient", "row_selection", "ROWS", "chain_columns",
           "check_joint_names"]


@functools.cache
def _lapack() -> Any:
    """``scipy.linalg.lapack``, imported when first needed: ~0.12 s that ``import wbc`` does not pay."""
    from scipy.linalg import lapack

    return lapack
