"""The node's record of itself: counters, latencies, tracking errors -- published as
``diagnostic_msgs/DiagnosticArray`` every diagnostics period and summed up at exit.

Latencies are kept for the last :data:`WINDOW` ticks (exact percentiles over them):

* ``latency`` -- the node's added latency: from the tick's start, when it takes the newest
  state from DDS, to the return of the last command's write ("state received -> command
  published": reading and checking the messages, the controller's step, the check of the
  command, serializing and writing it);
* ``step`` -- :meth:`wbc.Controller.step` alone (``controller.last.tick_time``: on the one-call
  native path the native call, see :class:`wbc.TickDiagnostics`);
* ``state_age`` -- how old the newest joint state was when the tick took it (its writer's
  source timestamp to the tick, same clock on one machine): transport plus the wait for the
  tick, up to one period.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .messages import DiagnosticArray, DiagnosticStatus, Header, KeyValue

WINDOW = 1 << 17  #: ticks whose latencies are kept (131072: 22 min at 100 Hz)
OK, WARN, ERROR, STALE = 0, 1, 2, 3  #: DiagnosticStatus levels


class Window:
    """The last :data:`WINDOW` values of one series, preallocated."""

    def __init__(self) -> None:
        self._values = np.zeros(WINDOW)
        self.count = 0

    def add(self, value: float) -> None:
        self._values[self.count % WINDOW] = value
        self.count += 1

    @property
    def values(self) -> NDArray[np.float64]:
        return self._values[:min(self.count, WINDOW)]

    def percentile(self, q: float) -> float:
        """The ``q``-th percentile of the kept values (NaN when there is none)."""
        return float(np.percentile(self.values, q)) if self.count else math.nan


@dataclass
class NodeStatus:
    """Counters and series of a running node."""

    ticks: int = 0  #: ticks run
    control_ticks: int = 0  #: ticks that commanded the robot (state fresh)
    overruns: int = 0  #: ticks that ended after the next one was due
    watchdog_trips: int = 0  #: times the state went stale and zero was published
    fallback_ticks: int = 0  #: ticks whose command came from a fallback (``last.success`` False)
    #: control ticks with no new joint state since the previous one (the robot's state was late: the
    #: command is computed from the state of a tick before)
    repeated_state_ticks: int = 0
    #: episodes of consecutive fallback ticks, and the constraints in conflict at the latest one's
    #: first tick (``controller.last.conflicts``; empty when none were found)
    conflict_episodes: int = 0
    last_conflicts: list[str] = field(default_factory=list)
    in_fallback: bool = False  #: the latest control tick was answered by a fallback
    zero_sent: bool = False  #: the latest command written is the zero command of the watchdog
    state: str = "waiting"  #: "waiting" (no state yet), "control", "stale"
    stale_reason: str = ""
    last_status: str = ""  #: ``controller.last.status`` of the latest control tick
    last_solve_time: float = math.nan
    #: [s] at each watchdog trip, the age of the oldest input the state needs (a joint or the odometry)
    trip_ages: list[float] = field(default_factory=list)
    latency: Window = field(default_factory=Window)
    step: Window = field(default_factory=Window)
    state_age: Window = field(default_factory=Window)
    position_error: Window = field(default_factory=Window)  #: [m] of the reference task, each control tick
    position_error_squares: float = 0.0
    position_error_max: float = 0.0

    def record_outcome(self, success: bool, conflicts: Callable[[], list[str]]) -> None:
        """Count a control tick answered by a fallback; at the first of an episode of such ticks,
        note the constraints in conflict (``conflicts()`` is called then only: it solves small QPs)."""
        if not success:
            self.fallback_ticks += 1
            if not self.in_fallback:
                self.conflict_episodes += 1
                self.last_conflicts = conflicts()
        self.in_fallback = not success

    def record_error(self, error: float) -> None:
        self.position_error.add(error)
        self.position_error_squares += error * error
        self.position_error_max = max(self.position_error_max, error)

    def summary(self, drops: dict[str, int], scaled: int, replaced: int) -> dict[str, Any]:
        """The numbers ``wbc ros`` prints at exit (``_us``, ``_m``, ``_s``: units)."""
        us = 1e6
        summary: dict[str, Any] = {
            "ticks": self.ticks, "control_ticks": self.control_ticks, "overruns": self.overruns,
            "watchdog_trips": self.watchdog_trips, "fallback_ticks": self.fallback_ticks,
            "conflict_episodes": self.conflict_episodes, "last_conflicts": list(self.last_conflicts),
            "repeated_state_ticks": self.repeated_state_ticks,
            "commands_scaled_into_limits": scaled, "commands_replaced_by_zero": replaced,
            "dropped_messages": sum(drops.values()), "dropped_by_reason": dict(drops),
            "latency_p50_us": self.latency.percentile(50) * us, "latency_p99_us": self.latency.percentile(99) * us,
            "step_p50_us": self.step.percentile(50) * us, "step_p99_us": self.step.percentile(99) * us,
            "state_age_p50_us": self.state_age.percentile(50) * us,
            "state_age_p99_us": self.state_age.percentile(99) * us,
            "state_age_max_us": self.state_age.percentile(100) * us,
            "watchdog_trip_state_ages_s": self.trip_ages,
        }
        if self.position_error.count:
            summary |= {"position_error_rms_m": math.sqrt(self.position_error_squares / self.position_error.count),
                        "position_error_max_m": self.position_error_max}
        return summary


def diagnostics_message(name: str, status: NodeStatus, values: dict[str, str], stamp_ns: int) -> DiagnosticArray:
    """The node's ``DiagnosticArray``: one ``DiagnosticStatus`` named ``name`` (the node), its level
    OK while it controls with optimal ticks, WARN after a fallback, an overrun or a dropped
    message since the last one (in ``values``), ERROR while the state is stale, STALE before
    the first state."""
    if status.state == "waiting":
        level, message = STALE, "waiting for the first joint states"
    elif status.state == "stale":
        level, message = ERROR, f"watchdog: {status.stale_reason}; zero command sent"
    elif values.get("warnings"):
        level, message = WARN, values["warnings"]
    else:
        level, message = OK, "controlling"
    header = Header()
    header.stamp.sec, header.stamp.nanosec = divmod(stamp_ns, 1_000_000_000)
    return DiagnosticArray(header=header, status=[DiagnosticStatus(
        level=level, name=name, message=message, hardware_id="",
        values=[KeyValue(key=key, value=value) for key, value in values.items() if key != "warnings"])])
