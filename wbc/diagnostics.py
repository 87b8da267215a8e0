"""Diagnostics record of one control tick (``Controller.last``)."""

from __future__ import annotations

import numpy as np

ACTIVE_TOLERANCE = 1e-7  #: a bound or row within this of equality counts as active


class TickDiagnostics:
    """What happened in the last call of :meth:`Controller.step`.

    * ``status`` -- ``"optimal"`` or the backend's failure reason; ``success`` -- bool;
    * ``solve_time`` -- time inside the QP backend [s]; ``tick_time`` -- whole ``step`` [s];
    * ``task_errors`` -- each task's error before the command (unweighted, [m] / [rad] /
      [m/s]); keys like ``"FrameTask(ee).position"``;
    * ``v`` -- the command (a copy); ``u`` -- the same command over the real inputs,
      ``v = robot.input_map(q) u`` (equal to ``v`` for holonomic bases);
    * ``max_violation`` -- largest violation of any bound or row by the command (solver tolerance);
    * ``active_constraints`` -- labels of the bounds / rows that hold with equality (within
      :data:`ACTIVE_TOLERANCE`) at the command.

    The last two are computed on first access from copies of this tick's bounds, so
    recording diagnostics costs the control loop only those copies.
    """

    __slots__ = ("tick", "solver", "status", "success", "solve_time", "tick_time", "task_errors",
                 "v", "u", "_lower", "_upper", "_row_residual", "_n_ineq", "_labels", "_active", "_violation")

    def __init__(self, tick: int, solver: str, status: str, success: bool, solve_time: float,
                 tick_time: float, task_errors: dict[str, float], v: np.ndarray | None = None,
                 lower: np.ndarray | None = None, upper: np.ndarray | None = None,
                 row_residual: np.ndarray | None = None, n_ineq: int = 0,
                 labels: "ActiveSetLabels | None" = None, u: np.ndarray | None = None) -> None:
        self.tick, self.solver, self.status, self.success = tick, solver, status, success
        self.solve_time, self.tick_time = solve_time, tick_time
        self.task_errors, self.v, self.u = task_errors, v, u
        self._lower, self._upper = lower, upper  # (k, nv): bounds of each bounding constraint
        self._row_residual, self._n_ineq = row_residual, n_ineq  # C v - upper(rows)
        self._labels = labels
        self._active: list[str] | None = None
        self._violation: float | None = None

    @property
    def max_violation(self) -> float:
        if self._violation is None:
            if self.v is None:
                self._violation = float("nan")
            else:
                worst = max(float(np.max(self.v - self._upper)), float(np.max(self._lower - self.v)), 0.0)
                if self._row_residual is not None and self._row_residual.size:
                    rows, p = self._row_residual, self._n_ineq
                    worst = max(worst, float(np.max(rows[:p], initial=0.0)),
                                float(np.max(np.abs(rows[p:]), initial=0.0)))
                self._violation = worst
        return self._violation

    @property
    def active_constraints(self) -> list[str]:
        if self._active is None:
            self._active = []
            if self.v is not None and self._labels is not None:
                at_upper = np.abs(self.v - self._upper) <= ACTIVE_TOLERANCE
                at_lower = np.abs(self.v - self._lower) <= ACTIVE_TOLERANCE
                rows = None
                if self._row_residual is not None:
                    rows = np.ones(self._row_residual.size, dtype=bool)
                    rows[: self._n_ineq] = self._row_residual[: self._n_ineq] >= -ACTIVE_TOLERANCE
                self._active = self._labels.names(np.concatenate([at_upper, at_lower], axis=1), rows)
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

    def names(self, bound_mask: np.ndarray, row_mask: np.ndarray | None) -> list[str]:
        names = [self.bound_labels[k][i] for k, i in zip(*np.nonzero(bound_mask))]
        if row_mask is not None:
            names += [self.row_labels[i] for i in np.flatnonzero(row_mask)]
        return names
