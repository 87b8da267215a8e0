"""Robot model: a Pinocchio model plus what a URDF cannot say (base kind, unbounded axes).

Conventions, fixed here for the whole library:

* ``q`` (size ``nq``) and ``v`` (size ``nv``) are Pinocchio's configuration and
  velocity vectors. For the shipped youBot they coincide (nq = nv = 8):
  ``q = (X_C, Y_C, theta, theta1, ..., theta5)`` as in Kapustina (2019).
* Poses are 4x4 homogeneous transforms of the frame in the **world** frame.
* Jacobians are 6 x nv and map ``v`` to the frame's twist expressed in the
  **world-aligned frame at the frame origin** (Pinocchio's LOCAL_WORLD_ALIGNED),
  rows ordered **(linear [m/s]; angular [rad/s])**.
* Rotations are matrices; wherever a quaternion appears it is (x, y, z, w).
"""

from __future__ import annotations

import difflib
import math
import os
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from dataclasses import replace as replace_field
from pathlib import Path
from typing import Annotated, Any, Literal

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike, NDArray
from pydantic import Field, ValidationError

from ..core.errors import InvalidInputError, ModelError, ModelWarning, UnknownFrameError
from ..core.schema import Positive, Table, explain, read_toml, suggest
from ..core.validation import all_finite, as_positive, as_vector
from ..runtime import kernels
from ..runtime.native_entry import unchecked_entry
from . import shipped
from .bases.floating import free_flyer_root
from .bases.interface import kind_class
from .couplings import JointCoupling, check_couplings, coupled_joints
from .declared_base import (
    BaseDeclaration,
    base_kind,
    declare_base,
    declare_floating,
    joint_index,
    planar_root_joints,
    wheel_like_joints,
)
from .mjcf import load_mjcf
from .mobile_base import FIXED_BASE, BaseKind, DifferentialWheels, MecanumWheels, MobileBase, PlanarBase

_REFERENCE_FRAME = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
_FLOAT64 = np.dtype(np.float64)
_empty = np.empty  # (a module global: one lookup fewer in the control loop's integrate)


def _integrate_vector_space(q: NDArray[np.float64], v: NDArray[np.float64], dt: float,
                            reached: NDArray[np.float64]) -> bool:
    """:func:`wbc.runtime.kernels.integrate_vector_space` through its compiled entry, without numba's
    type check (the caller checks that ``q`` and ``v`` are 1-D float64 arrays; ``reached`` is its
    own): this function replaces itself by that entry on its first call (the kernels load lazily)."""
    global _integrate_vector_space
    _integrate_vector_space = unchecked_entry(kernels.integrate_vector_space)
    return _integrate_vector_space(q, v, dt, reached)

#: Pinocchio joints whose coordinates form a vector space (``pinocchio.integrate`` is ``q + v``):
#: 1-DOF revolute (bounded: not the continuous kinds, nq = 2) and prismatic joints
VECTOR_SPACE_JOINTS = frozenset({"JointModelRX", "JointModelRY", "JointModelRZ", "JointModelRevoluteUnaligned",
                                 "JointModelPX", "JointModelPY", "JointModelPZ", "JointModelPrismaticUnaligned"})

#: largest number of velocity DOF a Robot accepts: Pinocchio's Data allocates O(nv^3) memory
#: (second-order derivative tensors; measured with pin 4.1: 69 MB at nv = 100, 0.5 GB at 200,
#: 1.7 GB at 300; a robot and each controller of it hold one), so a 1000-joint chain would need
#: ~64 GB. Read when a robot is built: raise it (``wbc.model.robot.MAX_VELOCITY_DOF = 500``) if the
#: memory is there
MAX_VELOCITY_DOF = 300


def rpy_matrix(roll: float, pitch: float, yaw: float) -> NDArray[np.float64]:
    """Rotation ``Rz(yaw) Ry(pitch) Rx(roll)`` (URDF convention)."""
    cr, sr, cp, sp, cy, sy = np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch), np.cos(yaw), np.sin(yaw)
    return np.array([
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
        [-sp, cp * sr, cp * cr],
    ])


#: the model's vectors that may hold inf (see Robot.__getstate__)
_LIMIT_VECTORS = ("lowerPositionLimit", "upperPositionLimit", "velocityLimit", "effortLimit")


@dataclass
class Robot:
    """A kinematic robot model.

    Build it with :func:`load_robot`. Attributes:

    * ``model`` -- the ``pinocchio.Model`` (read it, do not mutate it);
    * ``base`` -- the :class:`~wbc.model.mobile_base.MobileBase`;
    * ``lower``, ``upper`` -- position limits (size nq, ``+-inf`` where unbounded);
    * ``velocity_limit`` -- symmetric speed limits (size nv) [rad/s or m/s]; for a
      mobile base the linear entries are the base-frame limits of ``|v_x|, |v_y|``;
    * ``couplings`` -- joints that follow others (URDF ``<mimic>``, :mod:`wbc.model.couplings`),
      held by :class:`wbc.MimicJoints`, which every controller of the robot adds.
    """

    name: str
    model: pin.Model
    base: MobileBase = FIXED_BASE
    end_effector: str | None = None
    parameters: dict[str, Any] = field(default_factory=dict)
    source: Path | None = None
    couplings: tuple[JointCoupling, ...] = ()

    def __post_init__(self) -> None:
        model = self.model
        self._check_size()
        self.couplings = tuple(self.couplings)
        check_couplings(model, self.couplings, str(self.source or self.name))
        self._data = model.createData()
        self._check_joints()
        self.lower: NDArray[np.float64] = np.array(model.lowerPositionLimit, dtype=np.float64)
        self.upper: NDArray[np.float64] = np.array(model.upperPositionLimit, dtype=np.float64)
        self.velocity_limit: NDArray[np.float64] = np.array(model.velocityLimit, dtype=np.float64)
        self.base.limit_coordinates(self.lower, self.upper, self.velocity_limit)
        self._check_velocity_limits()
        for array in (self.lower, self.upper, self.velocity_limit):
            array.flags.writeable = False
        self.joint_names: list[str] = list(model.names[1:])
        #: (nq,) when q + v dt integrates every coordinate (decided once: vector-space joints and a
        #: base that keeps the joints' own integration), else None: the base's integrate (SE(2),
        #: SE(3), ...). (One attribute for the flag and the shape; np.empty takes a tuple ~15 ns
        #: faster than an int.)
        self._vector_space_shape: tuple[int] | None = (
            (model.nq,) if all(joint.shortname() in VECTOR_SPACE_JOINTS for joint in model.joints[1:])
            and type(self.base).integrate is MobileBase.integrate else None)
        self._input_map = self.base.allocate_input_map(self.nv)
        self._input_map_varies = self.base.is_nonholonomic  # S depends on q (else S = I)
        self._frame_ids: dict[str, int] = {}
        for index, frame in enumerate(model.frames):
            self._frame_ids.setdefault(frame.name, index)

    def _check_size(self) -> None:
        """A robot with no joint, or one too large for Pinocchio's Data (which allocates O(nv^3):
        ~8 nv^3 doubles in pin 4.1, 0.5 GB at nv = 200, 4 GB at 400), is refused before it is built."""
        where = self.source or self.name
        if self.model.njoints <= 1 or self.model.nv == 0:
            raise ModelError(f"{where}: the model has no movable joint; wbc controls joint velocities, so it "
                             "needs at least one revolute, prismatic or continuous joint")
        if self.model.nv > MAX_VELOCITY_DOF:
            raise ModelError(f"{where}: {self.model.nv} velocity DOF; wbc handles at most {MAX_VELOCITY_DOF} "
                             f"(Pinocchio's Data for {self.model.nv} would take "
                             f"~{8 * 8 * self.model.nv ** 3 / 1e9:.0f} GB: it grows as nv^3); with the memory for it, "
                             "raise wbc.model.robot.MAX_VELOCITY_DOF")

    def _check_joints(self) -> None:
        """Every joint moves something (a URDF ``<axis xyz="0 0 0">`` gives a zero Jacobian column)
        and its position limits are ordered (lower <= upper)."""
        model, where = self.model, self.source or self.name
        for joint_id in range(1, model.njoints):
            joint, name = model.joints[joint_id], model.names[joint_id]
            lower = model.lowerPositionLimit[joint.idx_q:joint.idx_q + joint.nq]
            upper = model.upperPositionLimit[joint.idx_q:joint.idx_q + joint.nq]
            if np.any(lower > upper):
                raise ModelError(f"{where}: joint {name!r} has lower limit {lower.tolist()} above its upper limit "
                                 f"{upper.tolist()}; swap them in the URDF's <limit lower=... upper=...>")
        columns = np.asarray(pin.computeJointJacobians(model, self._data, pin.neutral(model))).reshape(6, model.nv)
        norms = np.linalg.norm(columns, axis=0)
        for joint_id in range(1, model.njoints):
            joint = model.joints[joint_id]
            span = norms[joint.idx_v:joint.idx_v + joint.nv]
            if not np.all(span > 0.0):  # zero or NaN: the joint's axis is degenerate
                raise ModelError(f"{where}: joint {model.names[joint_id]!r} moves nothing (its motion axis is zero "
                                 "or not a number); give it a unit <axis xyz=\"...\"/> in the URDF")

    def _check_velocity_limits(self) -> None:
        """A zero, negative or NaN speed limit would freeze (or break) a joint: refuse it.
        A missing one (inf, e.g. a continuous joint without <limit>) means unbounded."""
        for joint_id in range(1, self.model.njoints):
            joint = self.model.joints[joint_id]
            limits = self.velocity_limit[joint.idx_v:joint.idx_v + joint.nv]
            if np.any(~(limits > 0.0)):
                raise ModelError(
                    f"{self.source or self.name}: joint {self.model.names[joint_id]!r} has velocity limit "
                    f"{limits.tolist()}; give it <limit ... velocity=\"...\"/> > 0 [rad/s or m/s] in the URDF")

    # ------------------------------------------------------------------ sizes
    @property
    def nq(self) -> int:
        """Size of the configuration ``q``."""
        return self.model.nq

    @property
    def nv(self) -> int:
        """Size of the velocity ``v`` (and of every command)."""
        return self.model.nv

    @property
    def frame_names(self) -> list[str]:
        """Names of the model's frames (the ``frame`` arguments it accepts)."""
        return list(self._frame_ids)

    # --------------------------------------------------------------- helpers
    def frame_id(self, frame: str) -> int:
        """Pinocchio index of ``frame``.

        Raises:
            UnknownFrameError: the model has no frame of that name (the message suggests close names).
        """
        try:
            return self._frame_ids[frame]
        except (KeyError, TypeError):
            close = difflib.get_close_matches(str(frame), self._frame_ids, n=3)
            hint = f"; did you mean {', '.join(close)}?" if close else ""
            raise UnknownFrameError(f"robot '{self.name}' has no frame {frame!r}{hint}") from None

    def check_configuration(self, q: ArrayLike) -> NDArray[np.float64]:
        """``q`` checked and converted: a finite float64 vector of size :attr:`nq`.

        Raises:
            InvalidInputError: wrong shape, not numbers (bool, str, None, complex), NaN or inf.
        """
        return as_vector(q, self.nq, "q")

    def check_velocity(self, v: ArrayLike) -> NDArray[np.float64]:
        """``v`` checked and converted: a finite float64 vector of size :attr:`nv`.

        Raises:
            InvalidInputError: wrong shape, not numbers (bool, str, None, complex), NaN or inf.
        """
        return as_vector(v, self.nv, "v")

    def neutral(self) -> NDArray[np.float64]:
        """Pinocchio's neutral configuration (zeros for the youBot: the arm straight up)."""
        return pin.neutral(self.model)

    def random_configuration(self, rng: np.random.Generator, base_range: float = 1.0) -> NDArray[np.float64]:
        """Uniform sample within the position limits; unbounded axes in ``[-base_range, base_range]``;
        quaternions (a floating base) and the ``(cos, sin)`` of continuous joints normalised."""
        low = np.where(np.isfinite(self.lower), self.lower, -base_range)
        high = np.where(np.isfinite(self.upper), self.upper, base_range)
        return pin.normalize(self.model, rng.uniform(low, high))  # unit quaternions, (cos, sin) pairs

    def within_limits(self, q: ArrayLike, tol: float = 0.0) -> bool:
        q = self.check_configuration(q)
        return bool(np.all(q >= self.lower - tol) and np.all(q <= self.upper + tol))

    # ------------------------------------------------------------ mobile base
    @property
    def nu(self) -> int:
        """Number of real inputs: nv, or nv - 1 for a nonholonomic base (no lateral input)."""
        return self._input_map.shape[1]

    def input_map(self, q: NDArray[np.float64] | Sequence[float],
                  out: NDArray[np.float64] | None = None) -> NDArray[np.float64]:
        """``S(q)`` (nv x nu) with ``v = S(q) u`` over the real inputs ``u``.

        Identity for fixed and holonomic bases. For a nonholonomic base
        ``u = (v, omega, other coordinates in order)``: forward speed [m/s], heading
        rate [rad/s], then the joint rates, and ``(xdot, ydot) = v (cos, sin)(heading)``.
        The task Jacobian over inputs is ``frame_jacobian(q, frame) @ input_map(q)``.
        """
        S = self._input_map if out is None else out
        if self._input_map_varies:
            self.base.write_input_map(q, S)
        elif out is not None:
            out[...] = self._input_map
        return S.copy() if out is None else S

    def base_twist(self, q: ArrayLike, v: ArrayLike) -> NDArray[np.float64]:
        """Base-frame twist ``(v_x, v_y, omega)`` [m/s, m/s, rad/s] of the velocity ``v`` at ``q``
        (a floating base: ``(v_x, v_y, v_z, omega_x, omega_y, omega_z)``).

        Raises:
            InvalidInputError: a fixed base, or a malformed ``q`` or ``v``.
        """
        if self.base.kind is BaseKind.FIXED:
            raise InvalidInputError(f"robot '{self.name}' has a fixed base")
        return self.base.twist(self.check_configuration(q), self.check_velocity(v))

    def wheel_speeds(self, q: ArrayLike, v: ArrayLike) -> NDArray[np.float64]:
        """Wheel angular rates [rad/s] realising ``v`` (mecanum: 4, differential drive: 2).

        Order and sign conventions: :class:`~wbc.model.mobile_base.MecanumWheels`,
        :class:`~wbc.model.mobile_base.DifferentialWheels`.

        Raises:
            InvalidInputError: the model declares no wheel geometry, or a malformed ``q`` or ``v``.
        """
        if self.base.wheels is None:
            raise InvalidInputError(f"robot '{self.name}' declares no wheel geometry")
        return self.base.wheels.inverse_matrix() @ self.base_twist(q, v)

    # ------------------------------------------------------------ kinematics
    def frame_pose(self, q: ArrayLike, frame: str) -> NDArray[np.float64]:
        """World pose of ``frame`` at configuration ``q``.

        Returns:
            The 4x4 homogeneous transform of the frame in the world (a new array).

        Raises:
            UnknownFrameError: no frame of that name.
            InvalidInputError: a malformed ``q``.
        """
        frame_id = self.frame_id(frame)
        q = self.check_configuration(q)
        pin.forwardKinematics(self.model, self._data, q)
        return pin.updateFramePlacement(self.model, self._data, frame_id).homogeneous

    def frame_jacobian(self, q: ArrayLike, frame: str) -> NDArray[np.float64]:
        """Jacobian of ``frame`` at configuration ``q``.

        Returns:
            The 6 x nv matrix mapping ``v`` to the frame's twist, world-aligned axes at the frame
            origin (Pinocchio's ``LOCAL_WORLD_ALIGNED``), rows (linear [m/s]; angular [rad/s]).

        Raises:
            UnknownFrameError: no frame of that name.
            InvalidInputError: a malformed ``q``.
        """
        frame_id = self.frame_id(frame)
        q = self.check_configuration(q)
        return pin.computeFrameJacobian(self.model, self._data, q, frame_id, _REFERENCE_FRAME)

    def integrate(self, q: ArrayLike, v: ArrayLike, dt: float) -> NDArray[np.float64]:
        """Configuration reached from ``q`` after moving at constant velocity ``v`` for ``dt`` [s].

        Returns:
            ``pinocchio.integrate(model, q, v * dt)`` (unless the base integrates its coordinates
            otherwise: :meth:`MobileBase.integrate`), a new array of size :attr:`nq`. On a robot
            whose coordinates all form a vector space (1-DOF revolute and prismatic joints, every
            shipped robot) that is ``q + v dt``, computed and checked in one compiled call.

        Raises:
            InvalidInputError: a malformed ``q`` or ``v``, ``dt`` not a finite number > 0, or a step
                ``v dt`` so large that the configuration reached is not finite.
        """
        shape = self._vector_space_shape
        if shape is not None and type(dt) is float:  # the control loop's fast path
            reached = _empty(shape)
            given_q: Any = q  # (their attributes are read inside the try)
            given_v: Any = v
            try:  # float64 vectors (any strides, read-only too): one compiled call, without numba's type check
                if (given_q.dtype is given_v.dtype is _FLOAT64 and given_q.ndim == given_v.ndim == 1
                        and _integrate_vector_space(given_q, given_v, dt, reached)):
                    return reached  # finite: so were q, v and dt
            except (AttributeError, TypeError):  # not ndarrays (the entry unboxes ndarrays only): checked below
                pass
        q = self.check_configuration(q)
        v = self.check_velocity(v)
        if not (type(dt) is float and dt > 0.0 and dt != math.inf):  # the control loop's fast path
            dt = as_positive(dt, "dt")
        with np.errstate(over="ignore", invalid="ignore"):  # (an overflow is refused below)
            reached = self.base.integrate(self.model, q, v, dt)
        if not all_finite(reached):
            raise InvalidInputError(f"q + v dt overflows (dt = {dt}, largest |v| = {np.abs(v).max():g}): "
                                    "no finite configuration is reached")
        return reached

    def __repr__(self) -> str:
        return f"Robot({self.name!r}, nq={self.nq}, nv={self.nv}, base={self.base.name})"

    def __getstate__(self) -> dict[str, Any]:
        """Pickling: Pinocchio 3.3's model serialisation (a boost text archive) cannot read back
        inf, which the limits of a mobile base or a continuous joint hold: the non-finite
        entries of the model's limit vectors travel beside it; the per-use Data is rebuilt."""
        state = self.__dict__.copy()
        model, non_finite = pin.Model(self.model), {}
        for name in _LIMIT_VECTORS:
            values = np.array(getattr(model, name), dtype=np.float64)
            mask = ~np.isfinite(values)
            if mask.any():
                non_finite[name] = (mask, values[mask])
                values[mask] = 0.0
                setattr(model, name, values)
        state.update(model=model, _non_finite=non_finite)
        del state["_data"]
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        model = state["model"]
        for name, (mask, values) in state.pop("_non_finite").items():
            restored = np.array(getattr(model, name), dtype=np.float64)
            restored[mask] = values
            setattr(model, name, restored)
        self.__dict__.update(state)
        self._data = model.createData()


# ---------------------------------------------------------------------------- loading
def shipped_models() -> list[str]:
    """Names of the robots shipped with wbc (the folders of ``models/``, :mod:`wbc.model.shipped`)."""
    root = shipped.folder("models")
    return sorted(p.name for p in root.iterdir() if p.is_dir() and (p / f"{p.name}.toml").is_file())


def model_path(name: str, kind: str = "urdf") -> Path:
    """Path of a shipped model file: ``kind`` is ``"urdf"``, ``"mjcf"`` or ``"toml"``.

    Raises:
        ModelError: no shipped model of that name, or it has no file of that kind.
    """
    if name not in shipped_models():
        raise ModelError(f"no shipped model {name!r}; available: {shipped_models()}")
    folder = shipped.folder("models") / name
    spec, _ = _read_sidecar(folder / f"{name}.toml")
    filename = {"toml": f"{name}.toml", "urdf": spec.urdf, "mjcf": spec.mjcf}.get(kind)
    if filename is None:
        raise ModelError(f"model {name!r} has no {kind} description")
    return folder / filename


def load_robot(name_or_path: str | Path, base: str | None = None, *, wheels: Sequence[str] = (),
               wheel_radius: float | None = None, lock: Sequence[str] = (), replace: Sequence[str] = (),
               max_linear_speed: float | None = None, max_yaw_rate: float | None = None,
               max_wheel_speed: float | None = None) -> Robot:
    """Load a shipped robot by name (``"youbot"``) or any URDF or MJCF (``.xml``, Pinocchio's MJCF
    parser, :mod:`wbc.model.mjcf`) by path.

    A URDF may sit next to a ``<stem>.toml`` sidecar (see ``models/youbot/youbot.toml``)
    that declares the base (an MJCF next to one is read with that sidecar's base). Without one,
    a chain of root joints prismatic-x, prismatic-y, revolute-z, or a URDF ``planar`` root joint,
    is recognised as a holonomic planar base, a free-flyer root joint (a URDF ``floating`` joint,
    an MJCF ``<freejoint/>``) as a floating base; anything else is a fixed-base robot, unless
    ``base`` declares one
    (:mod:`wbc.model.declared_base`: the base joints ``base_x``, ``base_y``, ``base_heading`` are
    put at the root of the model, replacing a ``planar`` root joint):

    Args:
        base: ``"planar"`` (holonomic, no wheel model), ``"mecanum"``, ``"differential"``,
            ``"synchro"``, ``"floating"`` (a free-flyer root joint, :mod:`wbc.model.bases.floating`;
            a URDF ``floating`` root joint is recognised without it) or ``"fixed"``; for a URDF
            without a sidecar (a sidecar declares its base in its ``[base]`` table, with the same keys).
        wheels: the driven wheel joints (differential: 2, mecanum: 4, any order): held at 0 in
            the model (their speeds follow from the base's motion) and read for the wheel model
            (positions, axes, URDF velocity limit, radius of the link's collision cylinder).
        wheel_radius: [m] when the URDF does not give it.
        lock: more joints held at their neutral position (casters, passive wheels).
        replace: the root joints the base joints replace (default: a ``planar`` root joint).
        max_linear_speed: [m/s] ``|v_x|, |v_y|`` limit (default: the replaced joints', else none;
            a floating base: each base-frame linear component).
        max_yaw_rate: [rad/s] ``|omega|`` limit (default as for ``max_linear_speed``; a floating
            base: each base-frame angular component).
        max_wheel_speed: [rad/s] (default: the wheel joints' URDF velocity limit).

    Returns:
        The robot: its Pinocchio model, base, limits (see :class:`Robot`).

    Raises:
        ModelError: neither a shipped model nor a file; an unreadable URDF or sidecar; a sidecar
            key that is unknown, misspelt or invalid (named with the file); a joint with a
            velocity limit of 0 or NaN; a base declaration that does not fit the model (unknown
            joints, wheels the base kind's wheel model does not describe, a radius to give).

    Warns:
        ModelWarning: a robot loaded with a fixed base whose ``continuous`` joints are named
            wheels (declare its base).
    """
    declared = base is not None or any((wheels, wheel_radius, lock, replace, max_linear_speed, max_yaw_rate,
                                        max_wheel_speed))
    if isinstance(name_or_path, str) and name_or_path in shipped_models():
        _no_declaration(declared, name_or_path)
        return _load_from_sidecar(model_path(name_or_path, "toml"))
    if not isinstance(name_or_path, (str, os.PathLike)):
        raise ModelError(f"load_robot takes a shipped model's name ({', '.join(shipped_models())}) or a file's "
                         f"path, got {type(name_or_path).__name__} {name_or_path!r}")
    path = Path(name_or_path)
    if not path.is_file():
        raise ModelError(
            f"{str(name_or_path)!r} is neither a shipped model ({', '.join(shipped_models())}) nor a file"
        )
    sidecar = path if path.suffix == ".toml" else path.with_suffix(".toml")
    if sidecar.is_file():
        _no_declaration(declared, sidecar)
        return _load_from_sidecar(sidecar, path if path.suffix.lower() == ".xml" else None)
    model = _build_model(path)
    where = str(path)
    if declared:
        if base is None:  # limits or joints to hold, for the base the model has: planar if it has one
            base = "planar" if planar_root_joints(model) else "floating" if free_flyer_root(model) else "fixed"
        declaration = BaseDeclaration(base_kind(base), tuple(wheels), wheel_radius,
                                      tuple(lock), tuple(replace), max_linear_speed, max_yaw_rate, max_wheel_speed)
        model, mobile_base = _declared(model, path, declaration, where)
    elif planar_root_joints(model):
        model, mobile_base = declare_base(model, path, BaseDeclaration(BaseKind.PLANAR), where)
    elif free_flyer_root(model) is not None:  # a URDF 'floating' root joint
        model, mobile_base = declare_floating(model, path, BaseDeclaration(BaseKind.FLOATING), where)
    else:
        mobile_base = _detect_planar_base(model)
    _warn_unhandled(model, mobile_base, path)
    return Robot(name=model.name or path.stem, model=model, base=mobile_base, source=path,
                 couplings=coupled_joints(path, model))


def _declared(model: pin.Model, urdf: Path, declaration: BaseDeclaration, where: str) -> tuple[pin.Model, MobileBase]:
    """The model and base of a declaration (a fixed one only locks joints)."""
    if declaration.kind is BaseKind.FLOATING:
        return declare_floating(model, urdf, declaration, where)
    if declaration.kind is not BaseKind.FIXED:
        return declare_base(model, urdf, declaration, where)
    if declaration.wheels or declaration.replace:
        raise ModelError(f"{where}: a fixed base has no wheels and replaces nothing; list joints to hold in lock=[...]")
    speeds = {"max_linear_speed": declaration.max_linear_speed, "max_yaw_rate": declaration.max_yaw_rate,
              "max_wheel_speed": declaration.max_wheel_speed}
    given = [key for key, value in speeds.items() if value is not None]
    if given:
        raise ModelError(f"{where}: {', '.join(given)} bound a mobile base, and this robot is loaded with a fixed "
                         "one; declare its base (base='planar' | 'mecanum' | 'differential' | 'synchro')")
    held = sorted(joint_index(model, name, "lock", where) for name in declaration.lock)
    planar = planar_root_joints(model)  # a planar root joint held: the robot stands at the origin
    free_flyer = free_flyer_root(model)  # the same for a free-flyer root joint
    locked = sorted(set(held + planar + ([free_flyer] if free_flyer else [])))
    return (pin.buildReducedModel(model, locked, pin.neutral(model)) if locked else model), FIXED_BASE


def _no_declaration(declared: bool, where: str | Path) -> None:
    if declared:
        raise ModelError(f"{where}: this robot's base is declared by its sidecar's [base] table; change it there "
                         "(load_robot's base, wheels, ... arguments are for a URDF without a sidecar)")


def _warn_unhandled(model: pin.Model, mobile_base: MobileBase, urdf: Path) -> None:
    """Say what wbc does not model: a mobile robot loaded as fixed, wheels left free."""
    wheels = wheel_like_joints(model)
    if wheels and mobile_base.kind is BaseKind.FIXED:
        warnings.warn(f"{urdf}: continuous joints {wheels} look like wheels, but the robot is loaded with a fixed "
                      "base (its base will not move); declare it: load_robot(path, base='differential' | "
                      "'mecanum' | 'planar', wheels=[...])", ModelWarning, stacklevel=3)
    elif wheels:
        warnings.warn(f"{urdf}: continuous joints {wheels} look like wheels but stay free joints of the model (the "
                      "controller would spin them as it likes); name the driven ones in wheels=[...] and the "
                      "others in lock=[...]", ModelWarning, stacklevel=3)


# ------------------------------------------------------------------ sidecar schema
class MecanumWheelsTable(Table):
    joints: list[str] | None = None  # wheel joints of the URDF: radius and layout read from them
    radius: Positive | None = None
    half_length: Positive | None = None
    half_width: Positive | None = None
    max_speed: Positive | None = None


class DifferentialWheelsTable(Table):
    joints: list[str] | None = None
    radius: Positive | None = None
    half_track: Positive | None = None
    max_speed: Positive | None = None


class FixedBaseTable(Table):
    kind: Literal["fixed"]
    lock: list[str] = []


class FloatingBaseTable(Table):
    kind: Literal["floating"]
    lock: list[str] = []
    max_linear_speed: Positive | None = None  # each base-frame linear component [m/s]
    max_yaw_rate: Positive | None = None  # each base-frame angular component [rad/s]


class MobileBaseTable(Table):
    # the model's own (x, y, heading) joints; None: wbc adds them (replacing ``replace``, e.g. a planar joint)
    joints: Annotated[list[str], Field(min_length=3, max_length=3)] | None = None
    replace: list[str] = []
    lock: list[str] = []
    max_linear_speed: Positive | None = None
    max_yaw_rate: Positive | None = None


class PlanarBaseTable(MobileBaseTable):
    kind: Literal["planar", "synchro"]


class MecanumBaseTable(MobileBaseTable):
    kind: Literal["mecanum"]
    wheels: MecanumWheelsTable | None = None


class UnicycleBaseTable(MobileBaseTable):
    kind: Literal["unicycle", "differential"]
    wheels: DifferentialWheelsTable | None = None


class AccelerationTable(Table):
    """``[acceleration]``: the defaults of :class:`wbc.AccelerationLimits` (cite the source of each number)."""

    joints: dict[str, Positive] = {}  # per joint name [rad/s^2 or m/s^2]
    base_linear: Positive | None = None  # |a_x|, |a_y| of the platform in the base frame [m/s^2]
    base_yaw: Positive | None = None  # yaw acceleration [rad/s^2]
    wheels: Positive | None = None  # wheel acceleration |du_i/dt| [rad/s^2]


class Sidecar(Table):
    """``<name>.toml`` next to a URDF (see models/youbot/youbot.toml)."""

    name: str | None = None
    urdf: str | None = None
    mjcf: str | None = None
    end_effector: str | None = None
    base: Annotated[FixedBaseTable | FloatingBaseTable | PlanarBaseTable | MecanumBaseTable | UnicycleBaseTable,
                    Field(discriminator="kind")] = FixedBaseTable(kind="fixed")
    geometry: dict[str, float] = {}
    acceleration: AccelerationTable | None = None


def _read_sidecar(path: Path) -> tuple[Sidecar, dict[str, Any]]:
    """The validated sidecar and its raw table."""
    params = read_toml(path, ModelError)
    try:
        return Sidecar.model_validate(params), params
    except ValidationError as exc:
        raise ModelError(f"{path}: {explain(exc, Sidecar)}") from None


def _build_model(urdf: Path) -> pin.Model:
    if urdf.suffix.lower() == ".xml":
        return load_mjcf(urdf)
    try:
        return pin.buildModelFromUrdf(str(urdf))
    except (ValueError, RuntimeError) as exc:
        raise ModelError(f"cannot parse URDF {urdf}: {exc}") from exc


def _load_from_sidecar(sidecar: Path, model_file: Path | None = None) -> Robot:
    """The robot a sidecar describes, from its URDF (or ``model_file``: the MJCF asked for)."""
    spec, params = _read_sidecar(sidecar)
    urdf = model_file or sidecar.parent / (spec.urdf or sidecar.with_suffix(".urdf").name)
    model = _build_model(urdf)
    try:
        model, base = _base_from_spec(model, urdf, spec.base)
    except ModelError as exc:
        raise ModelError(f"{sidecar}: {exc}") from exc
    _warn_unhandled(model, base, urdf)
    return Robot(name=spec.name or sidecar.stem, model=model, base=base, end_effector=spec.end_effector,
                 parameters=params, source=urdf, couplings=coupled_joints(urdf, model))


BaseTable = FixedBaseTable | FloatingBaseTable | PlanarBaseTable | MecanumBaseTable | UnicycleBaseTable


def _base_from_spec(model: pin.Model, urdf: Path, spec: BaseTable) -> tuple[pin.Model, MobileBase]:
    """The model and base a sidecar's ``[base]`` table describes."""
    if isinstance(spec, FixedBaseTable):
        return _declared(model, urdf, BaseDeclaration(BaseKind.FIXED, lock=tuple(spec.lock)), "[base]")
    if isinstance(spec, FloatingBaseTable):
        return declare_floating(model, urdf, BaseDeclaration(BaseKind.FLOATING, lock=tuple(spec.lock),
                                                             max_linear_speed=spec.max_linear_speed,
                                                             max_yaw_rate=spec.max_yaw_rate), "[base]")
    wheels = getattr(spec, "wheels", None)
    if spec.joints is None or spec.lock or spec.replace or (wheels is not None and wheels.joints):
        return _declared_from_table(model, urdf, spec, wheels)
    return model, _base_of_joints(model, spec, spec.joints)


def _declared_from_table(model: pin.Model, urdf: Path, spec: PlanarBaseTable | MecanumBaseTable | UnicycleBaseTable,
                         wheels: MecanumWheelsTable | DifferentialWheelsTable | None) -> tuple[pin.Model, MobileBase]:
    """A base wbc builds (:mod:`wbc.model.declared_base`): its joints added, wheels read from the model."""
    if spec.joints is not None:
        raise ModelError("[base] joints names the model's own base joints; lock, replace and [base.wheels] joints "
                         "are for a base wbc adds: remove joints (wbc then adds base_x, base_y, base_heading)")
    read = ("half_length", "half_width") if isinstance(wheels, MecanumWheelsTable) else ("half_track",)
    given = [key for key in read if wheels is not None and getattr(wheels, key) is not None]
    if wheels is not None and wheels.joints and given:
        raise ModelError(f"[base.wheels] {', '.join(given)}: read from the wheel joints' positions when joints is "
                         "given; remove them")
    if wheels is not None and not wheels.joints:
        _wheels(wheels)  # the geometry must then be given in full
    declaration = BaseDeclaration(
        base_kind(spec.kind), wheels=tuple(wheels.joints or ()) if wheels is not None else (),
        wheel_radius=wheels.radius if wheels is not None else None, lock=tuple(spec.lock), replace=tuple(spec.replace),
        max_linear_speed=spec.max_linear_speed, max_yaw_rate=spec.max_yaw_rate,
        max_wheel_speed=wheels.max_speed if wheels is not None else None)
    model, base = declare_base(model, urdf, declaration, "[base]")
    if wheels is not None and not wheels.joints:  # the geometry is given in full
        base = replace_field(base, wheels=_wheels(wheels))
    return model, base


def _base_of_joints(model: pin.Model, spec: PlanarBaseTable | MecanumBaseTable | UnicycleBaseTable,
                    names: list[str]) -> MobileBase:
    """A base on the model's own (x, y, heading) joints."""
    indices = []
    for joint_name in names:
        if not model.existJointName(joint_name):
            raise ModelError(f"[base] joints: {joint_name!r} is not a joint of the URDF"
                             f"{suggest(joint_name, model.names[1:])}")
        joint = model.joints[model.getJointId(joint_name)]
        if joint.nq != 1 or joint.nv != 1:
            raise ModelError(f"[base] joints: {joint_name!r} is a {joint.shortname().removeprefix('JointModel')} "
                             f"joint of {joint.nq} coordinates; the base coordinates are three 1-DOF joints -- "
                             f"for a continuous or planar joint, remove joints and list the model's base joints in "
                             f"replace = [...]: wbc then puts its own base joints in their place")
        indices.append(joint.idx_v)
    _check_base_joints(model, names)
    kind = base_kind(spec.kind)
    return kind_class(kind)(
        kind,
        indices=(indices[0], indices[1], indices[2]),
        max_linear_speed=_or_inf(spec.max_linear_speed),
        max_yaw_rate=_or_inf(spec.max_yaw_rate),
        wheels=_wheels(getattr(spec, "wheels", None)),
    )


#: what each of the (x, y, heading) joints of a mobile base must be: its motion, its world axis
_BASE_JOINTS = (("x", "prismatic", (1.0, 0.0, 0.0)), ("y", "prismatic", (0.0, 1.0, 0.0)),
                ("heading", "revolute", (0.0, 0.0, 1.0)))


def _joint_motion(joint: pin.JointModel) -> tuple[str, np.ndarray] | None:
    """("prismatic" | "revolute", unit axis in the joint frame) of a 1-DOF joint; None otherwise."""
    name = joint.shortname().removeprefix("JointModel")
    if name in ("PrismaticUnaligned", "RevoluteUnaligned"):
        axis = np.asarray(joint.axis, dtype=np.float64)
        return ("prismatic" if name.startswith("P") else "revolute"), axis / np.linalg.norm(axis)
    kinds = {"P": "prismatic", "R": "revolute", "RUB": "revolute"}
    for prefix, kind in kinds.items():
        if name[:-1] == prefix and name[-1] in "XYZ":
            return kind, np.eye(3)["XYZ".index(name[-1])]
    return None


def _check_base_joints(model: pin.Model, names: list[str]) -> None:
    """The ``[base] joints`` are the (x, y, heading) coordinates, in that order: three distinct
    joints chained from the root (x on the root, y on x, heading on y), prismatic along world
    x, prismatic along world y and revolute about world z. Anything else would be read as the
    wrong coordinates (swapped joints gave a wrong base twist and wheel speeds, "optimal")."""
    if len(set(names)) != 3:
        raise ModelError(f"[base] joints = {names} names a joint twice; give the three joints of the base's "
                         "(x, y, heading) coordinates, in that order")
    ids = [model.getJointId(name) for name in names]
    rotation = np.eye(3)
    for k, ((coordinate, kind, axis), name, joint_id) in enumerate(zip(_BASE_JOINTS, names, ids, strict=True)):
        expected_parent = 0 if k == 0 else ids[k - 1]
        if model.parents[joint_id] != expected_parent:
            parent = "the root" if expected_parent == 0 else repr(names[k - 1])
            raise ModelError(f"[base] joints: {name!r} (the {coordinate} coordinate) must hang from {parent}, "
                             f"but hangs from {model.names[model.parents[joint_id]]!r}; list the base joints "
                             "(x, y, heading) in chain order from the root")
        rotation = rotation @ model.jointPlacements[joint_id].rotation
        motion = _joint_motion(model.joints[joint_id])
        world_axis = np.zeros(3) if motion is None else rotation @ motion[1]  # (unread without motion)
        if motion is None or motion[0] != kind or not np.allclose(world_axis, axis, atol=1e-9):
            found = "not a revolute or prismatic joint" if motion is None else \
                f"{motion[0]} along {np.round(world_axis, 6).tolist()}"
            raise ModelError(f"[base] joints: {name!r} is the {coordinate} coordinate, so it must be {kind} "
                             f"along world {list(axis)}; it is {found} (joints listed as (x, y, heading))")


def _or_inf(value: float | None) -> float:
    """An optional speed limit: None (not given) means unbounded."""
    return np.inf if value is None else value


def _wheels(spec: MecanumWheelsTable | DifferentialWheelsTable | None) -> MecanumWheels | DifferentialWheels | None:
    """The wheel model a ``[base.wheels]`` table gives in full (radius and layout)."""
    if spec is None:
        return None
    fields = spec.model_dump(exclude={"joints"}) | {"max_speed": _or_inf(spec.max_speed)}
    missing = [key for key, value in fields.items() if value is None]
    if missing:
        raise ModelError(f"[base.wheels] {', '.join(missing)}: required key missing; give it, or the wheel joints "
                         "(joints = [...]) to read the geometry from the model")
    wheel_type = MecanumWheels if isinstance(spec, MecanumWheelsTable) else DifferentialWheels
    return wheel_type(**fields)


def _detect_planar_base(model: pin.Model) -> MobileBase:
    """Recognise root joints (prismatic x, prismatic y, revolute z) as a planar base."""
    expected = ("JointModelPX", "JointModelPY", "JointModelRZ")
    if model.njoints < 4:
        return FIXED_BASE
    joints = [model.joints[i] for i in (1, 2, 3)]
    chained = all(model.parents[i] == i - 1 for i in (1, 2, 3))
    if chained and tuple(j.shortname() for j in joints) == expected:
        limits = model.velocityLimit
        return PlanarBase(
            indices=(joints[0].idx_v, joints[1].idx_v, joints[2].idx_v),
            max_linear_speed=float(min(limits[joints[0].idx_v], limits[joints[1].idx_v])),
            max_yaw_rate=float(limits[joints[2].idx_v]),
        )
    return FIXED_BASE


__all__ = ["Robot", "load_robot", "shipped_models", "model_path", "rpy_matrix"]
