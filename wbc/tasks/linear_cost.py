"""A linear term ``c^T v`` in the QP's objective: the user's own, or one computed each tick."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.errors import InvalidInputError
from ..core.validation import as_vector
from ..model.kinematics import Kinematics
from ..model.robot import Robot
from .task import Task, TaskData


class LinearCost(Task):
    """Add ``c^T v`` to the objective of the control QP::

        minimise  1/2 sum_tasks |W (J v - r)|^2  +  c^T v     (+ damping)

    ``c`` [cost] / ([m/s] or [rad/s]), one entry per velocity coordinate, on the tasks' cost
    scale: a task row of weight ``w`` pulls ``v`` toward its target with the force ``w^2`` per
    unit of error, this term pushes ``v`` along ``-c`` with a constant force ``|c|``. Unlike a
    task it has no square: it never adds to ``H`` (so it cannot make the QP better conditioned;
    the controller's damping keeps the objective bounded below) and its pull does not fade near
    a goal -- the command settles where ``c`` is balanced by the tasks and the damping. Uses:
    a preferred direction of motion (NEO's base-heading term), the gradient of a measure to
    climb (:class:`~wbc.ManipulabilityGradient`).

    ``c`` may be reassigned every tick (``task.c = ...``); its length is fixed by the first
    value given, or by the robot of the first controller (then ``c = 0`` until assigned). In a
    hierarchy (``Controller(tasks=[[...], [...]])``) a linear cost belongs to the last level.

    Args:
        c: the vector (nv finite numbers), or None (zeros until assigned).
    """

    def __init__(self, c: ArrayLike | None = None, name: str | None = None) -> None:
        super().__init__(name)
        self._c: NDArray[np.float64] | None = None
        if c is not None:
            self.c = c

    @property
    def c(self) -> NDArray[np.float64]:
        """The vector (a copy); empty before it is sized."""
        return np.zeros(0) if self._c is None else self._c.copy()

    @c.setter
    def c(self, value: ArrayLike) -> None:
        if self._c is None:
            if np.ndim(value) != 1 or np.size(value) == 0:
                raise InvalidInputError(f"c must be a vector of one number per velocity coordinate, got shape "
                                        f"{np.shape(value)}")
            self._c = as_vector(value, np.size(value), "c").copy()
        else:
            self._c[:] = as_vector(value, self._c.size, "c")

    def size_for(self, robot: Robot) -> NDArray[np.float64]:
        """The vector, sized for ``robot`` (zeros if never assigned); refuses another length."""
        if self._c is None:
            self._c = np.zeros(robot.nv)
        elif self._c.size != robot.nv:
            raise InvalidInputError(f"{self.name}: c has {self._c.size} entries but robot {robot.name!r} has "
                                    f"nv = {robot.nv} velocity coordinates; give one entry per coordinate")
        return self._c

    def bind(self, robot: Robot) -> LinearCostData:
        self.size_for(robot)
        return LinearCostData(self)

    def __repr__(self) -> str:
        return f"LinearCost(c={self.c.tolist()})"


class LinearCostData(TaskData):
    """A linear cost in one controller: one row of the task stack holding ``c``, which the
    controller adds to the QP's ``c`` (``TaskData.linear``). Subclasses compute ``c`` each
    tick: override :meth:`compute_gradient`."""

    dim = 1
    linear = True
    lm_damped = False  # no error to overshoot

    def compute_gradient(self, kin: Kinematics, c: np.ndarray) -> None:
        """Write this tick's ``c`` (nv) into ``c``: the task's vector."""
        c[:] = self.task._c  # type: ignore[attr-defined]

    def compute(self, kin: Kinematics, dt: float, jacobian: np.ndarray, target: np.ndarray) -> None:
        self.compute_gradient(kin, jacobian[0])
