"""MJCF (MuJoCo) models through Pinocchio's MJCF parser, in the shape wbc reads.

Pinocchio gathers the joints of one MJCF ``<body>`` into a single composite joint (the youBot's
``base_x``, ``base_y``, ``base_yaw`` become ``Composite_base_x``, 3 coordinates). wbc drives a
base through separate 1-DOF joints, so :func:`load_mjcf` expands every composite into the chain
of its joints, named as in the file; the kinematics are unchanged. MJCF ``<equality>``
constraints (closed loops, joint couplings) are not modelled: loading warns and names the fix.
The expansion needs Pinocchio >= 4 (:data:`MIN_PIN_FOR_COMPOSITES`): pin 3.3.1's composite joints
of an MJCF body gave other kinematics than its own model when expanded, so an MJCF body with
several joints is refused there (a body with one joint each loads with any pin).
"""

from __future__ import annotations

import warnings
import xml.etree.ElementTree as ElementTree
from pathlib import Path

import numpy as np
import pinocchio as pin

from ..core.errors import ModelError, ModelWarning

#: the oldest Pinocchio whose composite joints (an MJCF body with several joints) wbc expands:
#: checked on 4.1 (same kinematics as Pinocchio's own model) and 3.3.1 (not the same)
MIN_PIN_FOR_COMPOSITES = (4, 0)


def load_mjcf(path: Path) -> pin.Model:
    """Pinocchio's model of an MJCF file, its composite joints expanded into 1-DOF chains.

    Raises:
        ModelError: a file Pinocchio's MJCF parser cannot read.
    Warns:
        ModelWarning: the file has ``<equality>`` constraints, which wbc does not model.
    """
    try:
        model = pin.buildModelFromMJCF(str(path))
        root = ElementTree.parse(path).getroot()
    except (ValueError, RuntimeError, ElementTree.ParseError) as exc:
        raise ModelError(f"cannot parse MJCF {path}: {exc}") from exc
    equality = [child.get("name") or child.tag for block in root.iterfind("equality") for child in block]
    if equality:
        warnings.warn(f"{path}: MJCF <equality> constraints {equality} (closed loops, couplings) are not modelled: "
                      "the joints move independently; lock them (lock=[...]) or couple 1-DOF joints with "
                      "wbc.MimicJoints", ModelWarning, stacklevel=3)
    return expand_composite_joints(model, _body_joint_names(root))


def _body_joint_names(root: ElementTree.Element) -> dict[str, list[str]]:
    """The joints of each MJCF body that has several, by the name of its first (Pinocchio names the
    composite ``Composite_<first>``)."""
    names = {}
    for body in root.iter("body"):
        joints = [joint.get("name", "") for joint in body if joint.tag in ("joint", "freejoint")]
        if len(joints) > 1 and all(joints):
            names[f"Composite_{joints[0]}"] = joints
    return names


def expand_composite_joints(model: pin.Model, names: dict[str, list[str]]) -> pin.Model:
    """``model`` with each composite joint replaced by the chain of its joints (named from
    ``names``, else ``<composite>_<k>``), the bodies on the last joint of each chain, every frame
    kept; the same kinematics, limits and inertias."""
    if not any(joint.shortname() == "JointModelComposite" for joint in model.joints):
        return model
    if tuple(int(part) for part in pin.__version__.split(".")[:2]) < MIN_PIN_FOR_COMPOSITES:
        raise ModelError(f"an MJCF <body> with several joints needs pinocchio >= "
                         f"{'.'.join(map(str, MIN_PIN_FOR_COMPOSITES))} (this is {pin.__version__}): "
                         "pip install -U pin, or give each joint a body of its own")
    expanded = pin.Model()
    expanded.name = model.name
    joint_map, frame_map = {0: 0}, {0: 0}
    for j in range(1, model.njoints):
        joint, parent, placement = model.joints[j], joint_map[model.parents[j]], model.jointPlacements[j]
        parts = _parts(joint, model.names[j], names)
        q_start, v_start = joint.idx_q, joint.idx_v
        for k, (name, part, part_placement) in enumerate(parts):
            q_slice, v_slice = slice(q_start, q_start + part.nq), slice(v_start, v_start + part.nv)
            parent = expanded.addJoint(parent, part, placement * part_placement if k == 0 else part_placement, name,
                                       np.asarray(model.effortLimit[v_slice]),
                                       np.asarray(model.velocityLimit[v_slice]),
                                       np.asarray(model.lowerPositionLimit[q_slice]),
                                       np.asarray(model.upperPositionLimit[q_slice]))
            q_start, v_start = q_start + part.nq, v_start + part.nv
        expanded.appendBodyToJoint(parent, model.inertias[j], pin.SE3.Identity())
        joint_map[j] = parent
    for f in range(1, model.nframes):
        frame = model.frames[f]
        # parentFrame is the frame tree's bookkeeping (placements are relative to parentJoint);
        # pin 3.3's MJCF parser gives a site its own index there: the universe stands in for it
        parent_frame = frame_map.get(frame.parentFrame, 0)
        frame_map[f] = expanded.addFrame(pin.Frame(frame.name, joint_map[frame.parentJoint], parent_frame,
                                                   frame.placement, frame.type, frame.inertia), False)
    return expanded


def _parts(joint: pin.JointModel, name: str,
           names: dict[str, list[str]]) -> list[tuple[str, pin.JointModel, pin.SE3]]:
    """(name, joint, placement after the previous part) of each part of a joint: itself, or
    the parts of a composite."""
    if joint.shortname() != "JointModelComposite":
        return [(name, joint, pin.SE3.Identity())]
    composite = joint.extract()
    parts = list(zip(composite.joints, composite.jointPlacements, strict=True))
    labels = names.get(name, [])
    if len(labels) != len(parts):
        labels = [f"{name}_{k}" for k in range(len(parts))]
    return [(label, part.extract() if hasattr(part, "extract") else part, placement)
            for label, (part, placement) in zip(labels, parts, strict=True)]


__all__ = ["load_mjcf", "expand_composite_joints"]
