"""The context of one control tick, which the items that ask for it read (issue 23 §3).

A controller owns one :class:`TickContext` and keeps it current: at the start of each
:meth:`wbc.Controller.step` it holds this tick's kinematics and control period, the command of
the previous tick and the measured joint velocity given to ``step`` (if any). A task's or
constraint's data asks for it by defining ``use_context(context)``: the controller calls it once,
when it binds the item, and the data reads the context in its ``compute`` from then on (e.g.
acceleration limits bound ``|v - previous| <= a_max dt``).
"""

from __future__ import annotations

from typing import Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.validation import as_vector
from .kinematics import Kinematics


class Braking(Protocol):
    """What the hard acceleration bounds of a controller can deliver (registered in the context
    by :class:`~wbc.AccelerationLimits`' data when it is bound)."""

    def decelerations(self, gradients: NDArray[np.float64], q: NDArray[np.float64],
                      out: NDArray[np.float64]) -> None:
        """``out[i]`` <= the largest rate of change of ``gradients[i] . v`` [unit/s^2] that the
        acceleration bounds allow in either direction at configuration ``q`` (a lower bound)."""


class TickContext:
    """What a tick knows besides the configuration (read-only for the items).

    * ``kinematics`` -- this tick's :class:`~wbc.model.kinematics.Kinematics` (frames, Jacobians);
    * ``dt`` -- the control period [s] (the controller's, kept in step with it);
    * ``previous`` -- the command ``v`` of the previous tick, as ``step`` returned it (None
      before the first tick; wbc never writes that array again);
    * ``measured`` -- the measured joint velocity ``v_measured`` given to this tick's ``step``
      [unit/s], size ``nv`` (None when not given);
    * ``braking`` -- the controller's acceleration bounds as a :class:`Braking` (None without
      them), set when the items are bound: rows that must brake in time (collision dampers) read it;
    * ``speed_bound`` -- ``|v_k| <= speed_bound[k]`` [unit/s] for every command the controller
      returns (``inf``: no such bound), what its hard constraints imply at every tick
      (:meth:`~wbc.constraints.constraint.ConstraintData.bound_speed`: the speed limits, frozen
      joints), set when the controller is built: rows that no command within it can violate
      are left out (collision pairs too far to be reached within one tick).
    """

    __slots__ = ("kinematics", "dt", "previous", "measured", "braking", "speed_bound", "_measured")

    def __init__(self, kinematics: Kinematics, dt: float) -> None:
        self.kinematics, self.dt = kinematics, dt
        self.previous: NDArray[np.float64] | None = None
        self.measured: NDArray[np.float64] | None = None
        self.braking: Braking | None = None
        self.speed_bound = np.full(kinematics.robot.nv, np.inf)  # (written in place: readers keep the array)
        self._measured = np.zeros(kinematics.robot.nv)  # where a measured velocity is copied to

    def measure(self, v_measured: ArrayLike) -> NDArray[np.float64]:
        """``v_measured`` checked and copied into the context's own array (returned; the caller
        sets ``measured`` to it).

        Raises:
            InvalidInputError: ``v_measured`` is not a finite vector of size ``nv``.
        """
        self._measured[:] = as_vector(v_measured, self._measured.size, "v_measured")
        return self._measured
