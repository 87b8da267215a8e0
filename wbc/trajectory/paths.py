"""Cartesian paths of a pose, parameterised by s in [0, 1], and their quintic timing.

Positions follow a straight line (Lu et al., eq. 1) or a circular arc (eqs. 2-3); the
orientation follows the geodesic of SO(3) between the end rotations (the paper's
``R1 Rot(f, theta_i)``, eq. 4, with f the fixed axis of R1^T R2)::

    R(s) = R0 exp(s [phi]),   phi = log(R0^T R1)   (|phi| < pi),

so the angular velocity is omega = s' R0 phi: a fixed world axis, rate proportional to s'.
Derivatives with respect to s are 6-vectors in wbc's twist convention (linear; angular),
world-aligned at the frame origin. A :class:`TimedPath` runs a path with the rest-to-rest
quintic s(t), so pose, twist and acceleration are continuous and twist and acceleration
vanish at both ends:

    twist = x'(s) s',   acceleration = x''(s) s'^2 + x'(s) s''.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike

from ..core.errors import InvalidInputError
from ..core.validation import as_pose, as_positive, as_vector
from .quintic import Quintic

RADIUS_TOLERANCE = 1e-6  #: relative mismatch of ``|O P1|`` and ``|O P2|`` accepted for an arc


class Path(Protocol):
    """A pose path over s in [0, 1]."""

    start: np.ndarray  #: 4x4 pose at s = 0
    end: np.ndarray  #: 4x4 pose at s = 1
    length: float  #: [m] travelled by the frame origin
    angle: float  #: [rad] turned by the frame

    def pose(self, s: float) -> np.ndarray: ...

    def derivatives(self, s: float) -> tuple[np.ndarray, np.ndarray]:
        """(dx/ds, d2x/ds2): 6-vectors (linear; angular), world-aligned."""
        ...


class _Geodesic:
    """Orientation part shared by the paths: R(s) = R0 exp(s phi)."""

    def __init__(self, start: ArrayLike, end: ArrayLike) -> None:
        self.start = as_pose(start, "start pose").copy()
        self.end = as_pose(end, "end pose").copy()
        self._phi = pin.log3(self.start[:3, :3].T @ self.end[:3, :3])
        self.angle = float(np.linalg.norm(self._phi))
        self._omega = self.start[:3, :3] @ self._phi  # world axis times angle

    def rotation(self, s: float) -> np.ndarray:
        return self.start[:3, :3] @ pin.exp3(s * self._phi)


class LinePath(_Geodesic):
    """Straight line p(s) = p0 + s (p1 - p0) with geodesic orientation (eq. 1)."""

    def __init__(self, start: ArrayLike, end: ArrayLike) -> None:
        super().__init__(start, end)
        self._delta = self.end[:3, 3] - self.start[:3, 3]
        self.length = float(np.linalg.norm(self._delta))
        if self.length == 0.0 and self.angle == 0.0:
            raise InvalidInputError("a line needs distinct start and end poses")

    def pose(self, s: float) -> np.ndarray:
        pose = np.eye(4)
        pose[:3, :3] = self.rotation(s)
        pose[:3, 3] = self.start[:3, 3] + s * self._delta
        return pose

    def derivatives(self, s: float) -> tuple[np.ndarray, np.ndarray]:
        return np.r_[self._delta, self._omega], np.zeros(6)


class ArcPath(_Geodesic):
    """Circular arc about ``centre`` from the start to the end position (eqs. 2-3).

    With u0 = p_start - O, u1 = p_end - O (equal lengths r), theta = angle(u0, u1) in
    (0, pi) and ``n = u0 x u1 / |u0 x u1|``::

        p(s) = O + Rot(n, s theta) u0 = O + [sin((1 - s) theta) u0 + sin(s theta) u1] / sin theta,

    the second form being the paper's eq. 2. Then dp/ds = theta n x (p - O) and
    d2p/ds2 = -theta^2 (p - O). Arcs of pi or more are not representable (n is undefined).
    """

    def __init__(self, start: ArrayLike, end: ArrayLike, centre: ArrayLike) -> None:
        super().__init__(start, end)
        self.centre = as_vector(centre, 3, "centre").copy()
        u0, u1 = self.start[:3, 3] - self.centre, self.end[:3, 3] - self.centre
        self.radius = float(np.linalg.norm(u0))
        if self.radius == 0.0 or abs(np.linalg.norm(u1) - self.radius) > RADIUS_TOLERANCE * self.radius:
            raise InvalidInputError(f"arc: start and end must be equally far from the centre and not on it "
                                    f"(|u0| = {self.radius:.6g}, |u1| = {np.linalg.norm(u1):.6g} m)")
        normal = np.cross(u0, u1)
        sine = np.linalg.norm(normal) / self.radius**2
        if sine < 1e-9:
            raise InvalidInputError("arc: start and end must not be collinear with the centre (angle 0 or pi)")
        self.normal = normal / np.linalg.norm(normal)
        self.sweep = float(np.arctan2(sine, u0 @ u1 / self.radius**2))
        self.length = self.radius * self.sweep
        self._u0 = u0

    def pose(self, s: float) -> np.ndarray:
        pose = np.eye(4)
        pose[:3, :3] = self.rotation(s)
        pose[:3, 3] = self.centre + pin.exp3(s * self.sweep * self.normal) @ self._u0
        return pose

    def derivatives(self, s: float) -> tuple[np.ndarray, np.ndarray]:
        radial = pin.exp3(s * self.sweep * self.normal) @ self._u0
        first = np.r_[self.sweep * np.cross(self.normal, radial), self._omega]
        second = np.r_[-self.sweep**2 * radial, np.zeros(3)]
        return first, second


class TimedPath:
    """A path run by the rest-to-rest quintic s(t) over ``duration`` [s]; a reference
    ``(pose, twist) = timed(t)`` (held at the end pose for t > duration)."""

    def __init__(self, path: Path, duration: float) -> None:
        self.path = path
        self.duration = as_positive(duration, "duration")
        self.timing = Quintic.rest_to_rest(0.0, 1.0, self.duration)

    def state(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Pose (4x4), twist (6) and acceleration (6: linear; angular) at time ``t``."""
        s, rate, acceleration = (float(x) for x in self.timing(t))  # (0-d arrays: a scalar quintic)
        first, second = self.path.derivatives(s)
        return self.path.pose(s), first * rate, second * rate**2 + first * acceleration

    def __call__(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        pose, twist, _ = self.state(t)
        return pose, twist


class SubPath:
    """The part s in [s0, s1] of ``path``, re-parameterised by sigma in [0, 1]:
    s = s0 + sigma (s1 - s0), so dx/dsigma = (s1 - s0) dx/ds and d2x/dsigma2 = (s1 - s0)^2 d2x/ds2."""

    def __init__(self, path: Path, s0: float, s1: float) -> None:
        if not 0.0 <= s0 < s1 <= 1.0:
            raise InvalidInputError(f"a sub-path needs 0 <= s0 < s1 <= 1, got [{s0}, {s1}]")
        self.path, self.s0, self.span = path, float(s0), float(s1 - s0)
        self.start, self.end = path.pose(s0), path.pose(s1)
        self.length, self.angle = path.length * self.span, path.angle * self.span

    def pose(self, s: float) -> np.ndarray:
        return self.path.pose(self.s0 + s * self.span)

    def derivatives(self, s: float) -> tuple[np.ndarray, np.ndarray]:
        first, second = self.path.derivatives(self.s0 + s * self.span)
        return first * self.span, second * self.span**2
