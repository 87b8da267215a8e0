"""Singular-region-aware planning (Lu et al., sec. 3): sample, check, re-route.

1. **Sample.** The Cartesian path, timed by the rest-to-rest quintic s(t) over
   ``duration``, is followed by IK continuation (:func:`.sampling.follow`): joint
   positions, rates and the singularity measure m = det(J_s^T J_s)
   (:func:`wbc.analysis.singularity.singularity_measure`, dimensionless) at every sample.
2. **Check.** Samples with m <= ``threshold`` lie in the singular region (the paper's
   eq. 6, with a unit-free measure).
3. **Re-route.** Every maximal run of samples with m < ``margin * threshold`` that
   reaches m <= threshold is cut out of the path. The motion becomes a chain of
   rest-to-rest quintic segments: the Cartesian stretches between the cuts (each a
   sub-path timed by its own quintic, of duration ``duration * sqrt(span)`` so neither
   peak speed nor peak acceleration exceed the straight plan's), and across every cut a
   **joint-space quintic** (eqs. 7-9 per joint, zero velocity and acceleration at both
   ends) from the configuration before the cut to the one after it, both on the start's
   IK branch (the one the continuation follows). Position, velocity and acceleration are
   continuous everywhere; the robot stops (v = a = 0) at each cut point.

   The joint quintic moves every joint monotonically between its end values. For the
   PUMA wrist both ends have theta5 of one sign and well off zero, so theta5 stays there
   while theta4 and theta6 turn: the paper's arc "about Z with joint 5 held" (sec. 4).
   Its duration ``T = 15/8 max_i |dq_i| / (speed_fraction v_max,i)`` keeps every joint below
   ``speed_fraction`` of its velocity limit. Along it m is checked again; if m reaches the
   threshold the margin is doubled (wider cuts) and the plan rebuilt.

Limits: across a cut the tool leaves the Cartesian path (for the PUMA its orientation
wanders by about twice the ``|theta5|`` at the cut points). The detour stays on the IK branch
of the start: when the continuation itself crosses the singular set (an exact crossing,
reported as an IK jump), or the joint-space segment between the cut points meets the
region whatever the margin, PlanningError says so. Joint-space segments need nq == nv.
"""

from __future__ import annotations

import bisect
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ..analysis.singularity import singularity_measure
from ..core.errors import InvalidInputError, PlanningError
from ..core.validation import as_positive
from ..model.robot import Robot
from .flips import WristFlip, branch_switches, wrist_flips
from .paths import Path, SubPath, TimedPath
from .quintic import REST_TO_REST_PEAK_SPEED, Quintic
from .sampling import MAX_JOINT_STEP, SAMPLES, JointTrajectory, follow

MARGIN = 2.0  #: runs are cut where m < MARGIN * threshold
SPEED_FRACTION = 0.8  #: detours keep every joint below this fraction of its velocity limit
DETOUR_SAMPLES = 400  #: samples of a joint-space detour (checks and diagnostics)
MAX_WIDENINGS = 8  #: margin doublings tried before giving up


class JointSegment:
    """Rest-to-rest joint quintic as a frame reference: ``(FK(q(t)), J(q(t)) qdot(t))``."""

    def __init__(self, robot: Robot, frame: str, start: ArrayLike, end: ArrayLike, duration: float) -> None:
        self.robot, self.frame, self.duration = robot, frame, duration
        self.quintic = Quintic.rest_to_rest(start, end, duration)

    def __call__(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        q, qdot, _ = self.quintic(t)
        return self.robot.frame_pose(q, self.frame).copy(), self.robot.frame_jacobian(q, self.frame) @ qdot


class PlannedReference:
    """``reference(t) -> (pose 4x4, twist 6)``: segments played one after the other,
    the last pose held (zero twist) after ``duration``."""

    def __init__(self, segments: Sequence[TimedPath | JointSegment]) -> None:
        self.segments = segments
        self.starts = list(np.cumsum([0.0] + [s.duration for s in segments[:-1]]))
        self.duration = float(self.starts[-1] + segments[-1].duration)

    def __call__(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        index = max(bisect.bisect_right(self.starts, t) - 1, 0)
        return self.segments[index](t - self.starts[index])


@dataclass(frozen=True)
class Detour:
    """A stretch [path_start, path_end] of the path parameter s crossed in joint space."""

    path_start: float
    path_end: float
    start: float  #: [s] on the planned clock
    duration: float  #: [s]


@dataclass
class Plan:
    """Result of :func:`plan`: the reference, its joint trajectory and diagnostics."""

    reference: PlannedReference
    joints: JointTrajectory  #: planned joint trajectory
    straight: JointTrajectory  #: IK continuation of the un-rerouted path
    threshold: float
    detours: list[Detour]
    flips: list[WristFlip]  #: of ``joints`` (empty when no wrist was given)
    straight_flips: list[WristFlip]  #: of ``straight``
    switches: np.ndarray  #: wrist branch switches of ``joints`` [s] (empty when no wrist was given)
    straight_switches: np.ndarray  #: of ``straight``

    @property
    def rerouted(self) -> bool:
        return bool(self.detours)

    @property
    def duration(self) -> float:
        return self.reference.duration

    @property
    def min_measure(self) -> float:
        return self.joints.min_measure


def plan(robot: Robot, path: Path, q0: ArrayLike, duration: float, threshold: float, frame: str | None = None,
         reroute: bool = True, wrist: tuple[str, str, str] | None = None, margin: float = MARGIN,
         speed_fraction: float = SPEED_FRACTION, samples: int = SAMPLES, max_joint_step: float = MAX_JOINT_STEP,
         length_scale: float | None = None) -> Plan:
    """Plan ``path`` (timed by the rest-to-rest quintic over ``duration`` [s]) from ``q0``.

    ``threshold`` bounds the singular region m <= threshold of the robot's registered
    singularity measure (of ``robot.end_effector`` with ``length_scale`` for an
    unregistered robot). With ``reroute=False`` the path is only sampled and checked
    (the naive plan). ``wrist`` names three wrist joints, e.g. ``("joint_4", "joint_5",
    "joint_6")`` for the PUMA: the first and last are watched for flips
    (:func:`.flips.wrist_flips`), the middle one for branch switches.
    """
    frame = robot.end_effector if frame is None else frame
    if frame is None:
        raise InvalidInputError(f"robot {robot.name!r} declares no end effector: pass frame=")
    threshold, margin = as_positive(threshold, "threshold"), as_positive(margin, "margin")
    speed_fraction = as_positive(speed_fraction, "speed_fraction")
    if margin < 1.0:
        raise InvalidInputError(f"margin must be >= 1, got {margin}")
    if wrist is not None and (isinstance(wrist, str) or len(wrist) != 3):
        raise InvalidInputError(f"wrist names three joints, e.g. ('joint_4', 'joint_5', 'joint_6'), got {wrist!r}")
    timed = TimedPath(path, duration)

    def sample(trajectory: TimedPath, q_start: ArrayLike) -> JointTrajectory:
        return follow(robot, frame, trajectory, q_start, samples, max_joint_step, length_scale)

    straight = sample(timed, q0)
    segments: list[TimedPath | JointSegment] = [timed]
    detours: list[Detour]
    joints, detours = straight, []
    if reroute and straight.min_measure <= threshold:
        for _ in range(MAX_WIDENINGS):
            rerouted = _reroute(robot, frame, timed, straight, threshold, margin, speed_fraction, length_scale, sample)
            if rerouted is not None:
                segments, joints, detours = rerouted
                break
            margin *= 2.0
        else:
            raise PlanningError(f"no joint-space detour clears the singular region (margin up to {margin:g})")

    def flips(trajectory: JointTrajectory) -> list[WristFlip]:
        return [] if wrist is None else wrist_flips(robot, trajectory, (wrist[0], wrist[2]))

    def switches(trajectory: JointTrajectory) -> np.ndarray:
        return np.zeros(0) if wrist is None else branch_switches(robot, trajectory, wrist[1])

    return Plan(PlannedReference(segments), joints, straight, threshold, detours, flips(joints), flips(straight),
                switches(joints), switches(straight))


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """(first, last) index of every maximal run of True."""
    edges = np.flatnonzero(np.diff(np.r_[0, mask.astype(int), 0]))
    return [(int(a), int(b) - 1) for a, b in zip(edges[::2], edges[1::2], strict=True)]


def _reroute(robot: Robot, frame: str, timed: TimedPath, straight: JointTrajectory, threshold: float, margin: float,
             speed_fraction: float, length_scale: float | None,
             sample: Callable[[TimedPath, ArrayLike], JointTrajectory],
             ) -> tuple[list[TimedPath | JointSegment], JointTrajectory, list[Detour]] | None:
    """Segments, joint trajectory and detours with cuts at ``margin``; None if a detour meets the region."""
    if robot.nq != robot.nv:
        raise PlanningError(f"robot {robot.name!r}: joint-space detours need nq == nv")
    if straight.jumps.size:
        raise PlanningError(f"the IK continuation changes branch at t = {straight.jumps.round(4).tolist()} s "
                            "(the path crosses a singular set): no detour on one branch")
    runs = [(a, b) for a, b in _runs(straight.measure < margin * threshold)
            if straight.measure[a:b + 1].min() <= threshold]
    if any(a == 0 or b == straight.time.size - 1 for a, b in runs):
        raise PlanningError("the start or goal pose lies within the re-routing margin of the singular "
                            f"region (m < {margin:g} * threshold): no room for a detour")
    progress = [float(timed.timing(t)[0]) for t in straight.time]  # path parameter s of every sample
    limit = speed_fraction * robot.velocity_limit
    segments: list[TimedPath | JointSegment] = []
    pieces: list[JointTrajectory] = []
    detours: list[Detour] = []
    clock, s_start, q_start = 0.0, 0.0, straight.q[0]
    for run in [*runs, None]:  # None: the part after the last run
        s_end = 1.0 if run is None else progress[run[0] - 1]
        part = TimedPath(SubPath(timed.path, s_start, s_end), timed.duration * np.sqrt(s_end - s_start))
        followed = sample(part, q_start)
        segments.append(part)
        pieces.append(_shifted(followed, clock))
        clock += part.duration
        if run is None:
            break
        last = run[1]
        q_cut, q_after = followed.q[-1], straight.q[last + 1]
        span = REST_TO_REST_PEAK_SPEED * np.max(np.abs(q_after - q_cut) / limit)
        segment = JointSegment(robot, frame, q_cut, q_after, span)
        crossing = _sample_segment(robot, segment, clock, length_scale)
        if crossing.min_measure <= threshold:
            return None
        segments.append(segment)
        pieces.append(crossing)
        detours.append(Detour(float(s_end), float(progress[last + 1]), float(clock), float(span)))
        clock += span
        s_start, q_start = progress[last + 1], q_after
    return segments, _concatenate(pieces, straight.jumps), detours


def _shifted(trajectory: JointTrajectory, offset: float) -> JointTrajectory:
    return JointTrajectory(trajectory.time + offset, trajectory.q, trajectory.qdot, trajectory.measure,
                           trajectory.jumps + offset)


def _sample_segment(robot: Robot, segment: JointSegment, offset: float, length_scale: float | None) -> JointTrajectory:
    local = np.linspace(0.0, segment.duration, DETOUR_SAMPLES)
    states = [segment.quintic(t) for t in local]
    q = np.array([s[0] for s in states])
    measure = np.array([singularity_measure(robot, qi, length_scale=length_scale) for qi in q])
    return JointTrajectory(local + offset, q, np.array([s[1] for s in states]), measure, np.zeros(0))


def _concatenate(pieces: list[JointTrajectory], jumps: np.ndarray) -> JointTrajectory:
    """Pieces one after the other; the first sample of each later piece (its predecessor's last) is dropped."""
    keep = [pieces[0]] + [JointTrajectory(p.time[1:], p.q[1:], p.qdot[1:], p.measure[1:], p.jumps)
                          for p in pieces[1:]]
    return JointTrajectory(np.concatenate([p.time for p in keep]), np.vstack([p.q for p in keep]),
                           np.vstack([p.qdot for p in keep]), np.concatenate([p.measure for p in keep]), jumps)
