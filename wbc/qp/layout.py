"""Where each task and constraint of a controller writes: the layout of its buffers."""

from __future__ import annotations

import numpy as np

from ..constraints.constraint import ConstraintData, ConstraintRows
from ..tasks.task import TaskData
from .bounds import BoundPolicy
from .problem import QP

#: a task's rows: (its data, W J view (dim x nv), W r view (dim), first row in the stack)
TaskBlock = tuple[TaskData, np.ndarray, np.ndarray, int]


class TaskStack:
    """The stacked least-squares rows ``A = [W J | W r]`` of every task.

    Rows: the ordinary tasks, then ``sqrt(damping) I`` (target 0), then the tasks that need
    the holonomic preview (SteeringTask). With A the first two blocks, ``A^T [W J] = [H; r^T J]``
    gives H and -c in one pass (:func:`wbc.runtime.kernels.normal_equations`), written straight into the
    QP buffer. Stored transposed (C-contiguous ``A^T``), so that every column of A the kernel sums
    over is contiguous. Each task writes its static rows once here (``write_static``).
    """

    def __init__(self, tasks: list[TaskData], nv: int) -> None:
        plain = [t for t in tasks if not t.uses_preview]
        preview = [t for t in tasks if t.uses_preview]
        self.n_plain = n_plain = sum(t.dim for t in plain) + nv  #: rows of the ordinary tasks and the damping
        self.stack_t = np.zeros((nv + 1, n_plain + sum(t.dim for t in preview)))
        self.stack = self.stack_t.T  #: (rows, nv + 1) view: [W J | W r]
        self.damping_rows = self.stack[n_plain - nv:n_plain, :nv]  #: sqrt(damping) I, written by the controller
        self.blocks: list[TaskBlock] = []
        self.preview_blocks: list[TaskBlock] = []
        start = 0
        for task in plain + preview:
            if preview and task is preview[0]:
                start = n_plain
            stop = start + task.dim
            block = (task, self.stack[start:stop, :nv], self.stack[start:stop, nv], start)
            task.write_static(block[1])
            (self.preview_blocks if task.uses_preview else self.blocks).append(block)
            start = stop


class ConstraintLayout:
    """Each constraint's bound slot (:class:`wbc.qp.bounds.BoundPolicy`: hard ones first) and its
    inequality and equality rows of the QP, with the labels of every bound and row (for
    ``last.active_constraints``) and the indices of the soft rows (elastic in the fallback).
    Each constraint writes its static parts once here (``write_static``)."""

    def __init__(self, constraints: list[ConstraintData], qp: QP, velocity_names: list[str]) -> None:
        nv = qp.n
        bounded = ([c for c in constraints if c.has_bounds and c.hard]
                   + [c for c in constraints if c.has_bounds and not c.hard])
        n_hard = sum(c.hard for c in bounded)
        self.bounds = BoundPolicy(n_hard, len(bounded) - n_hard, nv)
        self.blocks: list[tuple[ConstraintData, ConstraintRows]] = []
        inequality_labels: list[str] = []
        equality_labels: list[str] = []
        soft_rows: list[int] = []
        i_ineq = i_eq = 0
        for constraint in constraints:
            if constraint.has_bounds:
                lower, upper = self.bounds.slot(bounded.index(constraint))
            else:
                lower, upper = np.full(nv, -np.inf), np.full(nv, np.inf)
            p, e = constraint.n_inequalities, constraint.n_equalities
            rows = ConstraintRows(lower, upper, qp.G[i_ineq:i_ineq + p], qp.h[i_ineq:i_ineq + p],
                                  qp.A[i_eq:i_eq + e], qp.b[i_eq:i_eq + e])
            self.blocks.append((constraint, rows))
            labels = [f"{constraint.name}: {label}" for label in constraint.row_labels()]
            inequality_labels += labels[:p]
            equality_labels += labels[p:]
            if not constraint.hard:
                soft_rows += range(i_ineq, i_ineq + p)
            constraint.write_static(rows)
            i_ineq, i_eq = i_ineq + p, i_eq + e
        self.row_labels = inequality_labels + equality_labels  #: the QP's rows in order
        self.soft_rows = np.array(soft_rows, dtype=int)  #: indices among the inequality rows
        #: labels of every bound slot: (upper of each coordinate, then lower)
        self.bound_labels = [[f"{c.name}: {name} {side}" for side in ("upper", "lower") for name in velocity_names]
                             for c in bounded] or [[""] * (2 * nv)]
