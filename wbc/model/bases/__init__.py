"""The kinds of base, one module each, behind one interface (:class:`MobileBase`).

* :mod:`~wbc.model.bases.interface` -- :class:`MobileBase`, what every kind supplies;
* :mod:`~wbc.model.bases.fixed` -- bolted to the world;
* :mod:`~wbc.model.bases.planar` -- holonomic ``(x, y, heading)``, and the math planar kinds share;
* :mod:`~wbc.model.bases.mecanum` -- holonomic on four Swedish wheels;
* :mod:`~wbc.model.bases.unicycle` -- differential drive (no lateral slip);
* :mod:`~wbc.model.bases.synchro` -- synchro drive;
* :mod:`~wbc.model.bases.floating` -- a free-flyer root joint (SE(3)).
"""

from .fixed import FIXED_BASE, FixedBase
from .floating import FloatingBase
from .interface import NO_ROWS, BaseKind, MobileBase, TwistRows, Wheels
from .mecanum import MecanumBase, MecanumWheels
from .planar import PlanarBase
from .synchro import SynchroBase
from .unicycle import DifferentialWheels, UnicycleBase

__all__ = ["MobileBase", "BaseKind", "TwistRows", "Wheels", "NO_ROWS", "FixedBase", "FIXED_BASE", "PlanarBase",
           "MecanumBase", "MecanumWheels", "UnicycleBase", "DifferentialWheels", "SynchroBase",
           "FloatingBase"]
