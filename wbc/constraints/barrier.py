"""The front door for a new constraint that keeps functions of the configuration non-negative.

A subclass of :class:`Barrier` (the specification: gain, its own settings) and of
:class:`BarrierData` (one controller's data) writes, each tick, the values ``b(q)`` (n) of its
barrier functions and their gradients ``grad b`` (n x nv, ``db/dt = grad b . v``)
(:meth:`BarrierData.compute_barrier`). The generic :meth:`BarrierData.compute` then writes
the velocity-damper rows, the same way for every such constraint::

    grad b . v  >=  -gain b / dt          written as      -grad b . v  <=  gain b / dt

To first order the margin then shrinks by at most the fraction ``gain`` per tick,
``b(q+) >= (1 - gain) b(q)``, never changing sign; from ``b < 0`` the rows pull back at the
same rate. ``v = 0`` satisfies them whenever ``b >= 0``. Examples: the manipulability barrier
(``b = m - m_min``), a distance kept above a margin (``b = d - d_min``).
"""

from __future__ import annotations

import numpy as np

from ..model.kinematics import Kinematics
from ..model.robot import Robot
from .constraint import Constraint, ConstraintData, ConstraintRows


class Barrier(Constraint):
    """A constraint given by barrier functions ``b(q) >= 0`` (subclass it with a :class:`BarrierData`).

    The subclass declares ``gain`` (the fraction of the margin ``b`` that may be consumed per
    tick, in (0, 1]; a validated setting) and returns its data from :meth:`bind`. Barriers are
    soft by default (``hard = False``): they yield to the actuator limits in the controller's
    fallback solve.
    """

    gain: float
    hard = False

    def bind(self, robot: Robot) -> BarrierData:
        raise NotImplementedError(f"{type(self).__name__}.bind must return its BarrierData")


class BarrierData(ConstraintData):
    """A :class:`Barrier` in one controller: ``n_inequalities`` barrier functions, their values
    and gradients at the last tick, and the generic damper rows (:meth:`compute`)."""

    constraint: Barrier

    def __init__(self, barrier: Barrier, robot: Robot, n: int) -> None:
        super().__init__(barrier)
        self.n_inequalities = n
        self.barrier = np.full(n, np.nan)  #: b(q) at the last tick
        self.gradient = np.zeros((n, robot.nv))  #: grad b at the last tick

    def compute_barrier(self, kin: Kinematics, values: np.ndarray, gradients: np.ndarray) -> None:
        """Write this tick's ``b(q)`` into ``values`` (n) and ``grad b`` into ``gradients``
        (n x nv, C-contiguous): ``db/dt = gradients @ v``."""
        raise NotImplementedError(f"{type(self).__name__} must implement compute_barrier")

    def compute(self, kin: Kinematics, dt: float, rows: ConstraintRows) -> None:
        """``G = -grad b``, ``h = gain b / dt``, from :meth:`compute_barrier`."""
        self.compute_barrier(kin, self.barrier, self.gradient)
        np.negative(self.gradient, out=rows.G)
        np.multiply(self.barrier, self.constraint.gain / dt, out=rows.h)
