"""Soft manipulability objective: a least-squares row that raises m toward a target."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from ..core.errors import InvalidInputError
from ..core.settings import Setting
from ..core.validation import as_nonnegative, as_positive
from ..model.kinematics import Kinematics
from ..model.manipulability import Manipulability, Rows, check_joint_names, row_selection
from ..model.robot import Robot
from .error_task import ErrorTask, ErrorTaskData


class ManipulabilityTask(ErrorTask):
    """Pull the manipulability ``m`` of a frame (see :mod:`wbc.model.manipulability`) toward ``m*``.

    The task works on ``ln m``, so it is free of the units of ``m`` and pushes harder the
    closer the robot is to a singularity (``grad ln m = grad m / m`` grows as ``m -> 0``).
    One row::

        w ( (grad m / m) . v  -  gain / dt * ln(m* / m) ),    w = sqrt(cost)

    i.e. the :class:`~wbc.tasks.error_task.ErrorTask` rows of the error ``e = ln m* - ln m``
    with the Jacobian ``grad ln m = grad m / m``: each tick asks to remove the fraction ``gain`` of the
    log-ratio. Below ``m*`` the row rewards motion that raises ``m``; above it, motion
    that lowers it (the task regulates, it is not one-sided). To "maximize" ``m``, set
    ``m*`` at or above the largest value the robot can reach: near the maximum
    ``grad m -> 0``, the row fades out and the controller's damping keeps ``v`` finite.
    Being a cost, it competes with the other tasks: an ``m*`` out of reach keeps pulling
    and shifts their equilibria (a held gripper pose drifts, more so with a larger
    ``cost``). For a guarantee use :class:`~wbc.constraints.ManipulabilityBarrier`.
    Where ``m`` is exactly 0 (the gradient is then 0 or undefined) ``m`` is floored at
    ``1e-9 m*`` so the row stays finite.

    Args:
        frame: frame whose Jacobian defines ``m``.
        cost: weight [cost] / [1/s]^2 of the row (it is in relative units of m per second).
        gain: fraction of ``ln(m*/m)`` removed per tick, (0, 1].
        target: ``m*`` > 0 in the units of ``m`` for ``rows``.
        rows: ``"all"``, ``"position"`` or ``"orientation"`` rows of the Jacobian.
        joints: the measure of these joints' columns only (e.g. the arm of a mobile manipulator:
            its base keeps the whole-body measure large while the arm folds); None: every joint.
    """

    #: settings that may be changed between ticks (validated)
    target = Setting(as_positive)  # m* > 0

    def __init__(self, frame: str, cost: float, gain: float = 0.1, *, target: float, rows: Rows = "all",
                 joints: Sequence[str] | None = None, name: str | None = None) -> None:
        if not isinstance(frame, str):
            raise InvalidInputError(f"frame must be a frame name, got {frame!r}")
        self.frame = frame
        super().__init__(1, gain, name)
        self.cost, self.target = cost, target
        row_selection(rows)
        self.rows = rows
        self.joints = None if joints is None else tuple(check_joint_names(joints))

    @property
    def cost(self) -> float:
        """Weight [cost] / [1/s]^2 of the row (``w = sqrt(cost)``); may be changed between ticks."""
        return self._cost

    @cost.setter
    def cost(self, value: float) -> None:
        self._cost = as_nonnegative(value, "cost")
        self._weights[0] = math.sqrt(self._cost)

    def default_name(self) -> str:
        return f"ManipulabilityTask({self.frame})"

    def bind(self, robot: Robot) -> ManipulabilityTaskData:
        return ManipulabilityTaskData(self, robot)

    def __repr__(self) -> str:
        chain = "" if self.joints is None else f", joints={list(self.joints)!r}"
        return (f"ManipulabilityTask(frame={self.frame!r}, cost={self.cost}, gain={self.gain}, "
                f"target={self.target}, rows={self.rows!r}{chain})")


class ManipulabilityTaskData(ErrorTaskData):
    """A :class:`ManipulabilityTask` in one controller: ``m`` of the robot's frame, and its
    value and log-ratio error at the last tick."""

    python_kernels = ("frame_jacobian", "manipulability_gradient")  # Manipulability.compute's

    task: ManipulabilityTask

    def __init__(self, task: ManipulabilityTask, robot: Robot) -> None:
        super().__init__(task, robot)
        self._manipulability = Manipulability(robot, task.frame, task.rows, task.joints)
        self.value = float("nan")  #: m at the last tick
        self.error[0] = float("nan")  # ln(m* / m) at the last tick

    def compute_error_and_jacobian(self, kin: Kinematics, error: np.ndarray, jacobian: np.ndarray) -> None:
        """``e = ln(m* / m)`` and ``J = grad m / m`` (``m`` floored at ``1e-9 m*``)."""
        task, manipulability = self.task, self._manipulability
        self.value = manipulability.compute(kin)
        m = max(self.value, 1e-9 * task.target)
        error[0] = math.log(task.target / m)
        np.multiply(manipulability.gradient, 1.0 / m, out=jacobian[0])
