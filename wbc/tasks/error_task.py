"""The front door for a new task: say its error and Jacobian, the rest is generic.

A subclass of :class:`ErrorTask` (the specification: costs, gain, target) and of
:class:`ErrorTaskData` (one controller's data) writes, each tick, its error ``e`` (dim) and
Jacobian ``J`` (dim x nv, ``de/dt = -J v`` for a fixed target) into arrays it is handed
(:meth:`ErrorTaskData.compute_error_and_jacobian`). The generic :meth:`ErrorTaskData.compute`
then writes the rows of the objective once, the same way for every such task::

    W ( J v - sat(gain/dt * e) - xi ),   W = diag(sqrt(cost))

with ``sat`` the optional speed bounds of blocks of rows (``ErrorTask.speed_limits``: the
feedback velocity of a block scaled down in norm to its bound, direction kept), ``xi`` the task's
feed-forward velocity (set with its target, weighted with this tick's
``W``), and exposes ``W xi`` to the controller's error-scaled (LM) damping
(``TaskData.feedforward``), which then damps the feedback part only. Mink's and Pink's tasks
have the same contract (``compute_error``, ``compute_jacobian``); see docs/extending.md.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from ..core.errors import InvalidInputError
from ..core.settings import Setting
from ..core.validation import as_gain
from ..model.kinematics import Kinematics
from ..model.robot import Robot
from .task import Task, TaskData, _norm


class ErrorTask(Task):
    """A task given by its error and Jacobian (subclass it with an :class:`ErrorTaskData`).

    The subclass sizes the rows (``dim``), declares its costs as :class:`~wbc.core.settings.Cost`
    slices of ``_weights`` (``W = sqrt(cost)``, one per row, 1 until set), writes a moving
    target's feed-forward velocity into ``_feedforward`` (dim, unweighted; zero by default)
    and returns its data from :meth:`bind`. A subclass whose weights and feed-forward live in
    the settings vector of a compiled kernel (FrameTask, PositionTask) sets ``_weights`` and
    ``_feedforward`` as views into it before calling ``ErrorTask.__init__``.

    Args:
        dim: number of rows.
        gain: fraction of the error removed per tick, in (0, 1].
        name: the task's name (default: the class name, ``default_name()``).
    """

    gain = Setting(as_gain)
    #: blocks of rows whose feedback velocity ``gain/dt * e`` is bounded in norm (direction kept):
    #: (rows, name of the setting holding the bound [the error's units / s], inf for none)
    speed_limits: ClassVar[tuple[tuple[slice, str], ...]] = ()

    def __init__(self, dim: int, gain: float = 1.0, name: str | None = None) -> None:
        super().__init__(name)
        if getattr(self, "_weights", None) is None:  # (not already views into a kernel's settings)
            self._weights = np.ones(dim)  # W = sqrt(cost), per row
            self._feedforward = np.zeros(dim)  # xi, unweighted
        self.gain = gain

    #: the task needs a target before its first tick (``set_target`` sets ``_has_target``)
    needs_target: ClassVar[bool] = False
    _has_target = False

    def check_ready(self) -> None:
        """Raise InvalidInputError before the first target of a task that ``needs_target``."""
        if self.needs_target and not self._has_target:
            raise InvalidInputError(f"{self.name}: no target set; call set_target() before stepping")

    def bind(self, robot: Robot) -> ErrorTaskData:
        raise NotImplementedError(f"{type(self).__name__}.bind must return its ErrorTaskData")


class ErrorTaskData(TaskData):
    """An :class:`ErrorTask` in one controller: the error and Jacobian of the last tick, and the
    generic rows built from them (:meth:`compute`). A subclass resolves the task against the
    robot in ``__init__`` (frame indices, ...) and implements
    :meth:`compute_error_and_jacobian`."""

    task: ErrorTask

    def __init__(self, task: ErrorTask, robot: Robot) -> None:
        super().__init__(task)
        self.dim = task._weights.size
        self.error = np.zeros(self.dim)  #: last error e (the task's units)
        self.jacobian = np.zeros((self.dim, robot.nv))  #: last Jacobian J (unweighted)
        self.feedforward = np.zeros(self.dim)  #: W xi of the last tick (TaskData.feedforward)
        self._weight_column = task._weights[:, np.newaxis]  # W as a column: scales the rows of J

    def compute_error_and_jacobian(self, kin: Kinematics, error: np.ndarray, jacobian: np.ndarray) -> None:
        """Write this tick's error ``e`` into ``error`` (dim) and its Jacobian ``J`` into
        ``jacobian`` (dim x nv, C-contiguous): with the target fixed, ``de/dt = -J v``."""
        raise NotImplementedError(f"{type(self).__name__} must implement compute_error_and_jacobian")

    def compute(self, kin: Kinematics, dt: float, jacobian: np.ndarray, target: np.ndarray) -> None:
        """``jacobian = W J``, ``target = W (sat(gain/dt e) + xi)``, from :meth:`compute_error_and_jacobian`."""
        self.check_ready()
        task = self.task
        self.compute_error_and_jacobian(kin, self.error, self.jacobian)
        np.multiply(self._weight_column, self.jacobian, out=jacobian)
        np.multiply(task._weights, task._feedforward, out=self.feedforward)
        np.multiply(self.error, task.gain / dt, out=target)
        for rows, bound in task.speed_limits:
            _saturate(target[rows], getattr(task, bound))
        target *= task._weights
        target += self.feedforward

    def report(self, v: np.ndarray, errors: dict[str, float]) -> None:
        """The norm of the error (override for a breakdown)."""
        errors[self.name] = _norm(self.error)


def _saturate(velocity: np.ndarray, bound: float) -> None:
    """Scale ``velocity`` down in place to norm ``bound`` if it is longer (direction kept)."""
    norm = _norm(velocity)
    if norm > bound:
        velocity *= bound / norm
