"""The buffers of one controller's tick, in one object: what the hierarchy, the fallback and
the diagnostics record read (never the controller itself).

The controller builds a :class:`TickBuffers` once (its arrays are the ones the tick program
writes) and advances :attr:`TickBuffers.tick` every step; a diagnostics record compares its own
tick with it to know whether the buffers still hold its tick.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from ..model.kinematics import Kinematics
from ..model.tick_context import TickContext
from ..qp.layout import ConstraintLayout, LevelRows, TaskStack
from ..qp.problem import QP
from ..qp.reduction import InputReduction
from ..tasks.task import TaskData

ACTIVE_TOLERANCE = 1e-7  #: a bound or row within this of equality counts as active


class LevelAnswers(Protocol):
    """The levels of a strict hierarchy as the diagnostics read them
    (:class:`wbc.control.hierarchy.Hierarchy`)."""

    count: int  #: number of levels
    rows: LevelRows  #: each level's rows in the task stack
    answers: list[NDArray[np.float64] | None]  #: each level's answer (over v) in the latest tick


class TickBuffers:
    """The buffers one controller's tick fills, and the tick counter.

    * ``task_data``, ``task_stack`` -- the tasks' data and their stacked rows ``[W J | W r]``;
    * ``qp`` -- the controller's QP over v (level 0's with priorities), ``constraints`` -- where
      each constraint's bounds and rows sit in it, with their labels (and the bound policy);
    * ``preview`` -- the holonomic preview ``-H^-1 c``; ``cost_scaling`` -- (damping, floor);
      ``lm_damping`` -- the scale of the error-scaled damping (operands of the program's ops);
    * ``input_map`` -- S(q) of a nonholonomic base (written each tick), ``reduction`` -- the
      reduced form's buffers (None without ``reduced``);
    * ``cascade`` -- the strict hierarchy's levels (None for one level); ``tick`` -- the counter;
    * ``context`` -- the tick's context (:class:`~wbc.model.tick_context.TickContext`: kinematics,
      dt, the previous command, the measured velocity).
    """

    cascade: LevelAnswers | None  #: the strict hierarchy's levels (None for one level)
    tick: int  #: ticks stepped (1 after the first step): the tick whose values the buffers hold

    def __init__(self, kinematics: Kinematics, task_data: list[TaskData], task_stack: TaskStack, qp: QP,
                 constraints: ConstraintLayout, cost_scaling: NDArray[np.float64], lm_damping: NDArray[np.float64],
                 input_map: NDArray[np.float64], reduction: InputReduction | None,
                 context: TickContext | None = None) -> None:
        self.kinematics, self.nv, self.context = kinematics, qp.n, context
        self.task_data, self.task_stack, self.qp, self.constraints = task_data, task_stack, qp, constraints
        self.bounds = constraints.bounds
        self.cost_scaling, self.lm_damping = cost_scaling, lm_damping
        self.preview = np.zeros(qp.n)
        self.input_map, self.reduction = input_map, reduction
        self.cascade = None
        self.tick = 0
        self._flat_levels: LevelRows | None = None

    @property
    def levels(self) -> LevelRows:
        """The rows of each priority level (one level without a hierarchy)."""
        if self.cascade is not None:
            return self.cascade.rows
        if self._flat_levels is None:
            self._flat_levels = LevelRows(self.task_stack, lambda task: 0, 1, self.nv)
        return self._flat_levels

    # ------------------------------------------------------------ diagnostics
    def constraint_violation(self, v: NDArray[np.float64]) -> float:
        """Largest violation of this tick's bounds and rows by ``v`` (0 when feasible)."""
        qp = self.qp
        worst = max(float(np.max(v - qp.ub)), float(np.max(qp.lb - v)), 0.0)
        if qp.n_ineq or qp.n_eq:
            rows = qp.C @ v - qp.upper[qp.n:]
            worst = max(worst, float(np.max(rows[: qp.n_ineq], initial=0.0)),
                        float(np.max(np.abs(rows[qp.n_ineq:]), initial=0.0)))
        return worst

    def active_constraints(self, v: NDArray[np.float64]) -> list[str]:
        """Labels of this tick's bounds and rows that ``v`` meets with equality."""
        bounds, labels = self.bounds, self.constraints
        at_upper = np.abs(v - bounds.upper) <= ACTIVE_TOLERANCE
        at_lower = np.abs(v - bounds.lower) <= ACTIVE_TOLERANCE
        active = np.nonzero(np.concatenate([at_upper, at_lower], 1))
        names = [labels.bound_labels[k][i] for k, i in zip(*active, strict=True)]
        qp = self.qp
        row_labels = labels.row_labels
        if qp.n_ineq:
            rows = qp.C[: qp.n_ineq] @ v - qp.h
            names += [row_labels[i] for i in np.flatnonzero(rows >= -ACTIVE_TOLERANCE)]
        return names + row_labels[qp.n_ineq:]  # equality rows always hold

    def level_errors(self, v: NDArray[np.float64] | None) -> list[float]:
        """``|A_k v - b_k|`` of each level at the command ``v`` (weighted task residuals, as in the cost)."""
        rows = self.levels
        return [rows.residuals(self.task_stack.stack, v, k) for k in range(rows.count)]

    def level_optima(self, v: NDArray[np.float64] | None, answered: bool) -> list[float]:
        """``|A_k v_k - b_k|`` of each level at its own answer ``v_k`` (a flat controller's is the
        command); NaN for a level that was not solved, and for every level when no solve
        ``answered`` the tick (the zero command)."""
        cascade = self.cascade
        if cascade is None:
            return self.level_errors(v if answered else None)
        answers = cascade.answers if answered else [None] * cascade.count
        return [cascade.rows.residuals(self.task_stack.stack, answer, k) for k, answer in enumerate(answers)]
