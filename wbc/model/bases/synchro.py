"""A synchro-drive base: its wheels steer together, its chassis does not turn.

``heading`` is the wheels' common steering angle (not the chassis orientation); the velocity
obeys the unicycle's no-slip row and input map (De Luca's mobile manipulator, models/deluca).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from .interface import BaseKind
from .unicycle import UnicycleBase


@dataclass(frozen=True)
class SynchroBase(UnicycleBase):
    """The unicycle's rows and inputs, with the heading as the steering angle; no wheel model."""

    kind: BaseKind = BaseKind.SYNCHRO

    wheel_count: ClassVar[int] = 0  # its wheels are only locked


__all__ = ["SynchroBase"]
