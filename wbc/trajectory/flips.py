"""Detection of wrist flips in a sampled joint trajectory.

Near the wrist singularity of a 6R arm with a spherical wrist (PUMA: theta5 = 0, axes 4
and 6 aligned) a tool motion that passes the singular direction at a small angle eps
needs joints 4 and 6 to **counter-rotate by nearly pi** within a stretch of path of
order eps: the wrist changes from one IK solution (theta4, theta5, theta6) toward the
other (theta4 + pi, -theta5, theta6 + pi) and the joint rates grow like 1 / eps. That
is the "flip" of Lu et al. (joint 4 jumps from one value to another, sec. 4).

A flip is reported where joints a and b both turn by at least ``angle`` (default
pi/2), in opposite directions, within a time window shorter than ``angle / rate_a``
(default rate: the joint's velocity limit): faster, on average, than the drive may
turn. Turning by pi at bounded speed (the detour of :mod:`.planner`, which keeps
``|theta5|`` away from 0) is not a flip.

A *branch switch* (:func:`branch_switches`) is the other way through: theta5 changes
sign, the wrist passes through the singular set and ends on the other IK solution. A
resolved-rate controller that cannot follow a flip (speed limits) often does this.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.errors import InvalidInputError
from ..model.robot import Robot
from .sampling import JointTrajectory


@dataclass(frozen=True)
class WristFlip:
    """One flip: the shortest window [start, end] in which both joints turned by ``angle``."""

    start: float  #: [s]
    end: float  #: [s]
    change_a: float  #: [rad] of the first joint over the window
    change_b: float  #: [rad] of the second joint over the window


def joint_index(robot: Robot, name: str) -> int:
    """Velocity index of a 1-DOF joint given by name."""
    if not robot.model.existJointName(name):
        raise InvalidInputError(f"robot {robot.name!r} has no joint {name!r}; known: {robot.joint_names}")
    return robot.model.joints[robot.model.getJointId(name)].idx_v


def wrist_flips(robot: Robot, trajectory: JointTrajectory, joints: tuple[str, str],
                angle: float = np.pi / 2, rate: float | None = None) -> list[WristFlip]:
    """Windows where ``joints`` counter-rotate by >= ``angle`` faster than ``rate`` on average.

    ``rate`` [rad/s] defaults to the velocity limit of the first joint. Overlapping windows
    form one flip, reported by its shortest window.
    """
    a, b = (joint_index(robot, name) for name in joints)
    rate = robot.velocity_limit[a] if rate is None else rate
    window = angle / rate
    time, qa, qb = trajectory.time, trajectory.q[:, a], trajectory.q[:, b]
    hits: list[tuple[int, int]] = []  # (i, j): first j at which both turned by angle since i
    for i in range(time.size):
        inside = slice(i, np.searchsorted(time, time[i] + window, side="right"))
        turned_a, turned_b = qa[inside] - qa[i], qb[inside] - qb[i]
        found = np.flatnonzero((np.abs(turned_a) >= angle) & (np.abs(turned_b) >= angle)
                               & (turned_a * turned_b < 0.0))
        if found.size:
            hits.append((i, i + int(found[0])))
    flips: list[WristFlip] = []
    group: list[tuple[int, int]] = []
    for hit in hits + [None]:
        if group and (hit is None or hit[0] > group[-1][1]):  # a group of overlapping windows ends
            i, j = min(group, key=lambda h: time[h[1]] - time[h[0]])
            flips.append(WristFlip(float(time[i]), float(time[j]), float(qa[j] - qa[i]), float(qb[j] - qb[i])))
            group = []
        if hit is not None:
            group.append(hit)
    return flips


def branch_switches(robot: Robot, trajectory: JointTrajectory, joint: str) -> np.ndarray:
    """Times [s] where sin(q_joint) changes sign: for the PUMA wrist (joint = "joint_5") the
    motion moves from one wrist IK solution, (theta4, theta5, theta6), to the other,
    (theta4 + pi, -theta5, theta6 + pi), which is only possible through theta5 = 0."""
    sign = np.sign(np.sin(trajectory.q[:, joint_index(robot, joint)]))
    signed = np.flatnonzero(sign)  # samples exactly on the set do not decide
    changes = signed[1:][sign[signed[1:]] != sign[signed[:-1]]]
    return trajectory.time[changes]
