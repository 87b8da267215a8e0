"""Mass-matrix weighted velocity regularisation: the robot's kinetic energy as a cost."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin

from ..core.errors import ModelError
from ..core.settings import UniformCost
from ..model.kinematics import Kinematics
from ..model.robot import Robot
from .error_task import ErrorTask, ErrorTaskData


class KineticEnergyRegularization(ErrorTask):
    """Penalise the kinetic energy of the motion: the QP's cost gets ``cost v^T M(q) v``
    (= ``2 cost T``, ``T = 1/2 v^T M v`` the kinetic energy [J] of the command), so H gets
    ``cost M(q)``: heavy links (the platform) are moved less than light ones (the wrist).

    ``M(q)`` is the joint-space mass matrix (Pinocchio's CRBA, [kg], [kg m], [kg m^2] blocks);
    the rows are its Cholesky factor ``U`` (upper triangular, ``M = U^T U``), weighted
    ``W = sqrt(cost)``, with target 0: ``|W U v|^2 = cost v^T M v``. No error, no gain, no LM
    damping. One row per velocity coordinate, fixed when the first controller binds the task
    (a controller of a robot with another nv is refused: create another regularization).

    Needs a model with inertias: a robot whose mass matrix is not positive definite (links
    without ``<inertial>``, massless joints) is refused with a :class:`~wbc.core.errors.ModelError`
    when bound, or at the tick where it stops being positive definite.

    Args:
        cost: [cost] / [J]: weight of ``v^T M v``, >= 0; may be changed every tick.
    """

    cost = UniformCost("_weights")

    #: no error to feed back (e = 0): not a setting, the rows are the same for any gain
    gain = 1.0

    def __init__(self, cost: float = 1.0, name: str | None = None) -> None:
        super().__init__(1, 1.0, name)
        self._sized = False  # whether a controller fixed the number of rows
        self.cost = cost

    def size_rows(self, rows: int, robot: Robot) -> None:
        """One row per velocity coordinate of ``robot``: fixed by the first controller binding the task."""
        if self._sized and rows != self._weights.size:
            raise ModelError(f"{self.name} has {self._weights.size} rows for another robot; robot {robot.name!r} "
                             f"has nv = {rows}: create another KineticEnergyRegularization for it")
        if not self._sized:
            self._weights, self._feedforward = np.full(rows, math.sqrt(self.cost)), np.zeros(rows)
            self._sized = True

    def bind(self, robot: Robot) -> KineticEnergyRegularizationData:
        return KineticEnergyRegularizationData(self, robot)

    def __repr__(self) -> str:
        return f"KineticEnergyRegularization(cost={self.cost})"


class KineticEnergyRegularizationData(ErrorTaskData):
    """A :class:`KineticEnergyRegularization` in one controller: its own Pinocchio data for the CRBA."""

    task: KineticEnergyRegularization
    lm_damped = False  # no error: nothing to overshoot

    def __init__(self, task: KineticEnergyRegularization, robot: Robot) -> None:
        pinocchio_data = robot.model.createData()
        # a model without inertias is refused now, not at the first tick
        cholesky_factor(robot, pinocchio_data, robot.neutral(), task.name)
        task.size_rows(robot.nv, robot)
        super().__init__(task, robot)
        self.robot, self._data = robot, pinocchio_data

    def compute_error_and_jacobian(self, kin: Kinematics, error: np.ndarray, jacobian: np.ndarray) -> None:
        jacobian[...] = cholesky_factor(self.robot, self._data, kin.q, self.name)  # e = 0 (never written)


def cholesky_factor(robot: Robot, data: pin.Data, q: np.ndarray, where: str) -> np.ndarray:
    """``U`` (nv x nv, upper triangular) with ``U^T U = M(q)``, the CRBA computed in ``data``.

    Raises:
        ModelError: ``M(q)`` is not positive definite (the model lacks inertias).
    """
    mass = pin.crba(robot.model, data, q)  # the upper triangle is always filled
    try:
        lower = np.linalg.cholesky(mass.T)  # reads the lower triangle of M^T: M's upper one
    except np.linalg.LinAlgError:
        lower = None
    if lower is None or not np.all(np.isfinite(lower)):
        raise ModelError(
            f"{where}: the mass matrix of robot {robot.name!r} is not positive definite at q = "
            f"{np.round(q, 4).tolist()} (largest diagonal entry {np.max(np.abs(np.diag(mass))):.3g}): its links "
            "lack inertias. Add <inertial> elements (mass, inertia) to every moving link of the URDF, or "
            "regularise with wbc.DampingTask, which needs none")
    return lower.T
