"""Trajectories: quintic segments, Cartesian paths, IK sampling and singular-region-aware planning.

See docs/trajectories.md. The pieces:

* :class:`Quintic` -- position/velocity/acceleration boundary conditions (Lu et al., eqs. 7-9);
* :class:`LinePath`, :class:`ArcPath` -- pose paths over s in [0, 1] with geodesic orientation;
  :class:`TimedPath` runs one with the rest-to-rest quintic s(t): ``reference(t) -> (pose, twist)``;
* :func:`solve_ik` -- damped least squares; :func:`follow` -- IK continuation along a timed path;
* :func:`plan` -- sample, check against the singular region, re-route (:class:`Plan`);
* :func:`wrist_flips`, :func:`branch_switches` -- joint-4/joint-6 flips and wrist branch switches.
"""

from .flips import WristFlip, branch_switches, wrist_flips
from .ik import IKResult, pose_error, solve_ik
from .paths import ArcPath, LinePath, Path, SubPath, TimedPath
from .planner import Detour, JointSegment, Plan, PlannedReference, plan
from .quintic import Quintic, rest_to_rest_duration
from .sampling import JointTrajectory, follow

__all__ = [
    "Quintic", "rest_to_rest_duration", "Path", "LinePath", "ArcPath", "SubPath", "TimedPath",
    "IKResult", "pose_error", "solve_ik", "JointTrajectory", "follow",
    "Detour", "JointSegment", "Plan", "PlannedReference", "plan", "WristFlip", "wrist_flips", "branch_switches",
]
