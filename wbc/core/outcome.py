"""What answered a tick (:attr:`wbc.TickDiagnostics.outcome`): the control flow of the
fallback chain runs on this enum; ``TickDiagnostics.status`` is its text for people."""

from __future__ import annotations

from enum import Enum


class Outcome(Enum):
    """Which link of the fallback chain produced the command (see :class:`wbc.Controller`)."""

    OPTIMAL = "optimal"  #: the backend's answer to the full QP, checked
    ELASTIC = "fallback: elastic"  #: DAQP with the soft rows elastic (hard limits kept, checked)
    #: strict priorities: the answer of the deepest level solved this tick, when a level below it
    #: and its elastic re-solve failed (optimal for its level and those above; hard limits kept, checked)
    LEVEL_ABOVE = "fallback: level above"
    ZERO = "fallback: zero command"  #: v = 0, which satisfies every shipped hard limit
