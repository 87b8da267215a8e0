"""Climb the manipulability measure: its gradient as a linear cost (NEO's form)."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from ..core.errors import InvalidInputError
from ..core.settings import Setting
from ..core.validation import as_nonnegative
from ..model.kinematics import Kinematics
from ..model.manipulability import Manipulability, Rows, check_joint_names, row_selection
from ..model.robot import Robot
from .linear_cost import LinearCostData
from .task import Task

#: [units of m] the measure is floored here in ``grad m / m`` (a singular configuration gives a
#: zero or undefined gradient; the floor keeps c finite)
MEASURE_FLOOR = 1e-12


class ManipulabilityGradient(Task):
    """Raise the manipulability ``m`` of a frame (:mod:`wbc.model.manipulability`) for as long
    as it can rise: the linear cost (:class:`~wbc.LinearCost`) ::

        c = -cost * grad(ln m) = -cost * grad m / m        (c^T v = -cost * d(ln m)/dt)

    Each tick the command gains the velocity that raises ``ln m`` fastest, weighed against the
    other tasks and the damping; unlike :class:`~wbc.ManipulabilityTask` there is no target
    ``m*`` to pick (the row of that task fades at ``m*``; this term pushes until ``grad m = 0``,
    a local maximum, or until the tasks balance it). NEO (Haviland and Corke, 2021) maximises
    the arm's measure this way: give ``joints=[...]`` (the arm's joints) to climb the measure
    of that chain only, the base's columns left out. ``ln m`` makes the term free of the units
    of ``m`` and stronger near a singularity (``grad ln m`` grows as ``m -> 0``).

    Args:
        frame: frame whose Jacobian defines ``m``.
        cost: [cost] * [s] >= 0, the weight of ``-d(ln m)/dt`` in the objective; may be
            changed between ticks.
        rows: ``"all"``, ``"position"`` or ``"orientation"`` rows of the Jacobian.
        joints: the measure of these joints' columns only; None: every joint.
    """

    cost = Setting(as_nonnegative)

    def __init__(self, frame: str, cost: float = 1e-2, rows: Rows = "all", joints: Sequence[str] | None = None,
                 name: str | None = None) -> None:
        if not isinstance(frame, str):
            raise InvalidInputError(f"frame must be a frame name, got {frame!r}")
        self.frame = frame
        super().__init__(name)
        self.cost = cost
        row_selection(rows)
        self.rows = rows
        self.joints = None if joints is None else tuple(check_joint_names(joints))

    def default_name(self) -> str:
        return f"ManipulabilityGradient({self.frame})"

    def bind(self, robot: Robot) -> ManipulabilityGradientData:
        return ManipulabilityGradientData(self, robot)

    def __repr__(self) -> str:
        chain = "" if self.joints is None else f", joints={list(self.joints)!r}"
        return f"ManipulabilityGradient(frame={self.frame!r}, cost={self.cost}, rows={self.rows!r}{chain})"


class ManipulabilityGradientData(LinearCostData):
    """A :class:`ManipulabilityGradient` in one controller: ``m`` of the robot's frame and its
    value at the last tick."""

    python_kernels = ("frame_jacobian", "manipulability_gradient")  # Manipulability.compute's

    task: ManipulabilityGradient

    def __init__(self, task: ManipulabilityGradient, robot: Robot) -> None:
        super().__init__(task)
        self._manipulability = Manipulability(robot, task.frame, task.rows, task.joints)
        self.value = math.nan  #: m at the last tick

    def compute_gradient(self, kin: Kinematics, c: np.ndarray) -> None:
        """``c = -cost grad m / max(m, MEASURE_FLOOR)``."""
        manipulability = self._manipulability
        self.value = manipulability.compute(kin)
        np.multiply(manipulability.gradient, -self.task.cost / max(self.value, MEASURE_FLOOR), out=c)
