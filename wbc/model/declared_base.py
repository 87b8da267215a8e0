"""Declared bases: give any robot model the base joints wbc drives, and read its wheels.

wbc drives a mobile base through three 1-DOF joints at the root of the model, the base
coordinates ``(x [m], y [m], heading [rad])`` (:mod:`wbc.model.mobile_base`). Third-party models
rarely have them: TIAGo's URDF starts at ``base_footprint`` with its wheels as ``continuous``
joints (it loads as a fixed robot with two free wheels), Reachback's and Stretch's start with a
URDF ``planar`` joint (one joint of 4 coordinates ``(x, y, cos, sin)``). :func:`declare_base`
turns such a model into one wbc can drive:

1. the joints it is told to *replace* (a ``planar`` root joint, or a chain of root joints that
   are not three 1-DOF joints, e.g. a ``continuous`` yaw joint) and to *lock* (the wheels, and
   casters or passive wheels given as ``lock``) are held at their neutral position
   (``pinocchio.buildReducedModel``): the bodies behind them become rigid parts of their parent;
2. three joints ``base_x`` (prismatic along world x), ``base_y`` (prismatic along world y),
   ``base_heading`` (revolute about world z) are put at the root, and the model is attached to
   the last of them (``pinocchio.appendModel``): the model's root frame (``base_footprint``) is
   the base frame, its origin the base reference point, and ``q = (x, y, heading, joints...)``.

The wheels of a ``differential`` (2) or ``mecanum`` (4) base are read from the model: positions
and axes from the wheel joints at the neutral configuration, the radius from each wheel link's
``<collision>`` cylinder or sphere in the URDF. What cannot be read is asked for by name
(``wheel_radius=``), and a layout the wheel model does not describe (a differential axle that
does not pass through the base origin, wheels not symmetric) is refused with the numbers.
"""

from __future__ import annotations

import difflib
import math
import xml.etree.ElementTree as ElementTree
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from ..core.errors import InvalidInputError, ModelError
from .bases.floating import FloatingBase, free_flyer_root
from .bases.interface import LAYOUT_TOLERANCE, WheelMount, Wheels, kind_class
from .mobile_base import BaseKind, MobileBase

#: names of the base joints :func:`declare_base` adds, (x, y, heading)
BASE_JOINT_NAMES = ("base_x", "base_y", "base_heading")
#: base kinds by the name :func:`wbc.load_robot` accepts ("differential" is wbc's unicycle)
KIND_NAMES = {"fixed": BaseKind.FIXED, "planar": BaseKind.PLANAR, "mecanum": BaseKind.MECANUM,
              "differential": BaseKind.UNICYCLE, "unicycle": BaseKind.UNICYCLE, "synchro": BaseKind.SYNCHRO,
              "floating": BaseKind.FLOATING}
#: [m] how far two wheel radii may differ
RADIUS_TOLERANCE = 1e-9


@dataclass(frozen=True)
class BaseDeclaration:
    """What the user declares about a base (see :func:`wbc.load_robot`).

    Lengths in [m], speeds in [m/s], [rad/s].
    """

    kind: BaseKind
    wheels: tuple[str, ...] = ()  #: driven wheel joints, any order (sorted by position)
    wheel_radius: float | None = None  #: [m]; None: read from the wheels' collision shapes
    lock: tuple[str, ...] = ()  #: further joints held at their neutral position (casters, ...)
    replace: tuple[str, ...] = ()  #: root joints the base joints replace (found when empty)
    max_linear_speed: float | None = None  #: ``|v_x|, |v_y|`` limit; None: the model's or unbounded
    max_yaw_rate: float | None = None  #: ``|omega|`` limit; None: the model's or unbounded
    max_wheel_speed: float | None = None  #: [rad/s]; None: the wheel joints' URDF velocity limit


def base_kind(name: str) -> BaseKind:
    """The base kind called ``name`` (``"planar"``, ``"mecanum"``, ``"differential"``, ...).

    Raises:
        ModelError: an unknown name.
    """
    if not isinstance(name, str) or name not in KIND_NAMES:
        raise ModelError(f"unknown base kind {name!r}; choose one of {sorted(KIND_NAMES)}")
    return KIND_NAMES[name]


def planar_root_joints(model: pin.Model) -> list[int]:
    """The URDF ``planar`` joints at the root of ``model`` (Pinocchio's ``JointModelPlanar``)."""
    return [j for j in range(1, model.njoints)
            if model.parents[j] == 0 and model.joints[j].shortname() == "JointModelPlanar"]


def root_chain(model: pin.Model) -> list[int]:
    """The root joints prismatic x, prismatic y, revolute z, chained in that order (a base the
    model already has, e.g. the shipped youBot's); empty when the model does not start so."""
    expected = ("JointModelPX", "JointModelPY", "JointModelRZ")
    if model.njoints < 4 or any(model.parents[j] != j - 1 for j in (1, 2, 3)):
        return []
    return [1, 2, 3] if tuple(model.joints[j].shortname() for j in (1, 2, 3)) == expected else []


def declare_base(model: pin.Model, urdf: Path | None, declaration: BaseDeclaration,
                 where: str) -> tuple[pin.Model, MobileBase]:
    """``model`` with the base joints of ``declaration`` at its root, and its :class:`MobileBase`.

    A model whose root already is the (x, y, heading) chain is not rebuilt, unless joints are
    to be locked. ``urdf`` (when the model came from one) is where the wheel radii are read.

    Raises:
        ModelError: an unknown joint, a wheel that is not a 1-DOF revolute joint on the base
            body, a wheel count or layout the base kind's wheel model does not describe, a wheel
            radius that can be read from nowhere.
    """
    kind = declaration.kind
    replace = [joint_index(model, name, "replace", where) for name in declaration.replace]
    chain = [] if replace else root_chain(model)  # the model's own (x, y, heading) joints, kept
    if not replace and not chain:
        replace = planar_root_joints(model)
    _check_replaceable(model, replace, where)
    wheel_ids = [joint_index(model, name, "wheels", where) for name in declaration.wheels]
    lock_ids = [joint_index(model, name, "lock", where) for name in declaration.lock]
    _check_distinct(model, chain + replace + wheel_ids + lock_ids, where)
    base_joint = (chain or replace or [0])[-1]  # the joint whose body is the base body
    count = kind_class(kind).wheel_count
    if count and wheel_ids and len(wheel_ids) != count:
        raise ModelError(f"{where}: a {_kind_name(kind)} base has {count} driven wheels, {len(wheel_ids)} "
                         f"given ({', '.join(declaration.wheels)}); list the driven ones in wheels=[...] and the "
                         "others (casters, passive wheels) in lock=[...]")
    wheels = _read_wheels(model, urdf, declaration, wheel_ids, base_joint, where) if wheel_ids else None
    linear, yaw = _base_speeds(model, chain or replace, declaration)
    locked = sorted(replace + wheel_ids + lock_ids)
    reduced = pin.buildReducedModel(model, locked, pin.neutral(model)) if locked else model
    names = [model.names[j] for j in chain] if chain else list(BASE_JOINT_NAMES)
    with_base = reduced if chain else _prepend_base_joints(reduced, where)
    indices = tuple(with_base.joints[with_base.getJointId(name)].idx_v for name in names)
    return with_base, kind_class(kind)(kind, indices=(indices[0], indices[1], indices[2]), max_linear_speed=linear,
                                       max_yaw_rate=yaw, wheels=wheels)


def declare_floating(model: pin.Model, urdf: Path | None, declaration: BaseDeclaration,
                     where: str) -> tuple[pin.Model, FloatingBase]:
    """``model`` on a free-flyer root joint, and its :class:`FloatingBase`.

    A model whose root joint is a free flyer (a URDF ``floating`` root joint) keeps it; a URDF
    without one is parsed again with Pinocchio's ``JointModelFreeFlyer`` as its root joint
    (named ``root_joint``; the root link's inertia then moves with it). Joints in ``lock`` are
    held at their neutral position.

    Raises:
        ModelError: wheels, replaced joints or a wheel speed declared (a floating base has none),
            a planar root the free flyer would sit on, a model that is not a URDF and has no free
            flyer, or the free flyer itself locked.
    """
    given = [key for key, value in (("wheels", declaration.wheels), ("replace", declaration.replace),
                                    ("max_wheel_speed", declaration.max_wheel_speed)) if value]
    if given:
        raise ModelError(f"{where}: {', '.join(given)}: a floating base has no wheels and replaces no root joint; "
                         "remove them (lock=[...] holds joints)")
    if planar_root_joints(model) or root_chain(model):
        raise ModelError(f"{where}: the model's root already is a planar base; declare base='planar' (or a wheeled "
                         "kind) for it, or remove its planar root joint from the model for a floating base")
    if free_flyer_root(model) is None:
        if urdf is None or urdf.suffix.lower() != ".urdf":
            raise ModelError(f"{where}: base='floating' needs a URDF (parsed again with a free-flyer root) or a "
                             "model whose root joint is a free flyer (a URDF 'floating' root joint, an MJCF "
                             "<freejoint/>)")
        model = pin.buildModelFromUrdf(str(urdf), pin.JointModelFreeFlyer())
    locked = sorted(joint_index(model, name, "lock", where) for name in declaration.lock)
    if locked:
        model = pin.buildReducedModel(model, locked, pin.neutral(model))
    root = free_flyer_root(model)
    if root is None:
        raise ModelError(f"{where}: lock holds the free-flyer root joint; declare base='fixed' for a robot bolted "
                         "to the world")
    joint = model.joints[root]
    return model, FloatingBase(BaseKind.FLOATING, configuration_start=joint.idx_q, velocity_start=joint.idx_v,
                               max_linear_speed=declaration.max_linear_speed or math.inf,
                               max_yaw_rate=declaration.max_yaw_rate or math.inf)


# ------------------------------------------------------------------ model surgery
def _prepend_base_joints(model: pin.Model, where: str) -> pin.Model:
    """``model`` hung from new root joints prismatic x, prismatic y, revolute z."""
    clash = [name for name in BASE_JOINT_NAMES if model.existJointName(name)]
    if clash:
        raise ModelError(f"{where}: the model already has joints named {clash}, the names of the base joints wbc "
                         "adds; rename them in the URDF, or list the model's own base joints in a sidecar's "
                         "[base] joints")
    base = pin.Model()
    base.name = model.name
    parent = 0
    motions = (pin.JointModelPX(), pin.JointModelPY(), pin.JointModelRZ())
    for name, motion in zip(BASE_JOINT_NAMES, motions, strict=True):
        parent = base.addJoint(parent, motion, pin.SE3.Identity(), name)
        base.addJointFrame(parent, -1)
    attachment = base.getFrameId(BASE_JOINT_NAMES[-1])
    return pin.appendModel(base, model, attachment, pin.SE3.Identity())


# ------------------------------------------------------------------ wheels
def _read_wheels(model: pin.Model, urdf: Path | None, declaration: BaseDeclaration, wheel_ids: list[int],
                 base_joint: int, where: str) -> Wheels | None:
    """The wheel model of the base kind from the wheel joints (None for kinds without one)."""
    data = model.createData()
    pin.forwardKinematics(model, data, pin.neutral(model))
    base_pose = data.oMi[base_joint]
    wheels = []
    for joint_id in wheel_ids:
        name = model.names[joint_id]
        axis_local = _revolute_axis(model.joints[joint_id])
        if axis_local is None:
            raise ModelError(f"{where}: wheel {name!r} is a {model.joints[joint_id].shortname()}; a wheel is a "
                             "revolute or continuous joint")
        if model.parents[joint_id] != base_joint:
            raise ModelError(f"{where}: wheel {name!r} hangs from joint {model.names[model.parents[joint_id]]!r}, "
                             "which moves on the base; a driven wheel is mounted on the base body itself")
        placement = base_pose.actInv(data.oMi[joint_id])
        radius = declaration.wheel_radius or _urdf_wheel_radius(urdf, model, joint_id, where)
        wheels.append(WheelMount(name, np.array(placement.translation), placement.rotation @ axis_local, radius,
                             float(model.velocityLimit[model.joints[joint_id].idx_v])))
    radii = [wheel.radius for wheel in wheels]
    if max(radii) - min(radii) > RADIUS_TOLERANCE:
        raise ModelError(f"{where}: the wheels' radii differ ({', '.join(f'{w.name}: {w.radius} m' for w in wheels)});"
                         " wbc's wheel models have one radius: pass wheel_radius=... [m]")
    for wheel in wheels:
        if abs(abs(wheel.axis[1]) - 1.0) > LAYOUT_TOLERANCE:
            raise ModelError(f"{where}: wheel {wheel.name!r} turns about {np.round(wheel.axis, 6).tolist()} in the "
                             "base frame; a driven wheel turns about the base's y axis (its x axis is forward)")
    max_speed = declaration.max_wheel_speed or min(wheel.max_speed for wheel in wheels)
    kind = kind_class(declaration.kind)
    if kind.wheel_count and len(wheels) == kind.wheel_count:
        return kind.wheels_from_mounts(wheels, radii[0], max_speed, where)
    return None  # a kind without a wheel model (planar, synchro), or a count refused by the caller: locked only


def _urdf_wheel_radius(urdf: Path | None, model: pin.Model, joint_id: int, where: str) -> float:
    """The radius of the wheel's ``<collision>`` cylinder (or sphere) in the URDF."""
    name = model.names[joint_id]
    ask = "pass wheel_radius=... [m] (or [base.wheels] radius in a sidecar)"
    if urdf is None or urdf.suffix.lower() != ".urdf":
        raise ModelError(f"{where}: the radius of wheel {name!r} is not in the model; {ask}")
    root = ElementTree.parse(urdf).getroot()
    joint = root.find(f"joint[@name='{name}']")
    child = joint.find("child") if joint is not None else None
    link = root.find(f"link[@name='{child.get('link')}']") if child is not None else None
    radii = {float(shape.get("radius", "nan")) for shape in (link.iterfind("collision/geometry/*") if link is not None
                                                             else ()) if shape.tag in ("cylinder", "sphere")}
    if len(radii) != 1 or not all(math.isfinite(r) and r > 0.0 for r in radii):
        found = "no collision cylinder or sphere" if not radii else f"collision radii {sorted(radii)}"
        raise ModelError(f"{where}: cannot read the radius of wheel {name!r} from {urdf.name} ({found} on its "
                         f"link); {ask}")
    return radii.pop()


def _revolute_axis(joint: pin.JointModel) -> np.ndarray | None:
    """Unit axis (joint frame) of a revolute or continuous joint; None for other joints."""
    name = joint.shortname().removeprefix("JointModel")
    if name in ("RevoluteUnaligned", "RevoluteUnboundedUnaligned"):
        axis = np.asarray(joint.axis, dtype=np.float64)
        return axis / np.linalg.norm(axis)
    if name in ("RX", "RY", "RZ", "RUBX", "RUBY", "RUBZ"):
        return np.eye(3)["XYZ".index(name[-1])]
    return None


# ------------------------------------------------------------------ speeds and names
def _base_speeds(model: pin.Model, joints: list[int], declaration: BaseDeclaration) -> tuple[float, float]:
    """(max linear speed, max yaw rate): declared, else the velocity limits of the model's base
    joints (a planar joint's (v_x, v_y, omega), or the x, y, heading joints'), else unbounded (the
    wheel speed limits then bound the base, through WheelSpeedLimits)."""
    limits = np.concatenate([model.velocityLimit[model.joints[j].idx_v:model.joints[j].idx_v + model.joints[j].nv]
                             for j in joints]) if joints else np.full(3, math.inf)
    model_linear, model_yaw = (float(min(limits[0], limits[1])), float(limits[2])) if limits.size == 3 \
        else (math.inf, math.inf)
    linear = declaration.max_linear_speed or (model_linear if model_linear > 0.0 else math.inf)
    yaw = declaration.max_yaw_rate or (model_yaw if model_yaw > 0.0 else math.inf)
    return linear, yaw


def _check_replaceable(model: pin.Model, joints: list[int], where: str) -> None:
    """Joints replaced by base joints at the root: a chain from the root whose placements have no
    horizontal offset and no rotation, so that ``(x, y, heading)`` at the root moves the rest
    exactly as they did (a vertical offset commutes with the heading rotation)."""
    for k, joint_id in enumerate(joints):
        name = model.names[joint_id]
        if model.parents[joint_id] != (joints[k - 1] if k else 0):
            raise ModelError(f"{where}: replace: {name!r} does not hang from "
                             f"{repr(model.names[joints[k - 1]]) if k else 'the root'}; list the joints the base "
                             "replaces in chain order from the root")
        placement = model.jointPlacements[joint_id]
        if np.abs(placement.translation[:2]).max() > LAYOUT_TOLERANCE \
                or np.abs(placement.rotation - np.eye(3)).max() > LAYOUT_TOLERANCE:
            raise ModelError(f"{where}: joint {name!r}, which the base joints replace, is placed at "
                             f"{np.round(placement.translation, 6).tolist()} with a rotation; wbc's base joints "
                             "replace root joints placed straight above the root (no horizontal offset, no "
                             "rotation) -- move the offset into the child link's joint in the URDF")


def joint_index(model: pin.Model, name: str, key: str, where: str) -> int:
    """Pinocchio's index of joint ``name``; ModelError naming ``where``, ``key`` and close names otherwise."""
    if not isinstance(name, str) or not model.existJointName(name):
        close = difflib.get_close_matches(str(name), list(model.names[1:]), n=3)
        hint = f"; did you mean {', '.join(map(repr, close))}?" if close else ""
        raise ModelError(f"{where}: {key}: {name!r} is not a joint of the model{hint}")
    return int(model.getJointId(name))


def joint_columns(model: pin.Model, joints: Sequence[str], where: str) -> NDArray[np.intp]:
    """The velocity coordinates of ``joints`` (every coordinate of each, in their order).

    Raises:
        ModelError: an unknown joint (with close names, :func:`joint_index`).
        InvalidInputError: a joint named twice.
    """
    ids = [joint_index(model, name, "joints", where) for name in joints]
    repeated = sorted({name for name in joints if list(joints).count(name) > 1})
    if repeated:
        raise InvalidInputError(f"{where}: joints {repeated} named twice; name each joint once")
    return np.array([i for j in ids for i in range(model.joints[j].idx_v, model.joints[j].idx_v + model.joints[j].nv)],
                    dtype=np.intp)


def _check_distinct(model: pin.Model, ids: list[int], where: str) -> None:
    repeated = sorted({model.names[j] for j in ids if ids.count(j) > 1})
    if repeated:
        raise ModelError(f"{where}: joints {repeated} are named twice among replace, wheels and lock")


def _kind_name(kind: BaseKind) -> str:
    return "differential" if kind is BaseKind.UNICYCLE else kind.value


def wheel_like_joints(model: pin.Model) -> list[str]:
    """``continuous`` joints whose name says wheel: a mobile robot loaded without a base."""
    return [model.names[j] for j in range(1, model.njoints)
            if model.joints[j].shortname().startswith("JointModelRUB") and "wheel" in model.names[j].lower()]


__all__ = ["BaseDeclaration", "declare_base", "declare_floating", "base_kind", "planar_root_joints", "root_chain",
           "wheel_like_joints", "joint_index", "BASE_JOINT_NAMES", "KIND_NAMES"]
