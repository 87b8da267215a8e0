"""This tick's kinematics, computed once and shared by every task and constraint."""

from __future__ import annotations

import functools
from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin

from ..core.errors import ModelError
from ..runtime import kernels
from .robot import Robot

if TYPE_CHECKING:  # pragma: no cover
    from numpy.typing import NDArray

    from ..runtime.program import TickProgram

_LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED

#: values of :attr:`Kinematics.current`
NOTHING_CURRENT, PINOCCHIO_CURRENT, HESSIANS_CURRENT = 0, 1, 2

#: whether this Pinocchio's Python binding has kinematic Hessians (pin >= 4; not pin 3.x);
#: without them :class:`Kinematics` computes the same tensor itself (:func:`jacobian_derivative`)
PINOCCHIO_HESSIANS = hasattr(pin, "computeJointKinematicHessians") and hasattr(pin, "getFrameKinematicHessian")


class Kinematics:
    """Forward kinematics and joint Jacobians of one configuration.

    :meth:`update` computes the joint placements and joint Jacobians once per tick; frame
    placements and Jacobians are then read without recomputing the chain. Kinematic
    Hessians are computed on the first :meth:`frame_hessian` call of a tick only.
    Conventions as in :mod:`wbc.model.robot`.

    **Native mode** (every joint 1-DOF revolute or prismatic, :func:`native_chain`; all
    shipped robots): the compiled :func:`wbc.runtime.kernels.forward_kinematics` computes the joint
    placements and Jacobians into this object's buffers (the layouts of Pinocchio's
    ``data.oMi`` and ``data.J``, which the kernels read), and Pinocchio's own ``data`` is
    brought up to date only when something reads it (:attr:`data`, :meth:`frame_placement`,
    :meth:`frame_jacobian`, Hessians). A controller whose items are all compiled defers even
    that: ``update(q, deferred=True)`` only stores q, and the tick program's first op
    (:meth:`add_op`) computes the chain in the same native call as the rest.
    """

    def __init__(self, robot: Robot) -> None:
        # whatever reads a Kinematics runs the compiled kernels: load them now, when a controller
        # is built, not in its first tick (its ops compile when added to its program); and the
        # control loop's robot.integrate (on vector-space robots)
        kernels.load()
        kernels.prepare("integrate_vector_space")
        self.robot = robot
        self.model = robot.model
        self._data = robot.model.createData()
        self.q = np.zeros(robot.nq)
        self._masks: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        self._pinocchio_hessians = PINOCCHIO_HESSIANS
        #: what is computed for ``q`` beyond the compiled chain: NOTHING_CURRENT, PINOCCHIO_CURRENT
        #: (Pinocchio's data) or HESSIANS_CURRENT (and its kinematic Hessians). Whoever writes ``q``
        #: sets it to NOTHING_CURRENT: :meth:`update`, or the controller whose tick program copies q in
        self.current = NOTHING_CURRENT
        self._column_major = _hessian_buffer_is_column_major() if self._pinocchio_hessians else False
        if not _binding_returns_live_views():
            raise ModelError(f"pinocchio {pin.__version__}: data.J / data.oMi are not returned as live "
                             "views of the model data, which the compiled tasks read")
        self.chain = native_chain(self.model) if NATIVE_FORWARD_KINEMATICS else None
        if self.chain is not None:
            #: per joint: world rotation (column-major, 9) and translation (3)
            self.placements = np.zeros((self.model.njoints, 12))
            self._jacobians_t = np.zeros((self.model.nv, 6))
            #: every joint's Jacobian columns (6 x nv): spatial velocity at the world origin,
            #: world axes (Pinocchio's data.J); a live view, refreshed by :meth:`update`
            self.joint_jacobians = self._jacobians_t.T
        else:
            self.joint_jacobians = self._data.J
        self._joint_views: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
        # the neutral configuration, by Pinocchio (touches the buffers now, not in the first tick): the
        # compiled forward_kinematics compiles only for whoever calls update in its ticks, when it is
        # built (a controller's tick program runs the chain itself, in its first op)
        self.q[:] = pin.neutral(self.model)
        pin.computeJointJacobians(self.model, self._data, self.q)
        if self.chain is not None:
            fill_kinematics(self._data, self.placements, self._jacobians_t)
        self.current = PINOCCHIO_CURRENT

    @property
    def native(self) -> bool:
        """Whether the joint placements and Jacobians come from the compiled forward kinematics."""
        return self.chain is not None

    @property
    def data(self) -> pin.Data:
        """Pinocchio's data for the current ``q`` (forward kinematics and joint Jacobians)."""
        if self.current == NOTHING_CURRENT:
            pin.computeJointJacobians(self.model, self._data, self.q)
            self.current = PINOCCHIO_CURRENT
        return self._data

    def update(self, q: np.ndarray, deferred: bool = False) -> None:
        """Recompute for configuration ``q`` (already validated). ``deferred`` (native mode,
        a controller's tick program with :meth:`add_op` first): only store q."""
        self.q[:] = q
        if self.chain is None:
            pin.computeJointJacobians(self.model, self._data, self.q)
            self.current = PINOCCHIO_CURRENT
            return
        self.current = NOTHING_CURRENT
        if not deferred:
            kernels.forward_kinematics(self.q, self.chain, self.placements, self._jacobians_t)

    def add_op(self, program: TickProgram) -> bool:
        """Append the compiled forward kinematics to a tick program (native mode; False otherwise)."""
        if self.chain is None:
            return False
        program.add(kernels.FORWARD_KINEMATICS, q=self.q, chain=self.chain, placements=self.placements,
                    jacobians_t=self._jacobians_t, nq=self.q.size, joints=self.chain.shape[0],
                    nv=self._jacobians_t.shape[0])
        return True

    def joint_views(self, joint_id: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Every joint's Jacobian columns (:attr:`joint_jacobians`) and the world rotation
        (3 x 3) and translation (3) of joint ``joint_id``: live views, refreshed by
        :meth:`update` (the kernels read them in place). Fetched once per joint."""
        views = self._joint_views.get(joint_id)
        if views is None:
            if self.chain is not None:
                row = self.placements[joint_id]
                rotation, translation = row[:9].reshape(3, 3).T, row[9:12]
            else:
                placement = self._data.oMi[joint_id]
                rotation, translation = placement.rotation, placement.translation
            views = self._joint_views[joint_id] = (self.joint_jacobians, rotation, translation)
        return views

    def frame_placement(self, frame_id: int) -> pin.SE3:
        """World placement of a frame (an SE3 owned by this object's data)."""
        return pin.updateFramePlacement(self.model, self.data, frame_id)

    def frame_jacobian(self, frame_id: int) -> np.ndarray:
        """6 x nv frame Jacobian, world-aligned at the frame origin, rows (linear; angular)."""
        return pin.getFrameJacobian(self.model, self.data, frame_id, _LWA)

    def frame_hessian(self, frame_id: int) -> np.ndarray:
        """Derivative of :meth:`frame_jacobian`: a (6, nv, nv) array ``T`` with
        ``T[a, j, i] = d J[a, j] / d q_i`` (``q_i`` moved along the i-th tangent direction,
        i.e. ``pin.integrate(q, t e_i)``), so ``dJ/dt = sum_i T[:, :, i] v_i``.

        Pinocchio's kinematic Hessian where its binding has one (pin >= 4), else the same
        tensor from the frame Jacobian (:func:`jacobian_derivative`). Raises
        :class:`ModelError` when a joint carrying the frame is not one of :data:`HESSIAN_JOINTS`.
        """
        ancestry_t, _ = self._hessian_masks(frame_id)
        if self._pinocchio_hessians:
            return _hessian_tensor(self._raw_frame_hessian(frame_id), self._column_major)
        return jacobian_derivative(self.frame_jacobian(frame_id), ancestry_t)

    def contract_frame_hessian(self, frame_id: int, weights_t: np.ndarray, out: np.ndarray) -> np.ndarray:
        """``out[i] = sum_{a, j} W[a, j] T[a, j, i]`` for ``T = frame_hessian(frame_id)``, given
        ``weights_t = W^T`` (nv x 6, C-contiguous): the derivative of ``<W, J>`` along each
        tangent direction. With Pinocchio's Hessian, one matrix-vector product on its buffer
        in its own memory order ([i][j][a] in pin 4.1, which is exactly W^T flattened); else
        :func:`contract_jacobian_derivative`, without forming ``T``."""
        ancestry_t, others_t = self._hessian_masks(frame_id)
        if not self._pinocchio_hessians:
            return contract_jacobian_derivative(self.frame_jacobian(frame_id), weights_t, ancestry_t, others_t, out)
        raw = self._raw_frame_hessian(frame_id)
        nv = self.model.nv
        if self._column_major and raw.flags.c_contiguous:
            return np.dot(raw.reshape(nv, 6 * nv), weights_t.reshape(-1), out=out)
        tensor = _hessian_tensor(raw, self._column_major)
        return np.einsum("ja,aji->i", weights_t, tensor, out=out)

    def _raw_frame_hessian(self, frame_id: int) -> np.ndarray:
        """Pinocchio's frame Hessian as its binding returns it (joint Hessians once per tick)."""
        if self.current != HESSIANS_CURRENT:
            pin.computeJointKinematicHessians(self.model, self.data)
            self.current = HESSIANS_CURRENT
        return pin.getFrameKinematicHessian(self.model, self.data, frame_id, _LWA)

    def _hessian_masks(self, frame_id: int) -> tuple[np.ndarray, np.ndarray]:
        """``A^T`` and ``(1 - A)^T`` (C-contiguous) for ``A = hessian_ancestry(model, frame_id)``,
        built on the frame's first use (which checks its joints)."""
        masks = self._masks.get(frame_id)
        if masks is None:
            ancestry_t = hessian_ancestry(self.model, frame_id).T
            masks = self._masks[frame_id] = (np.ascontiguousarray(ancestry_t), np.ascontiguousarray(1.0 - ancestry_t))
        return masks


def jacobian_derivative(jacobian: np.ndarray, ancestry_t: np.ndarray) -> np.ndarray:
    """:meth:`Kinematics.frame_hessian` from the frame Jacobian alone, exactly.

    With columns ``J_j = (l_j; w_j)`` of ``jacobian`` (velocity of the frame origin; angular
    velocity, world axes) and ``A = ancestry_t^T`` (:func:`hessian_ancestry`)::

        T[:, j, i] = (w_i x l_j; w_i x w_j)   if A[i, j]
        T[:, j, i] = (w_j x l_i; 0)           otherwise

    Moving ``q_i`` turns the joint of column j and the frame rigidly about ``w_i`` when the
    joint of i carries the joint of j (within one joint: the joints of :data:`HESSIAN_JOINTS`);
    otherwise the column stays and only the frame origin moves, by ``l_i``. This is
    Pinocchio's ``getFrameKinematicHessian(..., LOCAL_WORLD_ALIGNED)``, whose world-frame
    blocks ``S_i x S_j`` shifted to the frame origin reduce to it by the Jacobi identity.
    """
    linear, angular = jacobian[:3, :, None], jacobian[3:, :, None]  # [a, j, (i)]
    linear_i, angular_i = linear.transpose(0, 2, 1), angular.transpose(0, 2, 1)  # [a, (j), i]
    nv = jacobian.shape[1]
    tensor = np.empty((6, nv, nv))
    tensor[:3] = np.where(ancestry_t, np.cross(angular_i, linear, axis=0), np.cross(angular, linear_i, axis=0))
    tensor[3:] = np.cross(angular_i, angular, axis=0) * ancestry_t
    return tensor


def _levi_civita_pairs() -> np.ndarray:
    """The (6, 36) matrix ``E`` with ``E @ (x y^T).ravel() = (l x m + w x n; m x w)`` for
    ``x = (l; w)``, ``y = (m; n)``: the cross products of :func:`contract_jacobian_derivative`,
    for every column at once, as one matrix product (not one numpy call per component)."""
    epsilon = np.zeros((3, 3, 3))
    for k, p, r in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):
        epsilon[k, p, r], epsilon[k, r, p] = 1.0, -1.0  # (a x b)_k = eps[k, p, r] a_p b_r
    pairs = np.zeros((6, 6, 6))
    pairs[:3, :3, :3] = epsilon  # l x m
    pairs[:3, 3:, 3:] = epsilon  # w x n
    pairs[3:, 3:, :3] = -epsilon  # m x w = -(w x m)
    return pairs.reshape(6, 36)


_CROSS_PAIRS = _levi_civita_pairs()


def contract_jacobian_derivative(jacobian: np.ndarray, weights_t: np.ndarray, ancestry_t: np.ndarray,
                                 others_t: np.ndarray, out: np.ndarray) -> np.ndarray:
    """``out[i] = sum_{a, j} W[a, j] T[a, j, i]`` for ``T = jacobian_derivative(jacobian, ancestry_t)``,
    ``weights_t = W^T`` (nv x 6), ``others_t = 1 - ancestry_t``, without forming ``T``. By the
    triple product ``a . (b x c) = b . (c x a)``, with ``W_j = (m_j; n_j)``::

        out[i] = w_i . sum_j A[i, j] (l_j x m_j + w_j x n_j) + l_i . sum_j (1 - A[i, j]) (m_j x w_j)
    """
    weights = weights_t.T
    crosses = _CROSS_PAIRS @ (jacobian[:, None, :] * weights[None, :, :]).reshape(36, -1)
    summed = np.empty_like(jacobian)  # (sum_j (1 - A[i, j]) ...; sum_j A[i, j] ...) matching (l_i; w_i)
    np.matmul(crosses[3:], others_t, out=summed[:3])
    np.matmul(crosses[:3], ancestry_t, out=summed[3:])
    return np.einsum("ai,ai->i", jacobian, summed, out=out)


#: joints whose motion subspace is constant in the joint frame and whose ``pin.integrate``
#: moves the joint frame by ``exp`` of the joint velocity on the right: for these, moving along
#: tangent direction i of the joint turns every column j of the same joint by ``S_i x S_j``
#: (q-dependent subspaces such as SphericalZYX or Universal break this, in Pinocchio's own
#: kinematic Hessian too)
HESSIAN_JOINTS = frozenset({
    "JointModelRX", "JointModelRY", "JointModelRZ", "JointModelRevoluteUnaligned",
    "JointModelRUBX", "JointModelRUBY", "JointModelRUBZ", "JointModelRevoluteUnboundedUnaligned",
    "JointModelPX", "JointModelPY", "JointModelPZ", "JointModelPrismaticUnaligned",
    "JointModelHX", "JointModelHY", "JointModelHZ", "JointModelHelicalUnaligned",
    "JointModelPlanar", "JointModelFreeFlyer", "JointModelSpherical", "JointModelTranslation",
})


def hessian_ancestry(model: pin.Model, frame_id: int) -> np.ndarray:
    """The (nv, nv) mask ``A`` of :meth:`Kinematics.frame_hessian`: ``A[i, j] = 1`` when
    velocity coordinates i and j both belong to joints supporting the frame and the joint of
    i is the joint of j or one of its ancestors. Raises :class:`ModelError` when one of those
    joints is not in :data:`HESSIAN_JOINTS`."""
    frame = model.frames[frame_id]
    chain = list(model.supports[frame.parentJoint])[1:]
    ancestry = np.zeros((model.nv, model.nv))
    for position, joint_id in enumerate(chain):
        joint = model.joints[joint_id]
        if joint.shortname() not in HESSIAN_JOINTS:
            raise ModelError(f"frame {frame.name!r}: no kinematic Hessian through joint {model.names[joint_id]!r} "
                             f"({joint.shortname()}, whose motion subspace is not constant in the joint frame); "
                             f"supported joint types: {', '.join(sorted(HESSIAN_JOINTS))}")
        columns = slice(joint.idx_v, joint.idx_v + joint.nv)
        for carrier_id in chain[:position + 1]:
            carrier = model.joints[carrier_id]
            ancestry[carrier.idx_v:carrier.idx_v + carrier.nv, columns] = 1.0
    return ancestry


#: use the compiled forward kinematics where the chain allows it (False: Pinocchio always)
NATIVE_FORWARD_KINEMATICS = True

_AXES = {"X": (1.0, 0.0, 0.0), "Y": (0.0, 1.0, 0.0), "Z": (0.0, 0.0, 1.0)}


def native_chain(model: pin.Model) -> np.ndarray | None:
    """The chain description of :func:`wbc.runtime.kernels.forward_kinematics` (one row per joint,
    ``CHAIN_COLUMNS``), or None when a joint is not 1-DOF revolute / prismatic about a fixed
    axis (Pinocchio's RX/RY/RZ/PX/PY/PZ and their unaligned forms)."""
    chain = np.zeros((model.njoints, kernels.CHAIN_COLUMNS))
    for j in range(1, model.njoints):
        joint = model.joints[j]
        name = joint.shortname()
        if name in ("JointModelRevoluteUnaligned", "JointModelPrismaticUnaligned"):
            axis = np.asarray(joint.extract().axis, dtype=float)
        elif len(name) == len("JointModelRX") and name[:-2] == "JointModel" and name[-2] in "RP" \
                and name[-1] in _AXES:
            axis = np.array(_AXES[name[-1]])
        else:
            return None
        kind = kernels.CHAIN_PRISMATIC if "Prismatic" in name or name[-2] == "P" else kernels.CHAIN_REVOLUTE
        placement = model.jointPlacements[j]
        chain[j, :4] = (model.parents[j], kind, joint.idx_q, joint.idx_v)
        chain[j, 4:7] = axis / np.linalg.norm(axis)
        chain[j, 7:16] = placement.rotation.ravel()
        chain[j, 16:19] = placement.translation
    return chain


def frame_in_joint(model: pin.Model, frame_id: int) -> tuple[int, np.ndarray, np.ndarray]:
    """What the compiled kernels need to place a frame: its parent joint, its placement in
    that joint as 12 numbers (rotation row-major, then translation) and the support mask
    (nv; 1 on the velocity coordinates of the joints from the root to the frame)."""
    frame = model.frames[frame_id]
    local = np.concatenate([frame.placement.rotation.ravel(), frame.placement.translation])
    support = np.zeros(model.nv)
    for joint_id in model.supports[frame.parentJoint][1:]:
        joint = model.joints[joint_id]
        support[joint.idx_v:joint.idx_v + joint.nv] = 1.0
    return frame.parentJoint, local, support


@functools.cache
def _binding_returns_live_views() -> bool:
    """Whether ``data.J`` and ``data.oMi[i].rotation / .translation`` are views that follow
    later kinematics updates (eigenpy returns references to Eigen members; checked once per
    process on a two-joint probe rather than assumed)."""
    model = pin.Model()
    first = model.addJoint(0, pin.JointModelRZ(), pin.SE3.Identity(), "a")
    model.addJoint(first, pin.JointModelRY(), pin.SE3(np.eye(3), np.array([0.3, 0.0, 0.0])), "b")
    data = model.createData()
    pin.computeJointJacobians(model, data, np.zeros(2))
    jacobians, rotation, translation = data.J, data.oMi[2].rotation, data.oMi[2].translation
    pin.computeJointJacobians(model, data, np.array([0.4, -0.7]))
    fresh = model.createData()
    pin.computeJointJacobians(model, fresh, np.array([0.4, -0.7]))
    return bool(np.array_equal(jacobians, fresh.J) and np.array_equal(rotation, fresh.oMi[2].rotation)
                and np.array_equal(translation, fresh.oMi[2].translation))


def _hessian_tensor(raw: np.ndarray, column_major: bool) -> np.ndarray:
    """View ``raw`` (as returned by Pinocchio's Python binding) as ``T[a, j, i]``."""
    if not column_major:
        return raw
    six, nv, _ = raw.shape
    return np.ravel(raw, order="K").reshape(nv, nv, six).transpose(2, 1, 0)


@functools.cache
def _hessian_buffer_is_column_major() -> bool:
    """Which memory layout this Pinocchio's binding gives kinematic Hessians.

    pin 4.1 returns the (6, nv, nv) Eigen tensor as an ndarray with C strides over
    its column-major buffer, so indexing the array as returned is wrong. Rather than
    trusting either layout, this is decided once per process: the Hessian of a
    3-joint probe chain (revolute z, revolute y, prismatic x, so 6 != nv and every
    block is non-zero) is compared with central differences of its Jacobian.
    """
    model = pin.Model()
    parent = 0
    for name, joint, translation in (("rz", pin.JointModelRZ(), (0.0, 0.0, 0.0)),
                                     ("ry", pin.JointModelRY(), (0.3, 0.0, 0.2)),
                                     ("px", pin.JointModelPX(), (0.0, 0.1, 0.4))):
        parent = model.addJoint(parent, joint, pin.SE3(np.eye(3), np.array(translation)), name)
    frame = model.addFrame(pin.Frame("tip", parent, pin.SE3(np.eye(3), np.array([0.2, 0.1, 0.3])),
                                     pin.FrameType.OP_FRAME))
    data = model.createData()
    q, step = np.array([0.3, -0.4, 0.2]), 1e-6
    pin.computeJointJacobians(model, data, q)
    pin.computeJointKinematicHessians(model, data)
    raw = pin.getFrameKinematicHessian(model, data, frame, _LWA)
    reference = np.zeros((6, 3, 3))
    for i in range(3):
        dq = np.zeros(3)
        dq[i] = step
        plus = pin.computeFrameJacobian(model, model.createData(), q + dq, frame, _LWA)
        minus = pin.computeFrameJacobian(model, model.createData(), q - dq, frame, _LWA)
        reference[:, :, i] = (plus - minus) / (2.0 * step)
    for column_major in (True, False):
        if np.allclose(_hessian_tensor(raw, column_major), reference, rtol=0.0, atol=1e-6):
            return column_major
    raise ModelError(f"pinocchio {pin.__version__}: kinematic Hessian matches neither memory layout")


def fill_kinematics(data: pin.Data, placements: NDArray[np.float64], jacobians_t: NDArray[np.float64]) -> None:
    """Pinocchio's joint placements and Jacobians in the layouts of :class:`wbc.model.kinematics.Kinematics`."""
    for joint, placement in enumerate(data.oMi):
        placements[joint, :9] = placement.rotation.ravel(order="F")
        placements[joint, 9:] = placement.translation
    jacobians_t[:] = data.J.T
