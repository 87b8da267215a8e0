"""Joint couplings: a joint that follows another (a URDF ``<mimic>``, e.g. the second finger of a
parallel gripper).

A coupling ``q_joint = multiplier q_leader + offset`` holds at every configuration on the path
when it holds at the start and the velocities obey ``v_joint = multiplier v_leader``, which
:class:`wbc.MimicJoints` makes an equality row of the control QP (every controller of a robot
with couplings adds it). Recent Pinocchio releases (pin 4.1) can build mimic joints into the
model itself; wbc keeps the joints and couples their velocities, the same with every supported
Pinocchio (down to 3.3.1).
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ElementTree
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import pinocchio as pin

from ..core.errors import ModelError
from .declared_base import joint_index


@dataclass(frozen=True)
class JointCoupling:
    """``q_joint = multiplier q_leader + offset`` [rad or m], so ``v_joint = multiplier v_leader``."""

    joint: str  #: the joint that follows (the URDF's ``<mimic>`` joint)
    leader: str  #: the joint it follows
    multiplier: float = 1.0
    offset: float = 0.0


def urdf_couplings(urdf: Path | None) -> tuple[JointCoupling, ...]:
    """The ``<mimic joint=... multiplier=... offset=...>`` elements of a URDF (defaults 1 and 0)."""
    if urdf is None or urdf.suffix.lower() != ".urdf":
        return ()
    couplings = []
    for joint in ElementTree.parse(urdf).getroot().iterfind("joint"):
        mimic = joint.find("mimic")
        if mimic is not None:
            couplings.append(JointCoupling(str(joint.get("name")), str(mimic.get("joint")),
                                           float(mimic.get("multiplier", "1")), float(mimic.get("offset", "0"))))
    return tuple(couplings)


def coupled_joints(urdf: Path | None, model: pin.Model) -> tuple[JointCoupling, ...]:
    """The URDF's couplings of joints ``model`` still has (a locked ``<mimic>`` joint is rigid)."""
    return tuple(coupling for coupling in urdf_couplings(urdf) if model.existJointName(coupling.joint))


def check_couplings(model: pin.Model, couplings: Sequence[JointCoupling], where: str) -> None:
    """Each coupling joins two distinct 1-DOF joints of ``model`` with a finite multiplier.

    Raises:
        ModelError: an unknown joint (a leader that was locked: lock its follower too), a joint
            with more than one velocity coordinate, a joint coupled to itself or twice, a
            multiplier or offset that is not finite.
    """
    followers = [coupling.joint for coupling in couplings]
    for coupling in couplings:
        name = f"joint {coupling.joint!r} (mimics {coupling.leader!r})"
        if not model.existJointName(coupling.leader):
            raise ModelError(f"{where}: {name}: {coupling.leader!r} is locked or not a joint of the model; lock "
                             f"{coupling.joint!r} too (lock=[...])")
        for joint in (coupling.joint, coupling.leader):
            nv = model.joints[joint_index(model, joint, "mimic", where)].nv
            if nv != 1:
                raise ModelError(f"{where}: {name}: {joint!r} has {nv} velocity coordinates; wbc couples 1-DOF "
                                 f"joints only: lock {coupling.joint!r} (lock=[...])")
        if coupling.joint == coupling.leader or followers.count(coupling.joint) > 1:
            raise ModelError(f"{where}: {name} is coupled to itself or twice; couple each joint to one other")
        if not (math.isfinite(coupling.multiplier) and math.isfinite(coupling.offset)):
            raise ModelError(f"{where}: {name}: multiplier {coupling.multiplier}, offset {coupling.offset}; give "
                             "finite numbers (<mimic multiplier=... offset=...>)")


__all__ = ["JointCoupling", "urdf_couplings", "coupled_joints", "check_couplings"]
