"""Numerical inverse kinematics: damped least squares on the Robot API.

Each iteration takes the pose error in wbc's convention (world-aligned at the frame
origin, as in FrameTask), e = (p* - p ; log(R* R^T)), and the step

    dq = J^T (J J^T + lambda^2 I)^-1 e,

scaled down to at most ``max_step`` [rad or m] in any coordinate, then projected onto the
position limits. Seeded with the solution of a nearby pose (the previous path sample),
it converges in a few iterations to the solution on the seed's branch: DLS moves to the
nearest solution it can reach, it never jumps between IK branches by itself unless the
seed is far from its own branch (then it may land on any).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike

from ..core.validation import as_pose, as_positive
from ..model.robot import Robot

TOLERANCE = 1e-10  #: [m] and [rad]: converged when both error norms are below this
DAMPING = 1e-4  #: lambda [in J's units]: regularises near singular poses
MAX_STEP = 0.2  #: [rad or m] largest change of one coordinate per iteration
MAX_ITERATIONS = 200


@dataclass
class IKResult:
    """Outcome of :func:`solve_ik`."""

    q: np.ndarray  #: last iterate (within the position limits)
    converged: bool
    position_error: float  #: [m]
    orientation_error: float  #: [rad]
    iterations: int


def pose_error(current: np.ndarray, target: np.ndarray) -> np.ndarray:
    """(p* - p ; log3(R* R^T)): world-aligned error of ``current`` toward ``target``."""
    return np.r_[target[:3, 3] - current[:3, 3], pin.log3(target[:3, :3] @ current[:3, :3].T)]


def solve_ik(robot: Robot, frame: str, target: ArrayLike, seed: ArrayLike, tol: float = TOLERANCE,
             damping: float = DAMPING, max_step: float = MAX_STEP, max_iterations: int = MAX_ITERATIONS) -> IKResult:
    """Configuration that puts ``frame`` at the 4x4 world pose ``target``, starting from ``seed``."""
    target = as_pose(target, "IK target")
    q = np.clip(robot.check_configuration(seed), robot.lower, robot.upper)
    tol, max_step = as_positive(tol, "tol"), as_positive(max_step, "max_step")
    lam2 = as_positive(damping, "damping") ** 2
    for iteration in range(max_iterations + 1):
        error = pose_error(robot.frame_pose(q, frame), target)
        position, orientation = np.linalg.norm(error[:3]), np.linalg.norm(error[3:])
        if position < tol and orientation < tol:
            return IKResult(q, True, float(position), float(orientation), iteration)
        if iteration == max_iterations:
            break
        jacobian = robot.frame_jacobian(q, frame)
        step = jacobian.T @ np.linalg.solve(jacobian @ jacobian.T + lam2 * np.eye(6), error)
        largest = np.max(np.abs(step))
        if largest > max_step:
            step *= max_step / largest
        q = np.clip(robot.integrate(q, step, 1.0), robot.lower, robot.upper)
    return IKResult(q, False, float(position), float(orientation), max_iterations)
