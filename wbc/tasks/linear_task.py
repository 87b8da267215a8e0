"""A soft linear equation on the joint velocity, ``A v = b`` (joint couplings, custom references)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.errors import InvalidInputError
from ..core.settings import Cost
from ..core.validation import as_vector
from ..model.kinematics import Kinematics
from ..model.robot import Robot
from .error_task import ErrorTask, ErrorTaskData
from .task import _norm


class LinearEquation:
    """``A`` (m x nv) and ``b`` (m) of an equation ``A v = b`` that an item asks for, each
    reassignable between ticks (the number of rows is fixed): shared by :class:`LinearTask`
    (soft) and :class:`~wbc.LinearConstraint` (hard). ``b`` lives in ``_rhs`` (a
    LinearTask's feed-forward)."""

    name: str
    _matrix: NDArray[np.float64]

    @property
    def _rhs(self) -> NDArray[np.float64]:
        raise NotImplementedError

    def set_target(self, b: ArrayLike) -> None:
        """``b`` (m numbers) from the next tick on.

        Raises:
            InvalidInputError: not m finite numbers (the previous ``b`` is kept).
        """
        self._rhs[:] = as_vector(b, self._rhs.size, "b")

    def set_matrix(self, A: ArrayLike) -> None:
        """``A`` (the same shape as before) from the next tick on.

        Raises:
            InvalidInputError: not finite, or another shape (the previous ``A`` is kept).
        """
        matrix = as_matrix(A)
        if matrix.shape != self._matrix.shape:
            raise InvalidInputError(f"{self.name}: A must keep its shape "
                                    f"{self._matrix.shape}, got {matrix.shape}; create another "
                                    f"{type(self).__name__} for another number of rows")
        self._matrix[...] = matrix

    @property
    def target(self) -> NDArray[np.float64]:
        """``b`` (a copy)."""
        return self._rhs.copy()

    @property
    def matrix(self) -> NDArray[np.float64]:
        """``A`` (a copy)."""
        return self._matrix.copy()

    def check_columns(self, robot: Robot) -> None:
        """Refuse ``A`` whose columns are not ``robot``'s velocity coordinates."""
        if self._matrix.shape[1] != robot.nv:
            raise InvalidInputError(f"{self.name}: A has {self._matrix.shape[1]} columns, "
                                    f"robot {robot.name!r} has nv = {robot.nv}: give one column per "
                                    "velocity coordinate")


class LinearTask(LinearEquation, ErrorTask):
    """Ask for ``A v = b`` in the least-squares sense: rows ``W (A v - b)``, i.e. the cost
    ``sum_i cost_i (A_i v - b_i)^2``, with ``A`` (m x nv) and ``b`` (m) given by the user in
    the units of their choice (e.g. ``v_i - v_j = 0`` couples two joints).

    The rows are exact (no error is fed back: no gain, no LM damping); ``b`` is the rows'
    feed-forward (``xi`` of :class:`~wbc.tasks.error_task.ErrorTask`). ``A`` and ``b`` may be
    changed every tick (:meth:`set_target`, :meth:`set_matrix`); the number of rows is fixed.
    The task's error (``Controller.last.task_errors``) is the residual ``|A v - b|`` of the
    command.

    Args:
        A: m x nv matrix (nv of the robot the controller drives; checked when bound).
        b: m numbers (default zeros).
        cost: [cost] / [units of A v]^2, scalar or one per row.
    """

    cost = Cost("_weights", slice(0, None))
    #: no error to feed back (the target is b): not a setting, the rows are the same for any gain
    gain = 1.0

    def __init__(self, A: Sequence[Sequence[float]] | ArrayLike, b: ArrayLike | None = None, cost: ArrayLike = 1.0,
                 name: str | None = None) -> None:
        matrix = np.array(as_matrix(A), dtype=float)
        super().__init__(matrix.shape[0], 1.0, name)
        self._matrix = matrix
        self.cost = cost
        self.set_target(np.zeros(matrix.shape[0]) if b is None else b)

    @property
    def _rhs(self) -> NDArray[np.float64]:
        return self._feedforward

    def bind(self, robot: Robot) -> LinearTaskData:
        return LinearTaskData(self, robot)

    def __repr__(self) -> str:
        return f"LinearTask(A={self._matrix.tolist()}, b={self._feedforward.tolist()}, cost={self.cost.tolist()})"


class LinearTaskData(ErrorTaskData):
    """A :class:`LinearTask` in one controller: ``A`` checked against the robot's nv."""

    task: LinearTask
    lm_damped = False  # exact rows, a reference rather than an error

    def __init__(self, task: LinearTask, robot: Robot) -> None:
        task.check_columns(robot)
        super().__init__(task, robot)
        self._residual = np.zeros(self.dim)

    def compute_error_and_jacobian(self, kin: Kinematics, error: np.ndarray, jacobian: np.ndarray) -> None:
        jacobian[...] = self.task._matrix  # e = 0 (never written); b enters as the feed-forward

    def report(self, v: np.ndarray, errors: dict[str, float]) -> None:
        """The residual ``|A v - b|`` of the command."""
        np.matmul(self.task._matrix, v, out=self._residual)
        self._residual -= self.task._feedforward
        errors[self.name] = _norm(self._residual)


def as_matrix(value: ArrayLike) -> NDArray[np.float64]:
    """A finite 2-D float array with at least one row and one column."""
    try:
        shape = np.shape(value)
    except ValueError:
        raise InvalidInputError("A must be a matrix (m x nv): its rows have different lengths") from None
    if len(shape) != 2 or 0 in shape:
        raise InvalidInputError(f"A must be a matrix (m x nv, m >= 1), e.g. [[0, 0, 0, 1, -1, 0, 0, 0]], got shape "
                                f"{shape}")
    matrix = as_vector(np.ravel(np.asarray(value, dtype=object)), shape[0] * shape[1], "A")
    return matrix.reshape(shape)
