"""Collision geometry: the robot's collision shapes, obstacles, signed distances with their
gradient rows.

* :mod:`~wbc.collision.geometry` -- :class:`RobotGeometry`: the URDF's ``<collision>`` shapes and
  the robot's self-collision pairs.
* :mod:`~wbc.collision.obstacles` -- :class:`Sphere`, :class:`Box`, :class:`Capsule`,
  :class:`Plane` in the world frame, movable between ticks.
* :mod:`~wbc.collision.distances` -- :class:`Distances`: per configuration, every pair closer than
  a detection distance, its signed distance, witness points and row ``grad d(q)^T``.

Only the compiled kernels (:mod:`~wbc.collision.kernels`) import numba, when a :class:`Distances`
is first built.
"""

from .distances import Distances, PairBuffers
from .geometry import ExcludedPair, RobotGeometry
from .obstacles import Box, Capsule, Obstacle, Plane, Sphere

__all__ = ["RobotGeometry", "ExcludedPair", "Obstacle", "Sphere", "Box", "Capsule", "Plane", "Distances",
           "PairBuffers"]
