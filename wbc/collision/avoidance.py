"""Collision avoidance as a constraint of the control QP: a velocity damper on every pair of
shapes closer than a detection distance."""

from __future__ import annotations

import functools
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from ..constraints.constraint import Constraint, ConstraintData, ConstraintRows
from ..core.errors import InvalidInputError
from ..core.settings import Operand
from ..core.validation import as_flag, as_gain, as_items, as_nonnegative, as_positive
from ..model.kinematics import Kinematics, fill_kinematics
from ..model.robot import Robot
from ..model.tick_context import TickContext
from ..runtime.native_entry import fits_signature, unchecked_entry
from .braking import RowBraking
from .distances import Distances, PairBuffers, compiled_pairs_only
from .geometry import RobotGeometry
from .layout import DETECTION, GAIN, MIN_DISTANCE, PAIR_COLUMNS, ROW, SCRATCH
from .obstacles import Obstacle

if TYPE_CHECKING:  # pragma: no cover
    from ..runtime.compiled_op import CompiledOp
    from ..runtime.program import TickProgram

#: [m/s] a capsule end gets no row (:func:`wbc.collision.kernels.corner_rows`) when its distance exceeds
#: the pair's by more than ``CORNER_SPEED * dt`` (overtaking the witness within one tick would take a
#: relative normal speed of the two points above this, far beyond a manipulator's) or when its damper
#: allows approaching faster than this (the row would never bind); where the controller bounds the
#: joint speeds (``TickContext.speed_bound``) a pair uses twice its reach instead when that is less
#: (the bound on its points' relative speed, :func:`wbc.collision.kernels._pair_reach`: both criteria sure)
CORNER_SPEED = 5.0
#: rows for corners (capsule ends and box vertices and edges that tie with a pair's witness) beyond the pairs'
#: own, the closest pairs' first: measured 3.8 on average and at most 7 per tick on the youBot with
#: self-collision and 10 obstacles (benchmarks/collision.py), 5.1 and 8 on youbot_obstacle (at the budget on
#: 3 % of its ticks, its margin kept to 0.01 mm) -- with the speed of CORNER_SPEED; with the pairs' reach (joint
#: speed bounds) 0.8 on average on the benchmark; every row costs DAQP time even inert. With the box features
#: (session 32) youbot_obstacle's closed loop has 2.9 on average, at most 5 (2.5 and 5 before)
CORNER_ROWS = 8
#: ``h`` of an unused row (its ``G`` row is zero): ``0 <= 1`` holds for every v and is never active (the
#: value of ``wbc.collision.kernels.INERT``, which imports numba)
INERT = 1.0


class DistanceMargins:
    """The settings ``min_distance`` [m] >= 0 and ``detection_distance`` [m] > ``min_distance`` of an
    avoidance constraint, validated together (set both first with :meth:`_set_margins`), kept in
    :attr:`_settings` = (detection_distance, min_distance, gain): the operand the kernels read, so
    a tick copies nothing (``gain``: the subclass's :class:`~wbc.core.settings.Operand` of slot 2)."""

    _settings: NDArray[np.float64]

    def _set_margins(self, min_distance: float, detection_distance: float) -> None:
        min_distance = as_nonnegative(min_distance, "min_distance")
        detection_distance = as_positive(detection_distance, "detection_distance")
        _check_margins(min_distance, detection_distance)
        self._settings = np.array([detection_distance, min_distance, 0.0])

    @property
    def min_distance(self) -> float:
        """[m] the distance kept; below :attr:`detection_distance`."""
        return float(self._settings[MIN_DISTANCE])

    @min_distance.setter
    def min_distance(self, value: float) -> None:
        value = as_nonnegative(value, "min_distance")
        _check_margins(value, self.detection_distance)
        self._settings[MIN_DISTANCE] = value

    @property
    def detection_distance(self) -> float:
        """[m] what is farther gets no row; above :attr:`min_distance`."""
        return float(self._settings[DETECTION])

    @detection_distance.setter
    def detection_distance(self, value: float) -> None:
        value = as_positive(value, "detection_distance")
        _check_margins(self.min_distance, value)
        self._settings[DETECTION] = value


class CollisionAvoidance(DistanceMargins, Constraint):
    """Keep every pair of collision shapes at least ``min_distance`` apart: the robot's own
    shapes (``self_collision``) and the robot against ``obstacles`` (world frame, movable
    between ticks). One inequality row per pair closer than ``detection_distance``, the
    velocity damper on the signed distance d of the pair (witness points ``w_a``, ``w_b``,
    unit normal n from a to b)::

        d_dot = n . (J_b(w_b) - J_a(w_a)) v  >=  -gain (d - min_distance) / dt

    With Euler integration, to first order ``d+ - min_distance >= (1 - gain)(d - min_distance)``:
    the margin shrinks at most geometrically and never changes sign, so d never drops below
    ``min_distance`` (up to the second-order term, ``O(dt^2 |v|^2)`` per tick, as for
    :class:`~wbc.ManipulabilityBarrier`). A robot that starts closer than ``min_distance`` (or
    in contact, d < 0) gets ``d_dot >= gain (min_distance - d) / dt > 0``: it is pushed out at
    that rate, never frozen. The rows are soft (``hard = False``): they yield to the actuator
    limits in the controller's elastic fallback when both cannot hold.

    **Corners.** Where a capsule lies parallel to the other shape's face or edge, or along another
    capsule, its closest point ties between points far apart: d is the minimum of smooth pieces
    (the ends' spheres' distances and the inside's) and one witness row is not its first-order
    model: the QP turns the witness away while an end approaches, the witness jumps, the command
    reverses, and a full-speed two-tick chatter creeps into the margin. So each capsule end that is
    not the witness gets a damper of its own (against a box, so does the point where the capsule
    overhangs the witness's face or edge), if within :data:`CORNER_SPEED` ``* dt`` of d
    (:func:`~wbc.collision.kernels.corner_rows` derives it: with the witness row, the first-order
    model of d at the tie). With :class:`~wbc.AccelerationLimits` in the stack every
    row also brakes in time (:class:`~wbc.collision.braking.RowBraking`).

    **Reach.** A pair whose damper no command can bind gets no row: the bounds on each ``|v_k|``
    that the controller's hard constraints imply at every tick (:class:`~wbc.JointVelocityLimits`,
    its base rows too, :class:`~wbc.DofFreezing`: ``TickContext.speed_bound``) bound ``|d_dot|``
    by ``sum_k speed_k (|v_O,k + w_k x c| + |w_k| r)`` over the coordinates that move only one of
    the two shapes (those that move both move them together and leave d alone; ``c``, ``r``: the
    moving shape's bounding sphere), and a pair whose lower bound of d gives
    ``gain (d - min_distance) / dt`` above that sum is left out before its distance is measured
    (:func:`~wbc.collision.kernels._out_of_reach`; first against a bound of that sum over every
    configuration, formed once per pair from the chain's lengths,
    :func:`~wbc.collision.reach.lever_bounds`: one comparison decides most pairs, applied to the
    bounding spheres before any other bound, :func:`~wbc.collision.kernels._cutoff`). Its row would
    hold for every command the controller returns, so nothing changes but the work (and
    :attr:`CollisionAvoidanceData.pairs`, which lists only the pairs within reach). A coordinate
    without such a bound never lets a pair it moves be left out; with
    :class:`~wbc.AccelerationLimits` (rows that brake) nothing is.

    **Rows.** The QP has a fixed number of rows, ``n_inequalities`` of its data
    = ``capacity`` + :data:`CORNER_ROWS` (``capacity`` default: every candidate pair, so no pair
    within ``detection_distance`` is ever left out); each tick the pairs within
    ``detection_distance`` fill the first rows, their corner rows the next (at most
    :data:`CORNER_ROWS`, the closest pairs' first), and the others
    are inert (``G`` row 0, ``h`` = :data:`INERT`): the row count never changes and nothing is
    allocated. With a smaller ``capacity``, the closest pairs get the rows.

    Args:
        obstacles: :class:`~wbc.Sphere`, :class:`~wbc.Box`, :class:`~wbc.Capsule`,
            :class:`~wbc.Plane` objects; move them between ticks with their setters.
        self_collision: also keep the robot's own non-adjacent links apart
            (:class:`~wbc.collision.RobotGeometry`: adjacent and always-touching pairs excluded).
        min_distance: [m] >= 0, the distance the pairs keep.
        detection_distance: [m] > ``min_distance``: pairs farther apart get no row (a bounding-
            sphere broad phase skips them at ~10 flops each).
        gain: fraction (0, 1] of the margin ``d - min_distance`` that one tick may consume.
        capacity: rows of the constraint (None: one per candidate pair).
        srdf: an SRDF whose ``<disable_collisions>`` pairs are excluded too.

    Raises:
        InvalidInputError: an argument out of range (named), ``min_distance`` not below
            ``detection_distance``, obstacles that are not obstacles.
        ModelError: when a controller is built, a robot whose URDF has no ``<collision>``
            elements (the message says how to add them).
    """

    gain = Operand("_settings", GAIN, as_gain)
    hard = False  # yields to the actuator limits: elastic in the controller's fallback solve

    def __init__(self, obstacles: Sequence[Obstacle] = (), self_collision: bool = True, min_distance: float = 0.02,
                 detection_distance: float = 0.3, gain: float = 0.5, capacity: int | None = None,
                 srdf: str | Path | None = None, name: str | None = None) -> None:
        super().__init__(name)
        self.obstacles = as_items(list(obstacles) if isinstance(obstacles, tuple) else obstacles, Obstacle,
                                  "obstacles")
        self.self_collision = as_flag(self_collision, "self_collision")
        self._set_margins(min_distance, detection_distance)
        self.gain = gain
        if capacity is not None and (isinstance(capacity, bool) or not isinstance(capacity, int) or capacity < 1):
            raise InvalidInputError(f"capacity must be None or an int >= 1, got {capacity!r}")
        self.capacity = capacity
        self.srdf = srdf

    def bind(self, robot: Robot) -> CollisionAvoidanceData:
        return CollisionAvoidanceData(self, robot)

    def __repr__(self) -> str:
        return (f"CollisionAvoidance(obstacles={self.obstacles!r}, self_collision={self.self_collision}, "
                f"min_distance={self.min_distance}, detection_distance={self.detection_distance}, gain={self.gain})")


def _check_margins(min_distance: float, detection_distance: float) -> None:
    if not min_distance < detection_distance:
        raise InvalidInputError(f"min_distance ({min_distance} m) must be below detection_distance "
                                f"({detection_distance} m): an obstacle must get its row before it reaches the margin")


class CollisionAvoidanceData(ConstraintData):
    """:class:`CollisionAvoidance` in one controller: the robot's shapes and the obstacles'
    (:class:`~wbc.collision.Distances`) and this tick's pairs (:attr:`pairs`)."""

    constraint: CollisionAvoidance

    def __init__(self, avoidance: CollisionAvoidance, robot: Robot) -> None:
        super().__init__(avoidance)
        geometry = RobotGeometry(robot, srdf=avoidance.srdf)
        self.distances = Distances(robot, avoidance.obstacles, avoidance.self_collision,
                                   avoidance.detection_distance, avoidance.capacity, geometry, prepare=False)
        capacity = self.distances.capacity
        #: rows: one per pair, then :data:`CORNER_ROWS` (at most ``capacity``) for the corners that tie
        #: with a pair's witness
        self.n_inequalities = capacity + min(capacity, CORNER_ROWS)
        #: the pair entry of each corner row of the last tick (entries ``0 .. corners - 1``)
        self.corner_pair = np.zeros(min(capacity, CORNER_ROWS), dtype=np.int64)
        #: (pairs.count, corners) of the last tick: written by the kernels that write the rows (the tick
        #: program's op, or :meth:`compute`), which rewrite the rows after a tick's only up to the last's
        self._counts = np.zeros(2, dtype=np.int64)
        self._braking = RowBraking(self.n_inequalities)  # with acceleration bounds in the stack
        self._pairs: PairBuffers = self.distances.buffers()
        #: (dt, CORNER_SPEED) of the kernel; dt copied every tick
        self._tick = np.array([0.0, CORNER_SPEED])
        #: (kinematics, rows, the kernel's arguments, the kernel bound to them) of the last tick
        self._call: tuple[Kinematics, ConstraintRows, tuple[Any, ...], Callable[[], tuple[int, int]]] | None = None
        self._G = np.zeros((self.n_inequalities, robot.nv))  # used when the controller's G rows are not C-contiguous
        # the kinematics in the kernels' layout when the controller's are Pinocchio's (not native)
        self._placements = np.zeros((robot.model.njoints, 12))
        self._jacobians_t = np.zeros((robot.nv, 6))
        self._context: TickContext | None = None  # the controller's (use_context)
        self._unbounded = np.full(robot.nv, np.inf)
        #: the speed bound the pairs' reach at every configuration was formed for, then that reach
        #: (:func:`~wbc.collision.kernels._refresh_reach`; NaN: not yet formed)
        self._reach = np.full(robot.nv + self.distances.pairs.shape[0], np.nan)

    def use_context(self, context: TickContext) -> None:
        self._braking.use_context(context)
        self._context = context

    @property
    def _speed(self) -> np.ndarray:
        """The bound on each ``|v_k|`` that leaves out the pairs out of reach: the controller's
        (``TickContext.speed_bound``), none (``inf``) without one or when the rows brake
        (:class:`~wbc.collision.braking.RowBraking` tightens them: a row left out might bind)."""
        context = self._context
        return context.speed_bound if context is not None and not self._braking.active else self._unbounded

    def write_static(self, rows: ConstraintRows) -> None:
        rows.G[:] = 0.0
        rows.h[:] = INERT

    @property
    def pairs(self) -> PairBuffers:
        """This tick's pairs within the detection distance and within reach (entries
        ``0 .. pairs.count - 1``; see the class's *Reach*)."""
        self._pairs.count = int(self._counts[0])  # (the tick program's op writes the count there)
        return self._pairs

    @property
    def corners(self) -> int:
        """The corner rows of the last tick (after the pairs' rows)."""
        return int(self._counts[1])

    def add_ops(self, program: TickProgram, kin: Kinematics, rows: ConstraintRows) -> bool:
        """The rows as one op of the tick program (:func:`avoidance_op`): when every candidate pair
        has a compiled distance (:func:`compiled_pairs_only`), the kinematics are the compiled chain's
        and no acceleration bounds ask for braking (:class:`~wbc.collision.braking.RowBraking`, in
        Python); else :meth:`compute` every tick. (Warns here, where the stack is known, when the
        detection distance is shorter than the braking distance: :meth:`RowBraking.check_detection`.)"""
        avoidance = self.constraint
        self._braking.check_detection(kin.robot, avoidance.name, avoidance.detection_distance, avoidance.min_distance)
        if not (kin.native and rows.G.flags.c_contiguous and not self._braking.active
                and compiled_pairs_only(self.distances)):
            return False
        distances, pairs = self.distances, self._pairs
        program.add(avoidance_op(), table=distances.table, pairs=distances.pairs, placements=kin.placements,
                    jacobians_t=kin.joint_jacobians.T, support=distances._support, world=distances._world,
                    index=pairs.index, distance=pairs.distance, points=pairs.points, rows=pairs.rows,
                    scratch=distances._scratch, G=rows.G, h=rows.h, settings=self.constraint._settings,
                    tick=self._tick, corner_slot=self.corner_pair, speed=self._speed, counts=self._counts,
                    levers=distances.levers, reach=self._reach,
                    shapes=distances.table.shape[0], candidates=distances.pairs.shape[0],
                    joints=kin.placements.shape[0], nv=rows.G.shape[1], capacity=pairs.capacity,
                    pending=pairs.pending.size, inequalities=self.n_inequalities, corners=self.corner_pair.size)
        return True

    def prepare_compute(self) -> None:
        """Compile what :meth:`compute` calls: :func:`~wbc.collision.kernels.avoidance_rows`, and the
        kernels of coal's pairs when some pair has no compiled distance."""
        from ..runtime.kernels._lazy import compile_named  # (numba: not by ``import wbc``)

        coal = () if compiled_pairs_only(self.distances) else ("insert_pair", "damper_rows", "corner_rows")
        compile_named(self.distances._kernels, "avoidance_rows", *coal)

    def compute(self, kin: Kinematics, dt: float, rows: ConstraintRows) -> None:
        pairs, settings, counts = self._pairs, self.constraint._settings, self._counts
        self._tick[0] = dt
        call = self._call
        if call is None or call[0] is not kin or call[1] is not rows:
            call = self._call = self._arguments(kin, rows)
        _, _, arguments, rows_of_tick = call
        if not kin.native:
            fill_kinematics(kin.data, self._placements, self._jacobians_t)
        packed, _ = rows_of_tick()  # (it sets counts when it writes the rows)
        if packed > pairs.capacity:  # pairs without a compiled distance: measured by coal, then the rows
            self._finish_with_coal(packed, arguments, dt)
        G, h = arguments[11], arguments[12]
        self._braking.apply(kin.q, G, h, settings[GAIN], dt, int(counts[0] + counts[1]))
        if G is not rows.G:
            rows.G[:] = G

    def _arguments(self, kin: Kinematics, rows: ConstraintRows
                   ) -> tuple[Kinematics, ConstraintRows, tuple[Any, ...], Callable[[], tuple[int, int]]]:
        """The arguments of :func:`~wbc.collision.kernels.avoidance_rows` for these kinematics and
        rows (fixed buffers: built on the first tick, then reused), and the kernel bound to them:
        its compiled entry without numba's dispatch (:func:`~wbc.runtime.native_entry.unchecked_entry`,
        ~0.04 us per argument saved), as every argument is one of these C-contiguous buffers of the
        kernel's dtypes and dimensions -- checked here, else the dispatcher, which checks them itself."""
        distances, pairs = self.distances, self._pairs
        if kin.native:
            placements, jacobians_t = kin.placements, kin.joint_jacobians.T
        else:
            placements, jacobians_t = self._placements, self._jacobians_t
        G = rows.G if rows.G.flags.c_contiguous else self._G  # the kernels write C-contiguous rows
        arguments = (distances.table, distances.pairs, placements, jacobians_t, distances._support, distances._world,
                     pairs.index, pairs.distance, pairs.points, pairs.rows, distances._scratch, G, rows.h,
                     self.constraint._settings, self._tick, self.corner_pair, self._speed, self._counts,
                     distances.levers, self._reach)
        kernel = self.distances._kernels.avoidance_rows
        if fits_signature(kernel, arguments):
            kernel = unchecked_entry(kernel)
        return kin, rows, arguments, functools.partial(kernel, *arguments)

    def _finish_with_coal(self, packed: int, arguments: tuple[Any, ...], dt: float) -> None:
        """After a kernel call that left pairs to coal: measure them, then every row."""
        distances, pairs, kernels = self.distances, self._pairs, self.distances._kernels
        settings = self.constraint._settings
        jacobians_t, G, h, counts = arguments[3], arguments[11], arguments[12], self._counts
        pairs.count = distances.finish_with_coal(pairs, packed, jacobians_t)
        kernels.damper_rows(pairs.count, counts[0] + counts[1], pairs.distance, pairs.rows, G, h, settings, dt)
        counts[0] = pairs.count
        counts[1] = kernels.corner_rows(distances.table, distances.pairs, distances._world, distances._support,
                                           jacobians_t, pairs.count, pairs.pair, pairs.distance, pairs.witness_a,
                                           pairs.witness_b, pairs.normal, G, h, settings, dt, CORNER_SPEED,
                                           self._speed, self.corner_pair, distances._scratch)

    @property
    def min_distance(self) -> float:
        """The smallest signed distance of the last tick's pairs [m] (inf when no pair was within
        the detection distance and within reach: :attr:`pairs`)."""
        count = self.pairs.count
        return float(self.pairs.distance[:count].min()) if count else float("inf")

    def active_labels(self) -> list[str]:
        """The pairs of the last tick's rows, in row order (``"link↔link"``, ``"link↔sphere0"``)."""
        return [self.distances.labels[k] for k in self.pairs.pair[:self.pairs.count].tolist()]

    def row_labels(self) -> list[str]:
        """This tick's pair of each row (``"link↔sphere0"``), then the corner rows (``"link↔sphere0
        corner"``), then ``"row i (no pair)"`` for the inert rows of the capacity."""
        active = self.active_labels()
        active += [f"{active[i]} corner" for i in self.corner_pair[:self.corners].tolist()]
        return active + [f"row {i} (no pair)" for i in range(len(active), self.n_inequalities)]


@functools.cache
def avoidance_op() -> CompiledOp:
    """The op of the tick program that computes a :class:`CollisionAvoidance`'s rows
    (:func:`wbc.collision.kernels.avoidance_op`): compiled once per process, when a controller first
    uses it."""
    from ..runtime.compiled_op import CompiledOp
    from . import kernels

    return CompiledOp("COLLISION_AVOIDANCE", kernels.avoidance_op, (
        ("table", ("shapes", ROW)), ("pairs", ("candidates", PAIR_COLUMNS), "int64"), ("placements", ("joints", 12)),
        ("jacobians_t", ("nv", 6)), ("support", ("joints", "nv")), ("world", ("shapes", kernels.POSE_COLUMNS)),
        ("index", ("capacity + pending",), "int64"), ("distance", ("capacity",)), ("points", (3, "capacity", 3)),
        ("rows", ("capacity", "nv")), ("scratch", (SCRATCH,)), ("G", ("inequalities", "nv")),
        ("h", ("inequalities",)), ("settings", (3,)), ("tick", (2,)), ("corner_slot", ("corners",), "int64"),
        ("speed", ("nv",)), ("counts", (2,), "int64"), ("levers", ("candidates", "nv")),
        ("reach", ("nv + candidates",)), ("shapes", None), ("candidates", None), ("joints", None),
        ("nv", None), ("capacity", None), ("pending", None), ("inequalities", None), ("corners", None)),
        checks=("capacity >= 1", "pending >= candidates", "pending >= 1", "inequalities == capacity + corners"))
