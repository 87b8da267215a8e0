"""A hard linear equation on the joint velocity, ``A v = b`` (the hard form of LinearTask)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..model.kinematics import Kinematics
from ..model.robot import Robot
from ..tasks.linear_task import LinearEquation, as_matrix
from .constraint import Constraint, ConstraintData, ConstraintRows


class LinearConstraint(LinearEquation, Constraint):
    """``A v = b`` exactly (m equality rows of the QP), with ``A`` (m x nv) and ``b`` (m) in the
    units of your choice: e.g. ``v_i - v_j = 0`` moves two joints together, a row of a Jacobian
    with ``b = 0`` forbids a motion. :class:`~wbc.LinearTask` asks the same softly.

    A hard constraint: with ``b = 0`` it holds together with every actuator limit (``v = 0``
    satisfies all of them); a ``b`` that the limits cannot meet makes the tick's QP infeasible --
    the controller's fallback then answers and ``controller.last.conflicts`` names the rows in
    conflict. ``A`` and ``b`` may be changed every tick (:meth:`set_matrix`,
    :meth:`set_target`); the number of rows is fixed.

    Args:
        A: m x nv matrix (nv of the robot the controller drives; checked when bound).
        b: m numbers (default zeros).
    """

    def __init__(self, A: Sequence[Sequence[float]] | ArrayLike, b: ArrayLike | None = None,
                 name: str | None = None) -> None:
        super().__init__(name)
        self._matrix = np.array(as_matrix(A), dtype=float)
        self._b = np.zeros(self._matrix.shape[0])
        if b is not None:
            self.set_target(b)

    @property
    def _rhs(self) -> NDArray[np.float64]:
        return self._b

    def bind(self, robot: Robot) -> LinearConstraintData:
        return LinearConstraintData(self, robot)

    def __repr__(self) -> str:
        return f"LinearConstraint(A={self._matrix.tolist()}, b={self._b.tolist()})"


class LinearConstraintData(ConstraintData):
    """A :class:`LinearConstraint` in one controller: ``A`` checked against the robot's nv."""

    constraint: LinearConstraint

    def __init__(self, linear: LinearConstraint, robot: Robot) -> None:
        linear.check_columns(robot)
        super().__init__(linear)
        self.n_equalities = linear._matrix.shape[0]

    def compute(self, kin: Kinematics, dt: float, rows: ConstraintRows) -> None:
        rows.A[...] = self.constraint._matrix
        rows.b[...] = self.constraint._b

    def row_labels(self) -> list[str]:
        return [f"row {i}" for i in range(self.n_equalities)]
