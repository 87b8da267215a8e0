"""What answered a tick (:attr:`wbc.TickDiagnostics.outcome`): the control flow of the
fallback chain runs on this enum; ``TickDiagnostics.status`` is its text for people."""

from __future__ import annotations

from enum import Enum


class Outcome(Enum):
    """Which link of the fallback chain produced the command (see :class:`wbc.Controller`)."""

    OPTIMAL = "optimal"  #: the backend's answer to the full QP, checked
    ELASTIC = "fallback: elastic"  #: DAQP with the soft rows elastic (hard limits kept, checked)
    ZERO = "fallback: zero command"  #: v = 0, which satisfies every shipped hard limit
