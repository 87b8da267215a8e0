"""Keep the centre of mass over a support polygon (tall arms on light bases tip over)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike, NDArray

from ..core.errors import InvalidInputError
from ..core.settings import Setting
from ..core.validation import as_gain, as_nonnegative, polygon_vertices
from ..model.kinematics import Kinematics
from ..model.robot import Robot
from ..tasks.com_task import require_mass
from .barrier import Barrier, BarrierData


class SupportPolygon(Barrier):
    """Keep the ground projection of the centre of mass ``c`` inside a convex polygon, ``margin``
    [m] from each edge: one row per edge (a :class:`~wbc.constraints.barrier.Barrier`).

    The polygon is given in the xy-plane of ``frame`` (the platform's frame for a mobile base,
    whose support moves with it; ``None`` for the world, e.g. the feet of a standing robot).
    With the frame's world placement ``(R, p)``, ``r = R^T (c - p)`` is the centre of mass in the
    frame, and edge ``i`` (outward unit normal ``n_i``, through vertex ``a_i``) gives::

        b_i(q) = n_i . a_i - margin - n_i . r_xy        >= 0

        db_i/dt = -n_i . [ R^T (J_c - J_p) v + r x (R^T J_w v) ]_xy

    (``J_c``: the centre-of-mass Jacobian, ``J_p``, ``J_w``: the frame's world-aligned linear and
    angular Jacobians), enforced as the velocity damper ``db_i/dt >= -gain b_i / dt``.

    Args:
        polygon: (N, 2) vertices [m] in the frame's xy-plane, counter-clockwise, convex, N >= 3
            (a list of pairs or an array).
        frame: the frame the polygon is fixed in (a name of the robot model), or None (world).
        margin: [m] kept from every edge (>= 0).
        gain: fraction of the margin ``b_i`` that may be consumed per tick, in (0, 1].
    """

    gain = Setting(as_gain)
    margin = Setting(as_nonnegative)

    def __init__(self, polygon: Sequence[Sequence[float]], frame: str | None = None, margin: float = 0.0,
                 gain: float = 0.5, name: str | None = None) -> None:
        super().__init__(name or (f"SupportPolygon({frame})" if frame else "SupportPolygon"))
        self.normals, self.offsets = polygon_edges(polygon)
        self.polygon = np.array(polygon, dtype=float)
        if frame is not None and not isinstance(frame, str):
            raise InvalidInputError(f"frame must be a frame name or None (the world), got {frame!r}")
        self.frame = frame
        self.margin, self.gain = margin, gain

    def bind(self, robot: Robot) -> SupportPolygonData:
        return SupportPolygonData(self, robot)

    def __repr__(self) -> str:
        return (f"SupportPolygon(polygon={self.polygon.tolist()}, frame={self.frame!r}, margin={self.margin}, "
                f"gain={self.gain})")


class SupportPolygonData(BarrierData):
    """A :class:`SupportPolygon` in one controller: the frame resolved against the robot."""

    constraint: SupportPolygon

    def __init__(self, polygon: SupportPolygon, robot: Robot) -> None:
        super().__init__(polygon, robot, polygon.normals.shape[0])
        require_mass(robot, polygon.name)
        self._frame_id = None if polygon.frame is None else robot.frame_id(polygon.frame)
        self._labels = [f"edge {i}" for i in range(self.n_inequalities)]
        self._in_frame = np.zeros((3, robot.nv))  # d r / dq

    def compute_barrier(self, kin: Kinematics, values: np.ndarray, gradients: np.ndarray) -> None:
        support = self.constraint
        com_jacobian = pin.jacobianCenterOfMass(kin.model, kin.data, False)
        com = kin.data.com[0]
        if self._frame_id is None:
            r, rate = com, com_jacobian
        else:
            placement = kin.frame_placement(self._frame_id)
            frame_jacobian = kin.frame_jacobian(self._frame_id)
            rotation_t = placement.rotation.T
            r = rotation_t @ (com - placement.translation)
            rate = self._in_frame
            np.matmul(rotation_t, com_jacobian - frame_jacobian[:3], out=rate)
            rate += np.cross(r, (rotation_t @ frame_jacobian[3:]).T).T  # r x (R^T J_w v)
        normals = support.normals
        np.subtract(support.offsets - support.margin, normals @ r[:2], out=values)
        np.matmul(-normals, rate[:2], out=gradients)

    def row_labels(self) -> list[str]:
        return self._labels


def polygon_edges(polygon: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Outward unit normals ``n_i`` (N, 2) and offsets ``n_i . a_i`` (N) of the edges of a convex,
    counter-clockwise polygon (edge i from vertex i to vertex i + 1).

    Raises:
        InvalidInputError: not an (N, 2) array of finite numbers with N >= 3, a repeated vertex,
            clockwise or not convex.
    """
    vertices = polygon_vertices(polygon, "polygon")
    edges = np.roll(vertices, -1, axis=0) - vertices
    lengths = np.linalg.norm(edges, axis=1)
    if np.any(lengths <= 0.0):
        raise InvalidInputError("polygon has a repeated vertex")
    turns = edges[:, 0] * np.roll(edges, -1, axis=0)[:, 1] - edges[:, 1] * np.roll(edges, -1, axis=0)[:, 0]
    if not np.all(turns > 0.0):
        raise InvalidInputError("polygon must be convex with its vertices counter-clockwise (seen from +z); "
                                "reverse the order of clockwise vertices")
    normals = np.column_stack([edges[:, 1], -edges[:, 0]]) / lengths[:, None]  # the edge turned clockwise
    return normals, np.einsum("ij,ij->i", normals, vertices)
