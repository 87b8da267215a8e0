"""Diagnostics record of one control tick (``Controller.last``)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class TickDiagnostics:
    """What happened in the last call of :meth:`Controller.step`.

    * ``status`` -- ``"optimal"`` or the backend's failure reason;
    * ``solve_time`` -- time inside the QP backend [s]; ``tick_time`` -- whole ``step`` [s];
    * ``task_errors`` -- each task's error before the command (unweighted, [m] / [rad] /
      [m/s]); keys like ``"FrameTask(ee).position"``;
    * ``active_constraints`` -- labels of the bounds / rows that hold with equality
      (within ``active_tolerance``) at the returned command;
    * ``max_violation`` -- largest constraint violation of the command (solver tolerance).
    """

    tick: int
    solver: str
    status: str
    success: bool
    solve_time: float
    tick_time: float
    task_errors: dict[str, float]
    max_violation: float
    active_constraints: list[str] = field(default_factory=list)
    v: np.ndarray | None = None
