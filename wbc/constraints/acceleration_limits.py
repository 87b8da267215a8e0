"""Acceleration and jerk limits: a bound on the change of the command per tick (issue 24 §6, §7).

Each *channel* -- a velocity coordinate (arm joint, base yaw), the platform's base-frame
velocity ``(v_x, v_y)``, and each wheel speed ``u_i`` of a wheeled base -- gets::

    |w - w_prev| <= a dt                               (acceleration)
    |(w - w_prev) - (w_prev - w_prev2)| <= j dt^2      (jerk, when max_jerk is given)

where ``w`` is the channel's value of this tick's command and ``w_prev``, ``w_prev2`` those of the
measured velocity (``step(q, v_measured=...)``) or, without one, of the previous commands; the
controller starts from rest (``w_prev = w_prev2 = 0`` before the first tick). Joints are bounds on
``v``; the base-frame velocity and the wheel speeds are rows turning with the heading
(:class:`~wbc.constraints.heading_rows.HeadingRows`, the rows of :class:`~wbc.JointVelocityLimits`
and :class:`~wbc.WheelSpeedLimits`), so they carry over to the reduced nonholonomic form.

**Viability** (Del Prete et al. 2018, "Joint position and velocity bounds in discrete-time
acceleration/torque control of robot manipulators", IEEE RA-L 3(1)). A joint with position limits
is also bounded by the largest speed from which braking at ``a`` stops it before its limit. With
``q+ = q + v dt`` and the braking commands ``v, v - a dt, v - 2 a dt, ...``, the distance covered
is ``D(v) = dt sum_{k=0}^{m} (v - k a dt)`` with ``m = floor(v / (a dt))``; ``D`` is increasing and
piecewise quadratic, and its inverse is exact::

    delta = d / (a dt^2),  m = floor((sqrt(8 delta + 1) - 1) / 2),  v_max(d) = a dt (delta / (m + 1) + m / 2)

(``~ sqrt(2 a d)`` far from the limit, 0 on it). Since ``D(v - a dt) = D(v) - v dt`` the bound is
invariant: a command that respected it leaves a braking command that respects it at the next tick,
so position limits are never overshot and braking never empties the acceleration box.

**Precedence** (docs/acceleration.md). The constraint is *hard*: the position damper
(:class:`~wbc.JointPositionLimits`, soft) is clipped into it. Among its own bounds: the model's speed
limits win (the reference velocity is taken into them first -- the base twist scaled as a whole into
the base and wheel speed limits, so that a command equal to it meets every row -- and the box is
intersected with them); then the acceleration box (from a state that cannot stop in time -- a
measured velocity, a start outside the limits -- the joint brakes at ``a``, no harder); then
viability; then the jerk bound (braking for a position or speed limit may exceed ``max_jerk``, which
bounds the joint coordinates only).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.errors import InvalidInputError
from ..model.kinematics import Kinematics
from ..model.robot import AccelerationTable, Robot
from ..model.tick_context import TickContext
from ..runtime import kernels
from ..runtime.kernels import BASE_SIZE, BASE_X, BASE_Y, BASE_YAW, BASE_YAW_CHANNEL
from ..runtime.native_entry import unchecked_entry
from .constraint import Constraint, ConstraintData, ConstraintRows
from .heading_rows import HeadingRows


def _as_limit(value: ArrayLike | None, name: str) -> NDArray[np.float64] | None:
    """A scalar or per-coordinate limit: > 0 (inf: no limit), no NaN."""
    if value is None:
        return None
    try:
        array = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise InvalidInputError(f"{name} must be a number or a vector of numbers, got {value!r}") from None
    if array.ndim > 1 or array.size == 0:
        raise InvalidInputError(f"{name} must be a scalar or a vector (one entry per velocity coordinate), "
                                f"got shape {array.shape}")
    if np.any(np.isnan(array)) or np.any(array <= 0.0):
        raise InvalidInputError(f"{name} must be > 0 (inf: no limit), got {value!r}")
    return array


def braking_speed(distance: NDArray[np.float64], a_max: NDArray[np.float64], dt: float,
                  out: NDArray[np.float64]) -> NDArray[np.float64]:
    """The largest speed toward a limit ``distance`` away from which braking at ``a_max`` per tick
    stops short of it (the exact inverse of the braking distance, see the module docstring); for a
    negative distance (beyond the limit) ``distance / dt``, the speed that lands on it in one tick;
    inf for an infinite distance. Compiled (:func:`wbc.runtime.kernels.acceleration.braking_speed`);
    returns ``out``."""
    kernels.braking_speed(distance, a_max, dt, out)
    return out


class AccelerationLimits(Constraint):
    """Bound the change of the command per tick: ``|v - v_prev| <= max_acceleration dt`` for each
    velocity coordinate, the platform's acceleration in the base frame and the wheel accelerations
    of a wheeled base; optionally the change of that change (``max_jerk``); with the viability bound
    that keeps the joints inside their position limits (module docstring).

    Args:
        max_acceleration: [rad/s^2, m/s^2] a scalar or one entry per velocity coordinate (for a mobile
            base the x, y entries bound the base-frame ``a_x, a_y``); ``inf``: unbounded. Default:
            the model's sidecar ``[acceleration]`` table.
        max_jerk: [rad/s^3, m/s^3] the same shape; default None: no jerk bound.
        max_wheel_acceleration: [rad/s^2] of each wheel; default: the sidecar's
            ``[acceleration] wheels`` (no wheel rows when the model declares none).
    """

    hard = True

    def __init__(self, max_acceleration: ArrayLike | None = None, max_jerk: ArrayLike | None = None, *,
                 max_wheel_acceleration: float | None = None, name: str | None = None) -> None:
        super().__init__(name)
        self._max_acceleration = _as_limit(max_acceleration, "max_acceleration")
        self._max_jerk = _as_limit(max_jerk, "max_jerk")
        wheel = _as_limit(max_wheel_acceleration, "max_wheel_acceleration")
        if wheel is not None and wheel.ndim:
            raise InvalidInputError("max_wheel_acceleration must be one number (every wheel), "
                                    f"got {max_wheel_acceleration!r}")
        self._max_wheel_acceleration = None if wheel is None else float(wheel)

    def bind(self, robot: Robot) -> AccelerationLimitsData:
        return AccelerationLimitsData(self, robot)

    def __repr__(self) -> str:
        return (f"AccelerationLimits(max_acceleration={self._max_acceleration}, max_jerk={self._max_jerk}, "
                f"max_wheel_acceleration={self._max_wheel_acceleration})")


def _per_coordinate(limit: NDArray[np.float64], robot: Robot, name: str) -> NDArray[np.float64]:
    if limit.ndim == 0:
        return np.full(robot.nv, float(limit))
    if limit.size != robot.nv:
        raise InvalidInputError(f"{name} has {limit.size} entries; robot '{robot.name}' has {robot.nv} velocity "
                                f"coordinates ({', '.join(robot.joint_names)}): give one number or {robot.nv}")
    return limit.copy()


def _declared(robot: Robot) -> AccelerationTable:
    table = robot.parameters.get("acceleration")
    if table is None:
        raise InvalidInputError(f"AccelerationLimits: robot '{robot.name}' declares no acceleration limits "
                                "(sidecar [acceleration] table): pass max_acceleration=...")
    return AccelerationTable.model_validate(table)


def _declared_acceleration(robot: Robot) -> NDArray[np.float64]:
    """The sidecar's ``[acceleration]`` limits per velocity coordinate."""
    table = _declared(robot)
    limit = np.full(robot.nv, np.nan)
    for joint, value in table.joints.items():
        if joint not in robot.joint_names:
            raise InvalidInputError(f"[acceleration] joints: {joint!r} is not a joint of '{robot.name}'")
        joint_model = robot.model.joints[robot.model.getJointId(joint)]
        limit[joint_model.idx_v:joint_model.idx_v + joint_model.nv] = value
    if robot.base.is_mobile:
        x, y, yaw = robot.base.indices
        limit[[x, y]] = np.nan if table.base_linear is None else table.base_linear
        limit[yaw] = np.nan if table.base_yaw is None else table.base_yaw
    missing = [robot.joint_names[i] if robot.nv == len(robot.joint_names) else str(i)
               for i in np.flatnonzero(np.isnan(limit))]
    if missing:
        raise InvalidInputError(f"AccelerationLimits: robot '{robot.name}' declares no acceleration limit for "
                                f"{', '.join(missing)} (sidecar [acceleration]): pass max_acceleration=...")
    return limit


class AccelerationLimitsData(ConstraintData):
    """:class:`AccelerationLimits` in one controller: the resolved limits, the channels' history
    (``w_prev``, ``w_prev2``) and the viability indices, all preallocated."""

    python_kernels = ("heading_rows", "acceleration_bounds", "braking_speed")  # (braking_speed: RowBraking's)

    has_bounds = True

    def __init__(self, limits: AccelerationLimits, robot: Robot) -> None:
        super().__init__(limits)
        nv, base = robot.nv, robot.base
        given = limits._max_acceleration
        accel = _declared_acceleration(robot) if given is None else _per_coordinate(given, robot, "max_acceleration")
        jerk = (np.full(nv, np.inf) if limits._max_jerk is None
                else _per_coordinate(limits._max_jerk, robot, "max_jerk"))
        speed = robot.velocity_limit
        self._joints = np.arange(nv)
        self._base_rows = base.is_mobile and bool(np.isfinite(accel[list(base.indices[:2])]).any())
        if base.is_mobile:
            self._x, self._y, self._yaw = base.indices
            self._joints = np.setdiff1d(self._joints, [self._x, self._y])  # the base-frame rows bound them
        wheel_accel = limits._max_wheel_acceleration
        if wheel_accel is None and base.wheels is not None and "acceleration" in robot.parameters:
            wheel_accel = _declared(robot).wheels
        wheels = base.wheels if wheel_accel is not None else None
        self._H0 = np.zeros((0, 3)) if wheels is None else wheels.inverse_matrix()  # no rows without a limit
        n_joints = len(self._joints)
        n_wheels = self._H0.shape[0]
        self.n_wheels = n_wheels
        self.n_inequalities = (4 if self._base_rows else 0) + 2 * n_wheels
        # channels: joints, then (v_x, v_y) of the base if it has rows, then the wheels
        base_channels = 2 if (self._base_rows or n_wheels) else 0
        n = n_joints + base_channels + n_wheels
        self._n_joints, self._n_base = n_joints, base_channels
        self._accel, self._jerk, self._speed = np.empty(n), np.full(n, np.inf), np.full(n, np.inf)
        self._accel[:n_joints], self._jerk[:n_joints] = accel[self._joints], jerk[self._joints]
        self._speed[:n_joints] = speed[self._joints]
        if base_channels:
            self._accel[n_joints:n_joints + 2] = accel[[self._x, self._y]]
            self._speed[n_joints:n_joints + 2] = speed[[self._x, self._y]]
        if n_wheels:
            self._accel[n_joints + 2:] = wheel_accel
            assert wheels is not None
            self._speed[n_joints + 2:] = wheels.max_speed
        self._prev, self._prev2 = np.zeros(n), np.zeros(n)  # w_prev, w_prev2: from rest
        # the base's indices for the kernel (BASE_X < 0: no base channels), its speed limits
        self._base = np.full(BASE_SIZE, -1, dtype=np.int64)
        self._twist_speed, self._wheel_speed = np.full(3, np.inf), np.inf
        if base.is_mobile:
            self._twist_speed[:] = speed[[self._x, self._y, self._yaw]]
            self._wheel_speed = np.inf if base.wheels is None else base.wheels.max_speed
            if base_channels:
                self._base[[BASE_X, BASE_Y, BASE_YAW]] = self._x, self._y, self._yaw
                self._base[BASE_YAW_CHANNEL] = int(np.flatnonzero(self._joints == self._yaw)[0])
        self._joints = self._joints.astype(np.int64)
        self._zero = np.zeros(nv)
        self._seen: object = None  # the context's previous command at the last compute (one shift per tick)
        self._heading = 0.0  # the heading at the last compute: the previous command's heading
        self._viability_channels(robot)
        self._braking_rates(robot)
        if self._base_rows or n_wheels:
            cos_part = np.array([[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0], [0.0, -1.0]])
            sin_part = np.array([[0.0, 1.0], [0.0, -1.0], [-1.0, 0.0], [1.0, 0.0]])
            if not self._base_rows:
                cos_part, sin_part = cos_part[:0], sin_part[:0]
            if n_wheels:
                forward = self._H0[:, :2]
                turned = forward @ np.array([[0.0, 1.0], [-1.0, 0.0]])
                cos_part = np.vstack([cos_part, forward, -forward])
                sin_part = np.vstack([sin_part, turned, -turned])
            self._heading_rows = HeadingRows(cos_part, sin_part, self._yaw, self._x, self._y)

    def _braking_rates(self, robot: Robot) -> None:
        """The rates :meth:`decelerations` reads (an unbounded channel: a huge finite rate)."""
        huge = 1e12
        self._magnitudes = np.zeros((0, robot.nv))
        self._joint_rate = np.zeros(robot.nv)  # per velocity coordinate; the base's x, y: below
        self._joint_rate[self._joints] = np.minimum(self._accel[:self._n_joints], huge)
        if not self._n_base:
            return
        base = np.minimum(self._accel[self._n_joints:self._n_joints + 2], huge)
        self._yaw_rate = float(self._joint_rate[self._yaw])
        if self.n_wheels:  # alone along x, y or yaw, every wheel within its limit
            wheel = self._accel[self._n_joints + 2]
            column = np.abs(self._H0).max(axis=0)
            limits = [min(rate, wheel / column[k]) if column[k] > 0.0 else rate
                      for k, rate in enumerate((base[0], base[1], self._yaw_rate))]
            base, self._yaw_rate = np.array(limits[:2]), limits[2]
            self._joint_rate[self._yaw] = 0.0
        self._base_rate = (float(base[0]), float(base[1]))

    def _viability_channels(self, robot: Robot) -> None:
        """The joint channels with finite position limits and acceleration (1-DOF joints)."""
        channel, q_index, lower, upper = [], [], [], []
        position = {joint.idx_v: joint.idx_q for joint in robot.model.joints[1:] if joint.nq == 1 and joint.nv == 1}
        for k, v_index in enumerate(self._joints):
            i = position.get(int(v_index))
            if i is not None and np.isfinite(self._accel[k]) and (np.isfinite(robot.lower[i])
                                                                  or np.isfinite(robot.upper[i])):
                channel.append(k)
                q_index.append(i)
                lower.append(robot.lower[i])
                upper.append(robot.upper[i])
        self._viable = np.array(channel, dtype=np.int64)
        self._viable_q = np.array(q_index, dtype=np.int64)
        self._position_lower = np.array(lower, dtype=np.float64)
        self._position_upper = np.array(upper, dtype=np.float64)
        self._viable_accel = self._accel[self._viable]  # their braking rate
        self._scratch = np.empty(2 * (self._accel.size + len(channel)))  # acceleration_bounds'
        # without numba's dispatch: every array it gets is a 1-D float64 (int64 indices) of this data, the
        # controller's rows, q, or the context's velocity (a command, or the checked v_measured)
        self._bounds = unchecked_entry(kernels.acceleration_bounds)

    def use_context(self, context: TickContext) -> None:
        self.context = context
        context.braking = self  # the collision dampers brake within these bounds

    def decelerations(self, gradients: NDArray[np.float64], q: NDArray[np.float64],
                      out: NDArray[np.float64]) -> None:
        """``out[i]``: a rate [unit/s^2] at which ``g . v`` (``g = gradients[i]``) can change in either
        direction within the acceleration bounds (:class:`~wbc.model.tick_context.Braking`): the
        support of the bounds' set in direction g, or a lower bound of it. The joint boxes are
        independent: ``sum_j |g_j| a_j``. The base's ``(a_x, a_y)`` box turns with the heading:
        ``a_x |g'_x| + a_y |g'_y|`` with ``g' = R(theta)^T g_xy``; with wheel limits, which couple
        ``(a_x, a_y, yaw)``, the largest of ``A_c |g'_c|`` over the three, ``A_c`` the acceleration
        along channel c alone that every bound allows (the set contains those six points, hence
        their hull). Speed limits are not counted (braking lowers speeds)."""
        n = gradients.shape[0]
        if n > self._magnitudes.shape[0]:  # grows to the caller's row count once
            self._magnitudes = np.zeros((n, gradients.shape[1]))
        magnitudes = self._magnitudes[:n]
        np.abs(gradients, out=magnitudes)
        np.matmul(magnitudes, self._joint_rate, out=out)
        if not self._n_base:
            return
        c, s = math.cos(q[self._yaw]), math.sin(q[self._yaw])
        ax, ay = self._base_rate
        for i in range(out.shape[0]):
            gx, gy = gradients[i, self._x], gradients[i, self._y]
            along, across = abs(c * gx + s * gy), abs(-s * gx + c * gy)
            if self.n_wheels:  # the yaw channel is in the hull, not in the box sum
                out[i] += max(ax * along, ay * across, self._yaw_rate * abs(gradients[i, self._yaw]))
            else:
                out[i] += ax * along + ay * across

    def write_static(self, rows: ConstraintRows) -> None:
        if self.n_inequalities:
            n, offset = self.n_wheels, 4 if self._base_rows else 0
            if n:
                rows.G[offset:offset + n, self._yaw] = self._H0[:, 2]
                rows.G[offset + n:, self._yaw] = -self._H0[:, 2]

    def compute(self, kin: Kinematics, dt: float, rows: ConstraintRows) -> None:
        """The bounds of this tick (:func:`wbc.runtime.kernels.acceleration.acceleration_bounds`): the
        channels' reference is the measured velocity, else the previous command (at the heading it
        was computed for), else rest; the history shifts once per tick."""
        context, q = self.context, kin.q
        previous, measured = context.previous, context.measured
        new_tick = previous is not self._seen  # the context holds a new array each tick
        self._seen = previous
        if measured is not None:
            v, heading = measured, q[self._yaw] if self._n_base else 0.0
        elif previous is not None:
            v, heading = previous, self._heading
        else:
            v, heading = self._zero, 0.0
        self._bounds(v, float(heading), new_tick, q, dt, self._joints, self._base, self._twist_speed,
                     self._H0, self._wheel_speed, self._accel, self._jerk, self._speed, self._prev, self._prev2,
                     self._viable, self._viable_q, self._viable_accel, self._position_lower, self._position_upper,
                     self._scratch, rows.lower, rows.upper, rows.h, self._base_rows)
        if self._n_base:
            self._heading = float(q[self._yaw])
        if self.n_inequalities:
            self._heading_rows.write(q, rows.G)

    def warm_state(self) -> tuple[float, NDArray[np.float64], NDArray[np.float64]]:
        """The heading the previous command was computed at and the channels' history
        (``w_prev``, ``w_prev2``): a copy's box and jerk bounds continue exactly."""
        return self._heading, self._prev.copy(), self._prev2.copy()

    def resume(self, state: tuple[float, NDArray[np.float64], NDArray[np.float64]]) -> None:
        self._heading = state[0]
        self._prev[...], self._prev2[...] = state[1], state[2]

    def row_labels(self) -> list[str]:
        base = ["base a_x upper", "base a_x lower", "base a_y upper", "base a_y lower"] if self._base_rows else []
        return base + [f"wheel {i} acceleration {side}" for side in ("forward", "backward")
                       for i in range(self.n_wheels)]
