"""Mobile-base descriptions: which coordinates form the base and how it moves (the public
names; each kind is a module of :mod:`wbc.model.bases`).

Conventions (used everywhere in wbc):

* The base pose is ``(x, y, heading)`` in the world frame: ``x, y`` [m] position of the
  base reference point, ``heading`` [rad] from the world x axis to the base x axis,
  counter-clockwise seen from above (+z). For a synchro drive the heading is the
  common steering angle of the wheels (the chassis itself does not turn).
* A planar base twist ``(v_x, v_y, omega)`` is given in the **base frame**:
  ``v_x`` forward, ``v_y`` to the left [m/s], ``omega`` heading rate [rad/s].
  With ``R(heading)`` the 2-D rotation, world rates are ``(xdot, ydot) = R (v_x, v_y)``.
* Nonholonomic bases (unicycle / differential drive, synchro drive) cannot slip
  sideways: ``v_y = -sin(heading) xdot + cos(heading) ydot = 0``. Their real inputs are
  ``(v, omega)`` = (forward speed [m/s], heading rate [rad/s]).
* A floating base (a free-flyer root joint) has the pose ``(p, quaternion (x, y, z, w))`` in
  ``q`` and the base-frame twist ``(v, omega)`` in ``v`` (:mod:`wbc.model.bases.floating`).
* Wheel speeds are wheel angular rates [rad/s], positive when the wheel rolls the base
  forward (+x of the base frame).
"""

from __future__ import annotations

from .bases import (
    FIXED_BASE,
    BaseKind,
    DifferentialWheels,
    FixedBase,
    FloatingBase,
    MecanumBase,
    MecanumWheels,
    MobileBase,
    PlanarBase,
    SynchroBase,
    TwistRows,
    UnicycleBase,
)

__all__ = ["MobileBase", "BaseKind", "MecanumWheels", "DifferentialWheels", "FIXED_BASE", "TwistRows", "FixedBase",
           "PlanarBase", "MecanumBase", "UnicycleBase", "SynchroBase", "FloatingBase"]
