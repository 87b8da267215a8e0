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
from abc import ABC, abstractmethod

import numpy as np

from ..item import Item
from ..kinematics import Kinematics
from ..program import TickProgram
from ..robot import Robot


class Task(Item, ABC):
    """Base class of all tasks (bound and shared as described in :class:`~wbc.item.Item`)."""

    #: number of task rows
    dim: int
    #: True for tasks that need the holonomic preview (see SteeringTask); they are
    #: computed after all others through ``compute_preview``
    uses_preview: bool = False

    def __init__(self, name: str | None = None) -> None:
        self.name = name or self.default_name()

    def default_name(self) -> str:
        return type(self).__name__

    def write_static(self, jacobian: np.ndarray) -> None:
        """Write rows that never change, once after allocation (e.g. a constant ``W J``)."""

    @abstractmethod
    def compute(self, kin: Kinematics, dt: float, jacobian: np.ndarray, target: np.ndarray) -> None:
        """Write ``W J`` into ``jacobian`` (dim x nv) and ``W r`` into ``target`` (dim)."""

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

    @abstractmethod
    def report(self, v: np.ndarray, errors: dict[str, float]) -> None:
        """Add this tick's error measures (unweighted, SI units) to ``errors``."""


def _norm(vector: np.ndarray) -> float:
    """Euclidean norm of a small vector (cheaper than np.linalg.norm on the hot path)."""
    return math.sqrt(float(vector @ vector))
