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

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..item import Item
from ..model.kinematics import Kinematics
from ..model.robot import Robot
from ..runtime.program import TickProgram


@dataclass
class ConstraintRows:
    """Where a constraint writes this tick (all views into controller buffers)."""

    lower: NDArray[np.float64]  #: (nv,) own lower bound on v
    upper: NDArray[np.float64]  #: (nv,) own upper bound on v
    G: NDArray[np.float64]  #: (n_inequalities, nv)
    h: NDArray[np.float64]  #: (n_inequalities,)
    A: NDArray[np.float64]  #: (n_equalities, nv)
    b: NDArray[np.float64]  #: (n_equalities,)


class ConstraintData:
    """A constraint's data in one controller (:meth:`Constraint.bind`): what the controller
    calls each tick. Built-in constraints return a data object of their own (robot-resolved
    limits and indices); it reads the constraint's settings from ``self.constraint``."""

    has_bounds: bool = False
    n_inequalities: int = 0
    n_equalities: int = 0
    #: hard constraints (actuator limits, no-slip rows) always hold and are jointly feasible
    #: at v = 0; soft ones (position dampers, barriers) yield to them when they conflict:
    #: soft bounds are clipped into the hard ones every tick, and soft rows become elastic
    #: in the controller's fallback solve
    hard: bool = True
    #: the compiled functions (names in :mod:`wbc.runtime.kernels`) its Python :meth:`compute`
    #: may call: a controller computing it in Python compiles them when it is built, not in a tick
    python_kernels: tuple[str, ...] = ()

    def __init__(self, constraint: Constraint) -> None:
        self.constraint, self.name = constraint, constraint.name
        self.hard = constraint.hard

    def write_static(self, rows: ConstraintRows) -> None:
        """Write the parts that never change (called once after allocation)."""

    def bound_speed(self, speed: NDArray[np.float64]) -> None:
        """Lower ``speed[k]`` [unit/s] to a bound on ``|v_k|`` that every ``v`` this constraint
        allows keeps, at every configuration and tick (e.g. a constant speed limit); called once,
        when a controller is built, and only for hard constraints: every command the controller
        returns keeps them (``TickContext.speed_bound``). Default: no such bound."""

    def prepare_compute(self) -> None:
        """Compile what :meth:`compute` calls beyond :attr:`python_kernels` (kernels of other modules,
        e.g. :mod:`wbc.collision.kernels`), when a controller that computes this constraint in Python is
        built -- never in its first tick. Default: nothing."""

    def compute(self, kin: Kinematics, dt: float, rows: ConstraintRows) -> None:
        """Write this tick's bounds / rows."""
        raise NotImplementedError(f"{type(self).__name__} computes no rows")

    def add_ops(self, program: TickProgram, kin: Kinematics, rows: ConstraintRows) -> bool:
        """Register this constraint's per-tick work as compiled ops and return True, or return
        False to be computed by :meth:`compute` every tick (the default). The ops must
        compute exactly what :meth:`compute` would; a subclass that overrides ``compute`` but
        not ``add_ops`` is computed in Python (``program.ops_follow_compute``)."""
        return False

    def warm_state(self) -> Any:
        """What this data keeps from tick to tick beyond the controller's previous command (e.g. a
        history of the channels it bounds), for a copy or pickle of a running controller to compute
        its next tick exactly as this one would: a picklable value, or None (the default: nothing)."""
        return None

    def resume(self, state: Any) -> None:
        """Continue from ``state``: the :meth:`warm_state` of the same constraint's data in the
        controller that this data's controller copies (called once, after the copy is built, when
        that was not None)."""

    def row_labels(self) -> list[str]:
        """Human-readable names of the inequality rows, then of the equality rows (read when the
        diagnostics are, after a tick: rows whose meaning changes per tick name this tick's)."""
        return [f"row {i}" for i in range(self.n_inequalities + self.n_equalities)]


class Constraint(Item):
    """Base class of all constraints: a specification that :meth:`Constraint.bind` turns into
    per-controller :class:`ConstraintData` (see :class:`~wbc.item.Item`). A constraint computes
    nothing itself: its ``bind`` returns a :class:`ConstraintData` subclass of its own (a class
    that subclasses both ``Constraint`` and ``ConstraintData`` is its own data, serving the
    controllers of one robot object)."""

    #: True for the no-slip rows, which the reduced form (``reduced=True``) satisfies by construction
    satisfied_by_input_map: bool = False
    #: the default of the data's :attr:`ConstraintData.hard` (True: an actuator or no-slip limit)
    hard: bool = True

    def __init__(self, name: str | None = None) -> None:
        self.name = name or type(self).__name__

    def bind(self, robot: Robot) -> ConstraintData:
        """This constraint's data for a controller of ``robot``.

        Raises:
            InvalidInputError: the constraint says nothing about its rows (no data class of its
                own, and it is not a :class:`ConstraintData` itself).
        """
        data: ConstraintData = self.bind_as_own_data(robot, ConstraintData, "Constraint",
                                                     "return a ConstraintData subclass from its bind()")
        return data

    def __repr__(self) -> str:
        return f"{type(self).__name__}()"
