"""What a kind of base supplies: :class:`MobileBase`, the interface behind ``robot.base``.

A base kind owns its coordinates and everything that depends on how it moves, so the robot,
the constraints and the controller ask the base instead of switching on its kind:

* its **coordinates** -- ``indices`` of ``(x, y, heading)`` in ``v`` (and ``q``: 1-DOF root
  joints), their position and speed limits (:meth:`MobileBase.limit_coordinates`);
* its **twist** ``(v_x, v_y, omega)`` in the base frame (:meth:`MobileBase.twist`);
* its **rows**, given on that twist: the speed rows ``M t <= b``
  (:meth:`MobileBase.speed_rows`, written by :class:`wbc.JointVelocityLimits`), the no-slip rows
  ``N t = 0`` (:meth:`MobileBase.no_slip_rows`, :class:`wbc.NonholonomicBase`) and the wheel
  map ``u = H0 t`` (``wheels``, :class:`wbc.WheelSpeedLimits`);
* its **inputs** ``v = S(q) u`` (:meth:`MobileBase.allocate_input_map`,
  :meth:`MobileBase.write_input_map`) and how its coordinates **integrate**
  (:meth:`MobileBase.integrate`).

Each shipped kind is one module of :mod:`wbc.model.bases`; docs/extending.md ("A new base
kind") writes a new one.
"""

from __future__ import annotations

import abc
import enum
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, ClassVar, Protocol

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray


class BaseKind(enum.Enum):
    """How the base of a robot moves."""

    FIXED = "fixed"  #: bolted to the world
    PLANAR = "planar"  #: holonomic (x, y, heading) without a wheel model
    MECANUM = "mecanum"  #: holonomic, four 45-degree Swedish wheels
    UNICYCLE = "unicycle"  #: differential drive: no lateral slip, the chassis turns with the heading
    SYNCHRO = "synchro"  #: synchro drive: no lateral slip, wheels steer together, chassis does not turn
    FLOATING = "floating"  #: a free-flyer root joint: SE(3) pose, base-frame twist (humanoids, legged robots)
    CUSTOM = "custom"  #: a kind defined outside wbc (its class names it: ``base.name``)

    @property
    def is_mobile(self) -> bool:
        """Whether the base drives on the ground plane on ``(x, y, heading)`` coordinates."""
        return self not in (BaseKind.FIXED, BaseKind.FLOATING)

    @property
    def is_nonholonomic(self) -> bool:
        return self in (BaseKind.UNICYCLE, BaseKind.SYNCHRO)


class Wheels(Protocol):
    """A wheel model: its wheel speeds ``u = H0 (v_x, v_y, omega)`` [rad/s] and their limit."""

    @property
    def max_speed(self) -> float:
        """``|u_i|`` limit [rad/s] (inf: none declared)."""
        ...

    def inverse_matrix(self) -> NDArray[np.float64]:
        """``H0`` (wheels x 3): base-frame twist -> wheel speeds."""
        ...


class TwistRows:
    """Rows on the base-frame twist ``t = (v_x, v_y, omega)``: ``matrix @ t`` against ``bound``
    (``<=`` for speed rows, ``= 0`` for no-slip rows), one label each."""

    def __init__(self, matrix: Any, bound: Any, labels: tuple[str, ...]) -> None:
        self.matrix: NDArray[np.float64] = np.array(matrix, dtype=np.float64).reshape(-1, 3)
        self.bound: NDArray[np.float64] = np.broadcast_to(np.asarray(bound, dtype=np.float64),
                                                          (self.matrix.shape[0],)).copy()
        self.labels = tuple(labels)
        if len(self.labels) != self.matrix.shape[0]:
            raise ValueError(f"{len(self.labels)} labels for {self.matrix.shape[0]} twist rows")

    @property
    def count(self) -> int:
        return self.matrix.shape[0]


NO_ROWS = TwistRows(np.zeros((0, 3)), 0.0, ())

#: [m] how far a wheel may sit from where its wheel model puts it (symmetry, axle on the origin)
LAYOUT_TOLERANCE = 1e-6


@dataclass(frozen=True)
class WheelMount:
    """A driven wheel as the model places it (read by :func:`wbc.model.declared_base.declare_base`)."""

    name: str  #: its joint
    position: NDArray[np.float64]  #: centre in the base frame [m]
    axis: NDArray[np.float64]  #: unit rotation axis in the base frame
    radius: float  #: [m]
    max_speed: float  #: [rad/s] (inf: none in the URDF)


@dataclass(frozen=True)
class MobileBase(abc.ABC):
    """The base of a robot (``robot.base``): one subclass per kind (:mod:`wbc.model.bases`).

    ``indices`` are the positions of ``(x, y, heading)`` in the velocity vector ``v``
    (and in ``q``; wbc requires the base coordinates to be 1-DOF joints).
    ``max_linear_speed`` [m/s] bounds the base-frame components ``|v_x|, |v_y|``,
    ``max_yaw_rate`` [rad/s] bounds ``|omega|``.

    ``MobileBase(kind, ...)`` builds the shipped class of ``kind`` (``MobileBase(BaseKind.MECANUM,
    wheels=...)`` is a :class:`~wbc.model.bases.mecanum.MecanumBase`).
    """

    kind: BaseKind
    indices: tuple[int, int, int] = (0, 1, 2)
    max_linear_speed: float = np.inf
    max_yaw_rate: float = np.inf
    wheels: Wheels | None = None

    #: whether the base drives on the ground plane on ``(x, y, heading)`` coordinates (False: bolted
    #: to the world, or floating: its free-flyer coordinates are read like joint rates)
    is_mobile: ClassVar[bool] = True
    #: driven wheels the kind's wheel model describes (:meth:`MobileBase.wheels_from_mounts`; 0: none)
    wheel_count: ClassVar[int] = 0
    _shipped: ClassVar[dict[BaseKind, type[MobileBase]]] = {}  #: the class of each shipped kind

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        kind = vars(cls).get("kind")  # the kind's default: the kind the class is
        if isinstance(kind, BaseKind) and kind is not BaseKind.CUSTOM and cls.__module__.startswith("wbc.model."):
            MobileBase._shipped.setdefault(kind, cls)

    def __new__(cls, *args: Any, **kwargs: Any) -> MobileBase:
        if cls is MobileBase:  # the constructor by kind: the kind's class
            kind = kwargs.get("kind", args[0] if args else None)
            if kind not in MobileBase._shipped:
                raise TypeError(f"MobileBase(kind, ...): kind must be a shipped BaseKind, got {kind!r}")
            cls = kind_class(kind)
        return super().__new__(cls)

    def __post_init__(self) -> None:
        kind = getattr(type(self), "kind", None)  # the field's default: the kind the class is
        if self.kind is not kind:
            raise TypeError(f"{type(self).__name__} is a {kind} base, not {self.kind}")

    @classmethod
    def wheels_from_mounts(cls, mounts: list[WheelMount], radius: float, max_speed: float, where: str) -> Wheels:
        """The kind's wheel model from its :attr:`wheel_count` driven wheels as mounted (any order).

        Raises:
            ModelError: a layout the wheel model does not describe (naming ``where``).
        """
        raise NotImplementedError(f"a {cls.__name__} has no wheel model")

    @property
    def name(self) -> str:
        """The kind's name in messages (``"mecanum"``, ...)."""
        return str(self.kind.value)

    @property
    def is_nonholonomic(self) -> bool:
        """Whether the base's velocity obeys no-slip rows (fewer inputs than coordinates)."""
        return self.no_slip_rows().count > 0

    @property
    def velocity_coordinates(self) -> tuple[int, ...]:
        """The base's coordinates in ``v`` (what whole-robot joint defaults such as
        :class:`wbc.PostureTask` leave out): ``indices`` for a ground base, none when fixed."""
        return tuple(self.indices) if self.is_mobile else ()

    # ------------------------------------------------------------ coordinates
    @abc.abstractmethod
    def limit_coordinates(self, lower: NDArray[np.float64], upper: NDArray[np.float64],
                          velocity_limit: NDArray[np.float64]) -> None:
        """Write the base coordinates' position limits and speed bounds into the robot's
        vectors (in place; the base-frame speed rows are :meth:`speed_rows`)."""

    @abc.abstractmethod
    def twist(self, q: NDArray[np.float64], v: NDArray[np.float64]) -> NDArray[np.float64]:
        """Base-frame twist ``(v_x, v_y, omega)`` of ``v`` at ``q``; rows of ``(T, n)`` arrays
        give a ``(T, 3)`` array. Inputs are not validated (see :meth:`Robot.base_twist`)."""

    # ------------------------------------------------------------------- rows
    def speed_rows(self) -> TwistRows:
        """Base-frame speed rows ``M t <= b`` (none by default)."""
        return NO_ROWS

    def no_slip_rows(self) -> TwistRows:
        """No-slip rows ``N t = 0`` (none: a holonomic base)."""
        return NO_ROWS

    # ----------------------------------------------------------------- inputs
    def allocate_input_map(self, nv: int) -> NDArray[np.float64]:
        """``S`` (nv x nu) at heading 0: its entries that do not depend on ``q``. Identity: the
        inputs are ``v`` itself."""
        return np.eye(nv)

    def write_input_map(self, q: NDArray[np.float64] | Sequence[float], S: NDArray[np.float64]) -> None:
        """Write the entries of ``S(q)`` that depend on ``q`` (called every tick)."""
        return None  # S = I: nothing depends on q

    def integrate(self, model: pin.Model, q: NDArray[np.float64], v: NDArray[np.float64],
                  dt: float) -> NDArray[np.float64]:
        """``q`` after moving at ``v`` for ``dt`` [s]: each joint integrates its own coordinates
        (``pinocchio.integrate``; the base joints: ``x += xdot dt``, ...)."""
        return pin.integrate(model, q, v * dt)


def kind_class(kind: BaseKind) -> type[MobileBase]:
    """The class of a shipped kind (what ``MobileBase(kind, ...)`` builds)."""
    return MobileBase._shipped[kind]


__all__ = ["BaseKind", "MobileBase", "TwistRows", "Wheels", "WheelMount", "NO_ROWS", "LAYOUT_TOLERANCE", "kind_class"]
