"""Diagnostics record of one control tick (``Controller.last``)."""

from __future__ import annotations

import numpy as np


class TickDiagnostics:
    """What happened in the last call of :meth:`Controller.step`.

    * ``status`` -- ``"optimal"`` or the backend's failure reason; ``success`` -- bool;
    * ``solve_time`` -- time inside the QP backend [s]; ``tick_time`` -- whole ``step`` [s];
    * ``task_errors`` -- each task's error before the command (unweighted, [m] / [rad] /
      [m/s]); keys like ``"FrameTask(ee).position"``;
    * ``max_violation`` -- largest constraint violation of the command (solver tolerance);
    * ``active_constraints`` -- labels of the bounds / rows that hold with equality (within
      ``ACTIVE_TOLERANCE`` of :mod:`wbc.controller`) at the command; built on first access,
      so recording diagnostics costs the hot path only two boolean masks.
    """

    __slots__ = ("tick", "solver", "status", "success", "solve_time", "tick_time", "task_errors",
                 "max_violation", "v", "_bound_mask", "_row_mask", "_labels", "_active")

    def __init__(self, tick: int, solver: str, status: str, success: bool, solve_time: float,
                 tick_time: float, task_errors: dict[str, float], max_violation: float,
                 v: np.ndarray | None = None, bound_mask: np.ndarray | None = None,
                 row_mask: np.ndarray | None = None, labels: "ActiveSetLabels | None" = None) -> None:
        self.tick, self.solver, self.status, self.success = tick, solver, status, success
        self.solve_time, self.tick_time = solve_time, tick_time
        self.task_errors, self.max_violation, self.v = task_errors, max_violation, v
        self._bound_mask, self._row_mask, self._labels = bound_mask, row_mask, labels
        self._active: list[str] | None = None

    @property
    def active_constraints(self) -> list[str]:
        if self._active is None:
            self._active = [] if self._labels is None else self._labels.names(self._bound_mask, self._row_mask)
        return self._active

    def __repr__(self) -> str:
        return (f"TickDiagnostics(tick={self.tick}, solver={self.solver!r}, status={self.status!r}, "
                f"solve_time={self.solve_time:.2e}, tick_time={self.tick_time:.2e}, "
                f"task_errors={self.task_errors}, max_violation={self.max_violation:.2e}, "
                f"active_constraints={self.active_constraints})")


class ActiveSetLabels:
    """Names for the entries of the active-set masks of one controller."""

    def __init__(self, bound_labels: list[list[str]], row_labels: list[str]) -> None:
        self.bound_labels = bound_labels  #: [constraint k][2 * nv]: upper then lower of each coordinate
        self.row_labels = row_labels  #: inequality rows then equality rows

    def names(self, bound_mask: np.ndarray | None, row_mask: np.ndarray | None) -> list[str]:
        names = []
        if bound_mask is not None:
            for k, i in zip(*np.nonzero(bound_mask)):
                names.append(self.bound_labels[k][i])
        if row_mask is not None:
            names += [self.row_labels[i] for i in np.flatnonzero(row_mask)]
        return names
