"""The error-scaled (Levenberg-Marquardt) damping of the tasks, ``Controller.lm_damping``.

Each task t whose data has ``lm_damped`` has ``mu_t = lm_damping |dt (W r - W xi)_t| max_j
|(W J)_t e_j|`` (:func:`wbc.runtime.kernels.lm_curvature`; ``W xi`` the task's weighted feed-forward,
``TaskData.feedforward``), and the damping of its level is raised to ``mu = sum_t mu_t``. The
tick program sums the ``mu_t`` of a level (one LM_TASK op per task, after the tasks' rows are
written) and then either writes ``sqrt(max(damping, mu)) I`` into the damping rows of a single
weighted level -- which every form of its QP sums: the normal equations, the lifted QP and its
dense fallback, the holonomic preview -- or adds ``max(mu - damping, 0) I`` to the Hessian of
one level of a hierarchy (damping 0 above the last). See :class:`wbc.Controller` for the math.
"""

from __future__ import annotations

import numpy as np

from ..qp.layout import TaskBlock
from ..runtime import kernels
from ..runtime.program import TickProgram


class LMDamping:
    """The LM ops of one controller: ``mu`` of each of its ``count`` levels, and the settings
    array ``lm`` (``(lm_damping,)``, the controller's) they read."""

    def __init__(self, lm: np.ndarray, count: int) -> None:
        self.lm = lm
        self.mu = np.zeros(count)  #: this tick's mu of each level
        self._no_feedforward: dict[int, np.ndarray] = {}  # zeros (dim) for tasks without one

    def add_task_ops(self, program: TickProgram, stack_t: np.ndarray, blocks: list[TaskBlock], level: int) -> bool:
        """Append the LM_TASK op of every damped task of ``blocks`` (summed into level ``level``'s
        mu); False when none is damped (mu stays 0)."""
        damped = [(task, start) for task, _, _, start in blocks if task.lm_damped]
        for i, (task, start) in enumerate(damped):
            feedforward = task.feedforward
            if feedforward is None:
                feedforward = self._no_feedforward.setdefault(task.dim, np.zeros(task.dim))
            program.add(kernels.LM_TASK, stack=stack_t, feedforward=feedforward, mu=self.mu[level:level + 1],
                        lm=self.lm, start=start, dim=task.dim, nv=stack_t.shape[0] - 1, rows=stack_t.shape[1],
                        reset=int(i == 0))
        return bool(damped)

    def add_rows_op(self, program: TickProgram, stack_t: np.ndarray, first: int, scaling: np.ndarray) -> None:
        """Append the op writing ``sqrt(max(damping, mu)) I`` (level 0's mu; ``scaling = (damping,
        floor)``) into the damping rows ``first:first + nv`` of the stack."""
        nv = stack_t.shape[0] - 1
        program.add(kernels.LM_DAMPING_ROWS, stack=stack_t, mu=self.mu[0:1], scaling=scaling, nv=nv,
                    rows=stack_t.shape[1], first=first)

    def add_level_op(self, program: TickProgram, level: int, Hc: np.ndarray, scaling: np.ndarray) -> None:
        """Append the op raising the damping of level ``level`` (``scaling[0]``, of ``scaling =
        (damping, floor)``) to its mu in ``Hc = [H; c]``."""
        program.add(kernels.LM_DAMPING_LEVEL, mu=self.mu[level:level + 1], scaling=scaling, Hc=Hc, nv=Hc.shape[1])
