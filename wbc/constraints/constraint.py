"""Constraint base class: hard limits of the control QP.

A constraint may contribute

* **bounds** ``lb <= v <= ub`` (it writes its own ``lower``/``upper`` vectors of
  size nv, ``-inf``/``+inf`` where it has no opinion; the controller intersects
  them, soft ones clipped into the hard ones), and/or
* **inequality rows** ``G v <= h`` (``n_inequalities`` rows), and/or
* **equality rows** ``A v = b`` (``n_equalities`` rows).

The controller hands each constraint views into its preallocated QP buffers
(:class:`ConstraintRows`), so nothing is allocated per tick.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np

from ..item import Item
from ..kinematics import Kinematics
from ..program import TickProgram
from ..robot import Robot


@dataclass
class ConstraintRows:
    """Where a constraint writes this tick (all views into controller buffers)."""

    lower: np.ndarray  #: (nv,) own lower bound on v
    upper: np.ndarray  #: (nv,) own upper bound on v
    G: np.ndarray  #: (n_inequalities, nv)
    h: np.ndarray  #: (n_inequalities,)
    A: np.ndarray  #: (n_equalities, nv)
    b: np.ndarray  #: (n_equalities,)


class Constraint(Item, ABC):
    """Base class of all constraints (bound and shared as described in :class:`~wbc.item.Item`)."""

    has_bounds: bool = False
    n_inequalities: int = 0
    n_equalities: int = 0
    #: hard constraints (actuator limits, no-slip rows) always hold and are jointly feasible
    #: at v = 0; soft ones (position dampers, barriers) yield to them when they conflict:
    #: soft bounds are clipped into the hard ones every tick, and soft rows become elastic
    #: in the controller's fallback solve
    hard: bool = True
    #: False when ``compute`` never changes the bounds (they are written once in
    #: ``write_static``), so the controller can intersect them once instead of every tick
    dynamic_bounds: bool = True

    def __init__(self, name: str | None = None) -> None:
        self.name = name or type(self).__name__

    def write_static(self, rows: ConstraintRows) -> None:
        """Write the parts that never change (called once after allocation)."""

    @abstractmethod
    def compute(self, kin: Kinematics, dt: float, rows: ConstraintRows) -> None:
        """Write this tick's bounds / rows."""

    def add_ops(self, program: TickProgram, kin: Kinematics, rows: ConstraintRows) -> bool:
        """Register this constraint's per-tick work as compiled ops and return True, or return
        False to be computed by :meth:`compute` every tick (the default). The ops must
        compute exactly what :meth:`compute` would; a subclass that overrides ``compute`` but
        not ``add_ops`` is computed in Python (``program.ops_follow_compute``)."""
        return False

    def row_labels(self) -> list[str]:
        """Human-readable names of the inequality rows, then of the equality rows."""
        return [f"row {i}" for i in range(self.n_inequalities + self.n_equalities)]

    def __repr__(self) -> str:
        return f"{type(self).__name__}()"
