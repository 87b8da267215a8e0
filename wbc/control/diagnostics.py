"""Diagnostics record of one control tick (``Controller.last``)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ..core.errors import WbcError
from ..core.outcome import Outcome
from .conflicts import find_conflicts
from .tick_buffers import TickBuffers

_OPTIMAL = Outcome.OPTIMAL


class StaleDiagnosticsError(WbcError):
    """A lazily computed diagnostics field was read after the controller stepped again."""


class NoTickYetError(WbcError, AttributeError):
    """:attr:`Controller.last <wbc.Controller.last>` was read before the first
    :meth:`~wbc.Controller.step`. An ``AttributeError`` too, so ``hasattr(controller, "last")``
    and ``getattr(controller, "last", None)`` tell whether the controller has ticked."""


class TickDiagnostics:
    """What happened in the last call of :meth:`Controller.step`.

    Always available (set during the tick):

    * ``tick`` -- tick counter; ``solver``; ``outcome`` -- :class:`wbc.core.outcome.Outcome` (which link
      of the fallback chain answered); ``status`` -- ``"optimal"``, or what went wrong and which
      fallback produced the command, in words (see :class:`Controller`); ``success`` -- True when
      the command is the (checked) solution of the full QP (``outcome is Outcome.OPTIMAL``);
    * ``solve_time`` -- time inside the QP backend(s) [s]; ``tick_time`` -- the whole ``step`` [s], but
      on the control loop's one-call path (a tick the native program answers: from the second
      tick of a controller whose program does the whole tick, without ``v_measured``) the native
      call alone, from ``q``'s copy to the checked answer, timed by the program itself: the
      ~0.3-0.5 us of Python around that call (``q``'s type check, the copy of the answer) are
      not in it;
    * ``v`` -- the command; ``u`` -- the same command over the real inputs, ``v = S(q) u``
      (``u is v`` for holonomic bases).

    Computed on first access, from the controller's buffers of this tick
    (:class:`~wbc.control.tick_buffers.TickBuffers`; so recording
    costs the control loop nothing). Read them before the next ``step`` or call
    :meth:`freeze` to keep them; a stale read raises :class:`StaleDiagnosticsError`:

    * ``task_errors`` -- each task's error before the command (unweighted, [m] / [rad] /
      [m/s]); keys like ``"FrameTask(ee).position"``;
    * ``max_violation`` -- largest violation of any bound or row by the command;
    * ``active_constraints`` -- labels of the bounds / rows holding with equality (within
      :data:`~wbc.control.tick_buffers.ACTIVE_TOLERANCE`), e.g. ``"JointVelocityLimits: arm_joint_2 upper"``;
    * ``level_errors`` -- per priority level, highest first (one entry without levels), the
      weighted residual ``|A_k v - b_k|`` of its tasks at the command (the square root of the
      level's cost, as in the QP, before the damping); ``level_optima`` -- the same at the
      level's own answer, the best it could do below the levels above it (NaN for a level that
      was not solved). ``level_errors[k] - level_optima[k]`` is what the levels below cost level
      k: zero up to the band (:data:`wbc.control.hierarchy.BAND`) and the backend's tolerance;
    * ``conflicts`` -- on a tick that did not succeed, the labels of a set of constraints that
      cannot hold together (bounds and rows, as in ``active_constraints``; each one takes part,
      removing any one resolves the conflict: :mod:`wbc.control.conflicts`), e.g.
      ``["PushJoint: row 0", "JointVelocityLimits: arm_joint_1 upper"]``; ``[]`` when the
      constraints were compatible (the backend failed for another reason) or the tick succeeded.
    """

    tick: int  #: the tick counter (1 at the first step)
    solver: str  #: the backend's name
    outcome: Outcome  #: which link of the fallback chain answered
    status: str  #: ``"optimal"``, or what went wrong and which fallback answered, in words
    success: bool  #: the command is the checked solution of the full QP (``outcome is Outcome.OPTIMAL``)
    solve_time: float  #: time inside the QP backend(s) [s]
    tick_time: float  #: the whole step [s]; on the one-call path the native call (see the class docstring)
    v: NDArray[np.float64] | None  #: the command (set by every step)
    u: NDArray[np.float64] | None  #: the command over the real inputs, ``v = S(q) u`` (``u is v`` for holonomic bases)
    __slots__ = ("tick", "solver", "outcome", "status", "success", "solve_time", "tick_time", "v", "u",
                 "_buffers", "_task_errors", "_active", "_violation", "_level_errors", "_level_optima",
                 "_conflicts")

    def __init__(self, buffers: TickBuffers, tick: int, solver: str, outcome: Outcome, status: str,
                 solve_time: float, tick_time: float, v: NDArray[np.float64] | None = None,
                 u: NDArray[np.float64] | None = None) -> None:
        self._buffers = buffers
        self.tick, self.solver, self.outcome, self.status = tick, solver, outcome, status
        self.success = outcome is _OPTIMAL
        self.solve_time, self.tick_time, self.v, self.u = solve_time, tick_time, v, u
        self._task_errors: dict[str, float] | None = None
        self._active: list[str] | None = None
        self._violation: float | None = None
        self._level_errors: list[float] | None = None
        self._level_optima: list[float] | None = None
        self._conflicts: list[str] | None = None

    def _source(self) -> TickBuffers:
        if self._buffers.tick != self.tick:
            raise StaleDiagnosticsError(
                f"diagnostics of tick {self.tick} were overwritten by tick {self._buffers.tick}; "
                "read them before the next step() or call freeze()")
        return self._buffers

    @property
    def task_errors(self) -> dict[str, float]:
        if self._task_errors is None:
            buffers = self._source()
            self._task_errors = {}
            if self.v is not None:
                for task in buffers.task_data:
                    task.report(self.v, self._task_errors)
        return self._task_errors

    @property
    def max_violation(self) -> float:
        if self._violation is None:
            self._violation = float("nan") if self.v is None else self._source().constraint_violation(self.v)
        return self._violation

    @property
    def active_constraints(self) -> list[str]:
        if self._active is None:
            self._active = [] if self.v is None else self._source().active_constraints(self.v)
        return self._active

    @property
    def level_errors(self) -> list[float]:
        if self._level_errors is None:
            self._level_errors = self._source().level_errors(self.v)
        return self._level_errors

    @property
    def level_optima(self) -> list[float]:
        if self._level_optima is None:
            self._level_optima = self._source().level_optima(self.v, self.outcome is not Outcome.ZERO)
        return self._level_optima

    @property
    def conflicts(self) -> list[str]:
        if self._conflicts is None:
            self._conflicts = [] if self.success else find_conflicts(self._source())
        return self._conflicts

    def freeze(self) -> TickDiagnostics:
        """Compute every lazy field now, so the record stays readable after later ticks."""
        _ = self.task_errors, self.max_violation, self.active_constraints, self.level_errors, self.level_optima
        _ = self.conflicts
        return self

    def __repr__(self) -> str:
        lazy = ""
        if self._buffers.tick == self.tick or self._active is not None:
            lazy = (f", task_errors={self.task_errors}, max_violation={self.max_violation:.2e}, "
                    f"active_constraints={self.active_constraints}")
        return (f"TickDiagnostics(tick={self.tick}, solver={self.solver!r}, status={self.status!r}, "
                f"solve_time={self.solve_time:.2e}, tick_time={self.tick_time:.2e}{lazy})")
