"""Collision geometry: the robot's collision shapes, obstacles, signed distances with their
gradient rows.

* :mod:`~wbc.collision.geometry` -- :class:`RobotGeometry`: the URDF's ``<collision>`` shapes and
  the robot's self-collision pairs.
* :mod:`~wbc.collision.obstacles` -- :class:`Sphere`, :class:`Box`, :class:`Capsule`,
  :class:`Plane` in the world frame, movable between ticks.
* :mod:`~wbc.collision.distances` -- :class:`Distances`: per configuration, every pair closer than
  a detection distance, its signed distance, witness points and row ``grad d(q)^T``.
* :mod:`~wbc.collision.avoidance` -- :class:`CollisionAvoidance`: the constraint of the control
  QP, a velocity damper per pair.
* :mod:`~wbc.collision.reach` -- how fast each joint velocity coordinate can move a pair's
  shape at any configuration: the first test that leaves a pair out of reach.
* :mod:`~wbc.collision.footprint` -- :class:`BaseFootprintAvoidance`: the mobile base's 2-D
  footprint kept clear of obstacle points (a laser scan) and polygons.
* :mod:`~wbc.collision.warm_up` -- every collision kernel compiled now (``wbc warmup``).

Only the compiled kernels (:mod:`~wbc.collision.kernels`) import numba, when a :class:`Distances`
is first built.
"""

from .avoidance import CollisionAvoidance, CollisionAvoidanceData
from .distances import Distances, PairBuffers
from .footprint import BaseFootprintAvoidance, BaseFootprintAvoidanceData
from .geometry import ExcludedPair, RobotGeometry
from .obstacles import Box, Capsule, Obstacle, Plane, Sphere

__all__ = ["CollisionAvoidance", "CollisionAvoidanceData", "BaseFootprintAvoidance", "BaseFootprintAvoidanceData",
           "RobotGeometry", "ExcludedPair", "Obstacle", "Sphere",
           "Box", "Capsule", "Plane", "Distances", "PairBuffers"]
