"""Centre-of-mass task."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike, NDArray

from ..core.errors import ModelError
from ..core.settings import Cost
from ..core.validation import as_vector
from ..model.kinematics import Kinematics
from ..model.robot import Robot
from .error_task import ErrorTask, ErrorTaskData


class CoMTask(ErrorTask):
    """Drive the robot's centre of mass ``c(q)`` (world, [m]) to a target point.

    Error ``e = c* - c`` [m]; Jacobian ``J_c = dc/dq`` (Pinocchio's ``jacobianCenterOfMass``: the
    mass-weighted mean of the links' centre-of-mass Jacobians), so ``de/dt = -J_c v`` for a fixed
    target. Rows ``W (J_c v - gain/dt e - cdot*)`` (:class:`~wbc.tasks.error_task.ErrorTask`),
    ``W = diag(sqrt(cost))``, ``cdot*`` an optional feed-forward velocity [m/s]. A cost of 0 on
    an axis frees it (``cost=[1, 1, 0]``: only the ground projection, the usual balance task).

    Args:
        cost: [cost] / [m]^2, scalar or per world axis (x, y, z).
        gain: fraction of the error removed per tick, in (0, 1].

    Raises (when a controller is built):
        ModelError: the robot has no mass (a model without inertias has no centre of mass).
    """

    needs_target = True

    cost = Cost("_weights", slice(0, 3))

    def __init__(self, cost: ArrayLike = 1.0, gain: float = 1.0, name: str | None = None) -> None:
        super().__init__(3, gain, name)
        self.cost = cost
        self._target = np.zeros(3)
        self._has_target = False

    def default_name(self) -> str:
        return "CoMTask"

    def set_target(self, position: ArrayLike, velocity: ArrayLike | None = None) -> None:
        """Set the target point [m] (world) and optionally its feed-forward velocity [m/s].

        Raises:
            InvalidInputError: ``position`` or ``velocity`` is not 3 finite numbers (the
                previous target is then kept).
        """
        target = as_vector(position, 3, "target position")
        feedforward = np.zeros(3) if velocity is None else as_vector(velocity, 3, "target velocity")
        self._target[...], self._feedforward[...] = target, feedforward
        if not self._has_target:
            self._has_target = True

    def set_target_from_configuration(self, robot: Robot, q: ArrayLike) -> None:
        """Hold the centre of mass where it is in configuration ``q``."""
        self.set_target(center_of_mass(robot, q))

    @property
    def target(self) -> NDArray[np.float64]:
        return self._target.copy()

    def bind(self, robot: Robot) -> CoMTaskData:
        return CoMTaskData(self, robot)

    def __repr__(self) -> str:
        return f"CoMTask(cost={self.cost.tolist()}, gain={self.gain})"


class CoMTaskData(ErrorTaskData):
    """A :class:`CoMTask` in one controller."""

    task: CoMTask

    def __init__(self, task: CoMTask, robot: Robot) -> None:
        super().__init__(task, robot)
        require_mass(robot, task.name)

    def compute_error_and_jacobian(self, kin: Kinematics, error: np.ndarray, jacobian: np.ndarray) -> None:
        jacobian[...] = pin.jacobianCenterOfMass(kin.model, kin.data, False)  # also sets data.com[0]
        np.subtract(self.task._target, kin.data.com[0], out=error)


def require_mass(robot: Robot, who: str) -> None:
    """Raise ModelError when ``robot`` has no mass (no inertias in its model)."""
    mass = sum(inertia.mass for inertia in robot.model.inertias)
    if not mass > 0.0:
        raise ModelError(f"{who}: robot '{robot.name}' has no mass (its model has no inertias), so no centre of "
                         "mass; give its links <inertial> elements in the URDF")


def center_of_mass(robot: Robot, q: ArrayLike) -> NDArray[np.float64]:
    """The robot's centre of mass [m], world, at configuration ``q``."""
    return np.array(pin.centerOfMass(robot.model, robot.model.createData(), robot.check_configuration(q)))
