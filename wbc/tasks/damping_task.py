"""Joint-velocity damping with per-coordinate costs (base motion costlier than arm motion)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.errors import InvalidInputError
from ..core.validation import as_weights
from ..model.declared_base import joint_columns
from ..model.kinematics import Kinematics
from ..model.robot import Robot
from .error_task import ErrorTask, ErrorTaskData


class DampingTask(ErrorTask):
    """Penalise the velocity of the selected coordinates: rows ``W v_S`` with target 0, i.e.
    the cost ``sum_i cost_i v_i^2`` added to the QP (H gets ``diag(cost)`` on them).

    There is no error (``e = 0``, the rows are exact: no gain, no LM damping); ``J`` is the
    selection of the coordinates. ``cost`` may be reassigned every tick, per coordinate (e.g.
    ``task.cost = [10, 10, 10, 1, 1, 1, 1, 1]`` on the youBot makes platform motion ten times
    costlier than arm motion); unlike ``Controller(damping=...)``, one value for every
    coordinate, it prices each coordinate on its own, on the tasks' cost scale.

    Rows: one per velocity coordinate of the selected joints, in the order of ``joints`` (of
    ``v`` for every coordinate). Their number is fixed when the first controller binds the task
    (from a vector ``cost`` given before, or the robot's selection); a controller of a robot
    with another number of selected coordinates is refused (create another DampingTask for it).

    Args:
        cost: [cost] / ([rad/s]^2 or [m/s]^2): a scalar (every selected coordinate) or one per
            selected coordinate.
        joints: joint names whose velocity coordinates are damped; ``None`` = every coordinate,
            **the mobile base's included** (its motion is what one most often wants to price).
    """

    #: no error to feed back (e = 0): not a setting, the rows are the same for any gain
    gain = 1.0

    def __init__(self, cost: ArrayLike, joints: Sequence[str] | None = None, name: str | None = None) -> None:
        if joints is not None and (isinstance(joints, str) or not all(isinstance(j, str) for j in joints)):
            raise InvalidInputError(f"joints must be a list of joint names, got {joints!r}"
                                    + (f"; write joints=[{joints!r}]" if isinstance(joints, str) else ""))
        if joints is not None and len(joints) == 0:
            raise InvalidInputError("joints is empty; name the joints to damp, or give joints=None for every one")
        self.joints = None if joints is None else tuple(joints)
        super().__init__(1, 1.0, name)
        self._sized = False  # whether the number of rows is fixed (a vector cost, or a controller bound it)
        self.cost = cost

    @property
    def cost(self) -> NDArray[np.float64]:
        """Per-coordinate costs (a copy; a 0-d array for a scalar given before the rows are sized)."""
        return self._cost.copy()

    @cost.setter
    def cost(self, value: ArrayLike) -> None:
        if np.ndim(value) == 0:
            scalar = as_weights(value, 1, "cost")[0]
            cost = np.full(self._weights.size, scalar) if self._sized else np.array(scalar)
        elif self._sized:
            cost = as_weights(value, self._weights.size, "cost")
        else:  # no controller uses the task yet: the vector sizes the rows
            cost = as_weights(value, np.size(value), "cost")
            if cost.size == 0:
                raise InvalidInputError("cost is empty; give a scalar or one cost per selected coordinate")
            self._weights, self._feedforward = np.zeros(cost.size), np.zeros(cost.size)
            self._sized = True
        self._weights[:] = np.sqrt(cost)
        self._cost = cost

    def size_rows(self, rows: int, robot: Robot) -> None:
        """Fix the number of rows at ``rows`` (a controller of ``robot`` binds the task), broadcasting
        a scalar cost; refuse another number once fixed."""
        if self._sized:
            if rows != self._weights.size:
                raise InvalidInputError(
                    f"{self.name}: {self._weights.size} costs, but robot {robot.name!r} has {rows} velocity "
                    f"coordinates in {'the joints ' + str(list(self.joints)) if self.joints else 'v'}; give one "
                    "cost per coordinate (or a scalar), or create another DampingTask for this robot")
            return
        cost = float(self._cost)
        self._weights, self._feedforward = np.full(rows, np.sqrt(cost)), np.zeros(rows)
        self._sized, self._cost = True, np.full(rows, cost)

    def bind(self, robot: Robot) -> DampingTaskData:
        return DampingTaskData(self, robot)

    def __repr__(self) -> str:
        return f"DampingTask(cost={self._cost.tolist()}, joints={None if self.joints is None else list(self.joints)})"


class DampingTaskData(ErrorTaskData):
    """A :class:`DampingTask` in one controller: the selected coordinates of the robot."""

    task: DampingTask
    diagonal_rows = True  # row i selects coordinate indices[i]
    lm_damped = False  # no error: nothing to overshoot

    def __init__(self, task: DampingTask, robot: Robot) -> None:
        self.indices = _velocity_indices(robot, task.joints, task.name)
        task.size_rows(self.indices.size, robot)
        super().__init__(task, robot)
        self.jacobian[np.arange(self.indices.size), self.indices] = 1.0  # constant: J = selection

    def compute_error_and_jacobian(self, kin: Kinematics, error: np.ndarray, jacobian: np.ndarray) -> None:
        """Nothing changes: ``e = 0`` and the selection ``J`` were written once."""


def _velocity_indices(robot: Robot, joints: tuple[str, ...] | None, where: str) -> NDArray[np.intp]:
    """The velocity coordinates of ``joints``, in their order (every coordinate of v for None)."""
    return np.arange(robot.nv) if joints is None else joint_columns(robot.model, joints, where)
