"""The shape table that the distance kernels read: one row of ``ROW`` floats per shape.

Pure Python (no numba): the obstacles write their rows, :class:`~wbc.collision.geometry.RobotGeometry`
the robot's, and :mod:`wbc.collision.kernels` reads both. Every shape is a pose in the frame of
its joint (the world, joint 0, for obstacles) and its size:

=============  ==============================================================================
kind           the shape, in its local frame
=============  ==============================================================================
``SPHERE``     the ball of ``RADIUS`` about the origin
``CAPSULE``    the points within ``RADIUS`` of the segment from ``-HALF_LENGTH`` to
               ``+HALF_LENGTH`` along local z
``BOX``        ``|x_i| <= HALF_EXTENTS[i]``
``PLANE``      the half-space below the local xy plane (z <= 0): the obstacle side of a
               :class:`~wbc.collision.obstacles.Plane`, its normal the local z axis
``COAL``       any other shape (cylinder, mesh, convex hull ...): distances by coal
=============  ==============================================================================

``BOUND_CENTER`` (local) and ``BOUND_RADIUS`` give a sphere that contains the shape: the broad
phase (a plane's radius is 0 and its centre its origin).
"""

from __future__ import annotations

#: shape kinds (0 is left unused: a row never written is refused by the kernels)
SPHERE, CAPSULE, BOX, PLANE, COAL = 1, 2, 3, 4, 5
KIND_NAMES = {SPHERE: "sphere", CAPSULE: "capsule", BOX: "box", PLANE: "plane", COAL: "coal"}

KIND = 0  #: the shape kind
JOINT = 1  #: the Pinocchio joint that carries the shape (0: the world)
ROTATION = slice(2, 11)  #: orientation in the joint frame, row-major 3x3
TRANSLATION = slice(11, 14)  #: position in the joint frame [m]
RADIUS = 14  #: sphere and capsule radius [m]
HALF_LENGTH = 15  #: half the length of a capsule's segment [m]
HALF_EXTENTS = slice(16, 19)  #: half the edge lengths of a box [m]
BOUND_RADIUS = 19  #: radius of the bounding sphere [m]
BOUND_CENTER = slice(20, 23)  #: its centre in the joint frame [m]
ROW = 23

#: columns of one entry of the pair table: the two shape rows, and the index of the pair in the
#: Pinocchio GeometryModel's collision pairs (the coal path, and the oracle of the tests)
PAIR_A, PAIR_B, PAIR_GEOMETRY = 0, 1, 2
PAIR_COLUMNS = 3

#: slots of an avoidance constraint's settings array (detection distance, min distance, gain), the
#: operand of :func:`wbc.collision.kernels.avoidance_rows`
DETECTION, MIN_DISTANCE, GAIN = 0, 1, 2

#: floats of the scratch array the kernels use (:func:`wbc.collision.kernels.box_box` needs 96)
SCRATCH = 96

#: the entries of ``BaseFootprintAvoidance._grid`` (what its tick-program op reads the points
#: through): the addresses of its point buffers (``set_points`` replaces them when a scan outgrows
#: them; a copy has its own), the point count, the cell-start count
GRID_ORDERED, GRID_CELL_START, GRID_POINTS, GRID_CELLS = range(4)
