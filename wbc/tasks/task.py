"""Task base class: one weighted least-squares term of the control QP.

A task contributes ``|| W (J v - r) ||^2`` to the cost, where ``v`` is the joint
velocity [SI units of each coordinate per second], ``J`` (dim x nv) the task
Jacobian, ``r`` (dim) the desired task velocity and ``W = diag(sqrt(cost))``.
Tasks write ``W J`` and ``W r`` straight into rows of the controller's stacked
buffers, so the whole stack costs a single ``H = Js^T Js`` product per tick.

Gains follow the per-tick convention of Pink and mink: ``gain`` in (0, 1] is the
fraction of the current error ``e`` the task asks to remove in one tick of length
``dt``, i.e. ``r = gain * e / dt`` (+ feed-forward), a continuous-time gain of
``gain / dt`` [1/s].
"""

from __future__ import annotations

import math

import numpy as np

from ..item import Item
from ..model.kinematics import Kinematics
from ..model.robot import Robot
from ..runtime.program import TickProgram


class TaskData:
    """A task's data in one controller (:meth:`Task.bind`): what the controller calls each tick.

    Built-in tasks return a data object of their own (robot-resolved indices, per-controller
    buffers and the task's error at the last tick); it reads the task's settings from
    ``self.task``. The methods below are the contract; their defaults do nothing.
    """

    #: number of task rows
    dim: int = 0
    #: True for tasks that need the holonomic preview (see SteeringTask); they are
    #: computed after all others through ``compute_preview``
    uses_preview: bool = False
    #: True when each row of ``W J`` has at most one non-zero entry, in a fixed column (e.g.
    #: PostureTask): the row then adds to the diagonal of H only, which the lifted form of
    #: high-DOF QPs (:mod:`wbc.qp.lifting`) keeps out of its auxiliary variables
    diagonal_rows: bool = False
    #: True for a linear cost term ``c^T v`` (:class:`~wbc.tasks.linear_cost.LinearCost`): the task
    #: has one row, :meth:`compute` writes ``c`` into its ``W J`` part (the target is unused) and the
    #: controller adds that row to the QP's ``c`` only -- never to ``H`` (no least-squares square)
    linear: bool = False
    #: True when the controller's error-scaled damping (``Controller.lm_damping``) applies to
    #: this task: its target feeds back an error through a nonlinear map (a frame's pose, a
    #: measure), whose linear model overshoots at the edge of the workspace. False when the
    #: rows are exact (PostureTask: joint coordinates) or the target is a velocity reference,
    #: not an error (BaseVelocityTask). Tasks with ``uses_preview`` are never damped
    lm_damped: bool = True
    #: the feed-forward part of the target rows, weighted as they are (``W xi``, dim), a view kept
    #: current by the task; the error-scaled damping sees only the rest of ``W r``, the feedback
    #: of the error. None: the whole target is feedback
    feedforward: np.ndarray | None = None
    #: the compiled functions (names in :mod:`wbc.runtime.kernels`) its Python :meth:`compute`
    #: may call: a controller computing it in Python compiles them when it is built, not in a tick
    python_kernels: tuple[str, ...] = ()

    def __init__(self, task: Task) -> None:
        self.task, self.name = task, task.name

    def write_static(self, jacobian: np.ndarray) -> None:
        """Write rows that never change, once after allocation (e.g. a constant ``W J``)."""

    def compute(self, kin: Kinematics, dt: float, jacobian: np.ndarray, target: np.ndarray) -> None:
        """Write ``W J`` into ``jacobian`` (dim x nv) and ``W r`` into ``target`` (dim)."""
        raise NotImplementedError(f"{type(self).__name__} computes no rows")

    def compute_preview(self, kin: Kinematics, dt: float, jacobian: np.ndarray, target: np.ndarray,
                        preview: np.ndarray) -> None:
        """As :meth:`compute` for a task with ``uses_preview``, given the holonomic
        relaxation's velocity ``preview`` (nv)."""
        raise NotImplementedError(f"{type(self).__name__} uses no preview")

    def add_ops(self, program: TickProgram, kin: Kinematics, stack_t: np.ndarray, start: int) -> bool:
        """Register this task's rows as compiled ops and return True, or return False to be
        computed by :meth:`compute` every tick (the default).

        The rows are ``start:start + dim`` of the controller's stack ``A = stack_t^T``
        (``stack_t``: (nv + 1) x rows, C-contiguous; column nv of A holds ``W r``). The ops
        must compute exactly what :meth:`compute` would; a subclass that overrides
        ``compute`` but not ``add_ops`` is computed in Python (``program.ops_follow_compute``).
        """
        return False

    def add_preview_ops(self, program: TickProgram, kin: Kinematics, stack_t: np.ndarray, start: int,
                        preview: np.ndarray) -> bool:
        """As :meth:`add_ops` for a task with ``uses_preview``: ``preview`` (nv) holds the
        holonomic relaxation's velocity when the ops run."""
        return False

    def check_ready(self) -> None:
        """Raise InvalidInputError if the task cannot be evaluated yet (e.g. no target)."""
        self.task.check_ready()

    def report(self, v: np.ndarray, errors: dict[str, float]) -> None:
        """Add this tick's error measures (unweighted, SI units) to ``errors``."""


class Task(Item):
    """Base class of all tasks: a specification (settings) that :meth:`Task.bind` turns into
    per-controller :class:`TaskData` (see :class:`~wbc.item.Item`).

    A task computes nothing itself: its rows are computed by the data ``bind`` returns. A new
    task that drives an error to zero subclasses :class:`~wbc.tasks.error_task.ErrorTask` (it
    says its error and Jacobian, the rest is generic); any other returns a :class:`TaskData`
    subclass of its own from :meth:`bind`. A class that subclasses both ``Task`` and
    ``TaskData`` is its own data (it then serves the controllers of one robot object).
    """

    def __init__(self, name: str | None = None) -> None:
        self.name = name or self.default_name()

    def default_name(self) -> str:
        return type(self).__name__

    def bind(self, robot: Robot) -> TaskData:
        """This task's data for a controller of ``robot``.

        Raises:
            InvalidInputError: the task says nothing about its rows (no data class of its own,
                and it is not a :class:`TaskData` itself).
        """
        data: TaskData = self.bind_as_own_data(robot, TaskData, "Task", "return a TaskData subclass from its "
                                               "bind(), or subclass wbc.tasks.error_task.ErrorTask and say its error "
                                               "and Jacobian")
        return data

    def check_ready(self) -> None:
        """Raise InvalidInputError if the task cannot be evaluated yet (e.g. no target)."""


def _norm(vector: np.ndarray) -> float:
    """Euclidean norm of a small vector: never overflows, hence never warns (``v @ v`` does past
    1e154), and ~25x cheaper than ``sqrt(v @ v)`` for 3 entries (numpy 2.4)."""
    return math.hypot(*vector.tolist())
