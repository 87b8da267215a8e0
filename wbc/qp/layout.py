"""Where each task and constraint of a controller writes: the layout of its buffers."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..constraints.constraint import ConstraintData, ConstraintRows
from ..runtime import kernels
from ..runtime.program import TickProgram
from ..tasks.task import TaskData
from .bounds import BoundPolicy
from .problem import QP

#: a task's rows: (its data, W J view (dim x nv), W r view (dim), first row in the stack)
TaskBlock = tuple[TaskData, np.ndarray, np.ndarray, int]


class TaskStack:
    """The stacked least-squares rows ``A = [W J | W r]`` of every task.

    Rows: the ordinary tasks, then ``sqrt(damping) I`` (target 0), then the tasks that need
    the holonomic preview (SteeringTask), then the linear cost terms (``TaskData.linear``: one
    row ``c^T`` each, added to the QP's ``c`` alone). With A the first two blocks,
    ``A^T [W J] = [H; r^T J]`` gives H and -c in one pass
    (:func:`wbc.runtime.kernels.normal_equations`), written straight into the QP buffer. Stored
    transposed (C-contiguous ``A^T``), so that every column of A the kernel sums over is
    contiguous. Each task writes its static rows once here (``write_static``).
    """

    def __init__(self, tasks: list[TaskData], nv: int) -> None:
        plain = [t for t in tasks if not (t.uses_preview or t.linear)]
        preview = [t for t in tasks if t.uses_preview and not t.linear]
        linear = [t for t in tasks if t.linear]
        self.n_plain = n_plain = sum(t.dim for t in plain) + nv  #: rows of the ordinary tasks and the damping
        #: rows whose squares make the cost (ordinary, damping, preview); the linear rows follow
        self.n_quadratic = n_quadratic = n_plain + sum(t.dim for t in preview)
        self.stack_t = np.zeros((nv + 1, n_quadratic + sum(t.dim for t in linear)))
        self.stack = self.stack_t.T  #: (rows, nv + 1) view: [W J | W r]
        self.damping_rows = self.stack[n_plain - nv:n_plain, :nv]  #: sqrt(damping) I, written by the controller
        self.blocks: list[TaskBlock] = []
        self.preview_blocks: list[TaskBlock] = []
        self.linear_blocks: list[TaskBlock] = []
        for group, start, blocks in ((plain, 0, self.blocks), (preview, n_plain, self.preview_blocks),
                                     (linear, n_quadratic, self.linear_blocks)):
            for task in group:
                stop = start + task.dim
                block = (task, self.stack[start:stop, :nv], self.stack[start:stop, nv], start)
                task.write_static(block[1])
                blocks.append(block)
                start = stop

    def add_linear_op(self, program: TickProgram, qp: QP) -> None:
        """Append the op adding the linear rows to ``qp``'s ``c`` (none without linear terms):
        after the normal equations that reset it, before its cost normalisation."""
        if self.linear_blocks:
            program.add(kernels.LINEAR_COST, stack=self.stack_t, nv=qp.n, rows=self.stack_t.shape[1],
                        first=self.n_quadratic, last=self.stack_t.shape[1], Hc=qp.Hc)


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
            if not constraint.hard:
                soft_rows += range(i_ineq, i_ineq + p)
            constraint.write_static(rows)
            i_ineq, i_eq = i_ineq + p, i_eq + e
        self.soft_rows = np.array(soft_rows, dtype=int)  #: indices among the inequality rows
        #: ``|v_k| <= speed_bound[k]`` for every command: what the hard constraints imply
        #: (:meth:`ConstraintData.bound_speed`; ``TickContext.speed_bound``)
        self.speed_bound = np.full(nv, np.inf)
        for constraint in constraints:
            if constraint.hard:
                constraint.bound_speed(self.speed_bound)
        #: labels of every bound slot: (upper of each coordinate, then lower)
        self.bound_labels = [[f"{c.name}: {name} {side}" for side in ("upper", "lower") for name in velocity_names]
                             for c in bounded] or [[""] * (2 * nv)]


    @property
    def row_labels(self) -> list[str]:
        """Labels of the QP's rows in order (inequality rows, then equality rows), as the
        constraints name them now: a constraint whose rows change meaning from tick to tick
        (collision pairs) names this tick's."""
        inequality: list[str] = []
        equality: list[str] = []
        for constraint, _ in self.blocks:
            labels = [f"{constraint.name}: {label}" for label in constraint.row_labels()]
            inequality += labels[:constraint.n_inequalities]
            equality += labels[constraint.n_inequalities:]
        return inequality + equality

class LevelRows:
    """The rows of each priority level in a controller's task stack (tasks ordered by level; one
    level for a flat controller).

    ``tasks[k]``: (first, last) of level k's ordinary task rows; ``preview[k]``: those of its
    preview tasks (after the damping rows); ``(0, 0)`` when it has none. ``normal[k]``: the
    ordinary rows its cost sums -- the last level's include ``sqrt(damping) I``.
    """

    def __init__(self, stack: TaskStack, level_of: Callable[[object], int], count: int, nv: int) -> None:
        def span(blocks: list[TaskBlock]) -> list[tuple[int, int]]:
            spans = []
            for k in range(count):
                mine = [(start, start + task.dim) for task, _, _, start in blocks if level_of(task) == k]
                spans.append((mine[0][0], mine[-1][1]) if mine else (0, 0))
            return spans

        self.count = count
        self.tasks, self.preview = span(stack.blocks), span(stack.preview_blocks)
        damping = stack.n_plain - nv
        last_first = self.tasks[-1][0] if self.tasks[-1][1] > self.tasks[-1][0] else damping
        self.normal = self.tasks[:-1] + [(last_first, stack.n_plain)]
        #: normal ranges as floats (first, last per level), the operand of HIERARCHY_PREVIEW
        self.ranges = np.array([bound for span in self.normal for bound in span], dtype=np.float64)

    def dim(self, k: int) -> int:
        """Task rows of level k (ordinary and preview)."""
        (first, last), (first_p, last_p) = self.tasks[k], self.preview[k]
        return last - first + last_p - first_p

    def residuals(self, stack: np.ndarray, v: np.ndarray | None, k: int) -> float:
        """``|A_k v - b_k|`` of level k's task rows (``stack``: ``[W J | W r]``); NaN without v."""
        if v is None:
            return float("nan")
        nv = v.size
        (first, last), (first_p, last_p) = self.tasks[k], self.preview[k]
        rows = np.concatenate([stack[first:last], stack[first_p:last_p]])
        return float(np.linalg.norm(rows[:, :nv] @ v - rows[:, nv]))
