"""Joint trajectories of Cartesian references: IK continuation along a timed path.

The path is sampled at ``samples`` equal time steps; each sample is solved by damped
least squares (:mod:`.ik`) seeded with the previous solution. Where one step moves a
joint by more than ``max_joint_step`` the step is halved (down to ``min_time_step``), so
the samples follow the IK branch continuously through fast wrist swings. A step that is
still larger at the finest resolution is recorded as a *jump*: the seeded IK changed
branch there (at an exact crossing of a singular set, for instance).

At every sample the joint rates follow from the twist xi of the reference:
qdot = J^+ xi (least squares where J is not square).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ..analysis.singularity import singularity_measure
from ..core.errors import PlanningError
from ..model.robot import Robot
from .ik import solve_ik
from .paths import TimedPath

SAMPLES = 400  #: equal time steps over a path before refinement
MAX_JOINT_STEP = 0.02  #: [rad or m] largest joint change between accepted samples
MIN_TIME_STEP_FRACTION = 1e-6  #: finest refinement, as a fraction of the path duration


@dataclass
class JointTrajectory:
    """A sampled joint trajectory (rows are samples, in time order)."""

    time: np.ndarray  #: (K,) [s]
    q: np.ndarray  #: (K, nq)
    qdot: np.ndarray  #: (K, nv) [rad/s or m/s]
    measure: np.ndarray  #: (K,) singularity_measure at each sample (dimensionless)
    jumps: np.ndarray  #: times [s] where the seeded IK changed branch (see the module docstring)

    @property
    def min_measure(self) -> float:
        return float(self.measure.min())

    def speed_ratio(self, robot: Robot) -> np.ndarray:
        """``(K, nv)`` array of ``|qdot_i| / velocity_limit_i``."""
        return np.abs(self.qdot) / robot.velocity_limit

    def max_speed_ratio(self, robot: Robot) -> float:
        """Largest ``|qdot_i| / velocity_limit_i`` over the whole trajectory."""
        return float(self.speed_ratio(robot).max())


def joint_rates(robot: Robot, frame: str, q: np.ndarray, twist: np.ndarray) -> np.ndarray:
    """qdot = J^+ twist (least squares where J is not square)."""
    return np.linalg.lstsq(robot.frame_jacobian(q, frame), twist, rcond=None)[0]


def follow(robot: Robot, frame: str, trajectory: TimedPath, q0: ArrayLike, samples: int = SAMPLES,
           max_joint_step: float = MAX_JOINT_STEP, length_scale: float | None = None) -> JointTrajectory:
    """IK continuation of ``trajectory`` from ``q0`` (solved onto the start pose first).

    Raises PlanningError where a sample cannot be reached.
    """
    start = solve_ik(robot, frame, trajectory(0.0)[0], q0)
    if not start.converged:
        raise PlanningError(f"IK from q0 does not reach the start pose (error {start.position_error:.2e} m, "
                            f"{start.orientation_error:.2e} rad)")
    duration = trajectory.duration
    min_step = MIN_TIME_STEP_FRACTION * duration
    times, qs, jumps = [0.0], [start.q], []
    pending = list(np.linspace(duration, 0.0, samples + 1)[:-1])  # popped from the end: increasing times
    while pending:
        t = pending[-1]
        result = solve_ik(robot, frame, trajectory(t)[0], qs[-1])
        if not result.converged:
            raise PlanningError(f"IK fails at t = {t:.4f} s of the path (error {result.position_error:.2e} m, "
                                f"{result.orientation_error:.2e} rad): pose out of reach or at a joint limit")
        step = np.max(np.abs(result.q - qs[-1]))
        if step > max_joint_step and t - times[-1] > min_step:
            pending.append(0.5 * (times[-1] + t))
            continue
        if step > max_joint_step:
            jumps.append(t)
        pending.pop()
        times.append(t)
        qs.append(result.q)
    q = np.array(qs)
    qdot = np.array([joint_rates(robot, frame, qi, trajectory(t)[1]) for t, qi in zip(times, q, strict=True)])
    measure = np.array([singularity_measure(robot, qi, length_scale=length_scale) for qi in q])
    return JointTrajectory(np.array(times), q, qdot, measure, np.array(jumps))
