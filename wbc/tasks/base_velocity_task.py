"""Track a commanded planar base twist."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.errors import InvalidInputError
from ..core.settings import Cost
from ..core.validation import as_vector
from ..model.kinematics import Kinematics
from ..model.robot import Robot
from .task import Task, TaskData


class BaseVelocityTask(Task):
    """Make the mobile base follow a twist ``(v_x, v_y, omega)`` given in the **base frame**.

    With base yaw ``theta`` and world rates ``(xdot, ydot, thetadot)``, the base-frame
    twist is ``S(theta) v`` with ``S = [[c, s, 0], [-s, c, 0], [0, 0, 1]]`` on the base
    coordinates. Rows: ``W (S v - twist*)``.

    Args:
        cost: [cost] / [m/s]^2 (and [rad/s]^2 for the yaw row), scalar or one per row.
    """

    cost = Cost("_weights", slice(0, 3))  #: may be changed between ticks

    def __init__(self, cost: ArrayLike, name: str | None = None) -> None:
        super().__init__(name)
        self._weights = np.zeros(3)
        self.cost = cost
        self._twist = np.zeros(3)

    @property
    def twist(self) -> NDArray[np.float64]:
        """Commanded (v_x [m/s], v_y [m/s], omega [rad/s]), base frame."""
        return self._twist.copy()

    def set_target(self, twist: ArrayLike) -> None:
        """Command a base-frame twist ``(v_x, v_y, omega)`` [m/s, m/s, rad/s].

        Raises:
            InvalidInputError: ``twist`` is not 3 finite numbers.
        """
        self._twist[...] = as_vector(twist, 3, "base twist")

    def bind(self, robot: Robot) -> BaseVelocityTaskData:
        if not robot.base.is_mobile:
            raise InvalidInputError(f"{self.name}: robot '{robot.name}' has a {robot.base.name} base; a base "
                                    "velocity task drives a ground base on (x, y, heading)")
        return BaseVelocityTaskData(self, robot)

    def __repr__(self) -> str:
        return f"BaseVelocityTask(cost={self.cost.tolist()})"


class BaseVelocityTaskData(TaskData):
    """A :class:`BaseVelocityTask` in one controller: the base coordinates of the robot."""

    dim = 3
    task: BaseVelocityTask
    lm_damped = False  # a velocity reference, no error to overshoot

    def __init__(self, task: BaseVelocityTask, robot: Robot) -> None:
        super().__init__(task)
        self._x, self._y, self._yaw = robot.base.indices
        self._cos_sin = (1.0, 0.0)

    def compute(self, kin: Kinematics, dt: float, jacobian: np.ndarray, target: np.ndarray) -> None:
        # in Python floats: an overflow (a twist of 1e300 weighted 1e6) is inf, not a numpy warning
        yaw = float(kin.q[self._yaw])
        cos, sin = math.cos(yaw), math.sin(yaw)
        (w_x, w_y, w_yaw), (t_x, t_y, t_yaw) = self.task._weights.tolist(), self.task._twist.tolist()
        jacobian.fill(0.0)
        jacobian[0, self._x], jacobian[0, self._y] = w_x * cos, w_x * sin
        jacobian[1, self._x], jacobian[1, self._y] = -w_y * sin, w_y * cos
        jacobian[2, self._yaw] = w_yaw
        target[0], target[1], target[2] = w_x * t_x, w_y * t_y, w_yaw * t_yaw
        self._cos_sin = (cos, sin)

    def report(self, v: np.ndarray, errors: dict[str, float]) -> None:
        cos, sin = self._cos_sin
        xdot, ydot, yawdot = float(v[self._x]), float(v[self._y]), float(v[self._yaw])
        t_x, t_y, t_yaw = self.task._twist.tolist()
        errors[self.name] = math.hypot(cos * xdot + sin * ydot - t_x, -sin * xdot + cos * ydot - t_y, yawdot - t_yaw)
