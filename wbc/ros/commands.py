"""What the node writes to the robot: the base twist and each velocity controller's command,
after a last check that nothing non-finite or beyond a hard speed limit reaches the wire.

* The base: ``geometry_msgs/Twist`` (or ``TwistStamped``) in the base frame, ``linear.x,
  linear.y, angular.z`` = ``(v_x, v_y, omega)`` of :meth:`wbc.Robot.base_twist`; a
  nonholonomic base (differential, synchro) gets ``linear.y = 0``, which it cannot do anyway.
* Each ros2_control ``JointGroupVelocityController``: ``std_msgs/Float64MultiArray`` with one
  velocity per joint in its order, ``sign * v`` (:class:`wbc.ros.config.JointWiring`).

The check (:func:`limit_ratio`): the controller's command satisfies every hard limit (and is
zero when the QP cannot be solved); should a command ever exceed a speed limit (joint, base
frame or wheel) it is scaled down uniformly -- same direction, slower -- until it does not,
and a non-finite one is replaced by zero. Both are counted.
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np
from cyclonedds.pub import DataWriter
from numpy.typing import NDArray

from ..model.robot import Robot
from .config import ControllerWiring, NodeConfig
from .dds import Participant, acknowledged
from .messages import Float64MultiArray, MultiArrayDimension, MultiArrayLayout, Twist, TwistStamped


def limit_ratio(robot: Robot, q: NDArray[np.float64], v: NDArray[np.float64]) -> float:
    """The largest ``|speed| / limit`` of command ``v`` at ``q`` over the joints (for a mobile
    base: its yaw rate and its base-frame speed rows ``M t <= b``, :meth:`MobileBase.speed_rows`)
    and the wheels of a base with a wheel speed limit;
    ``inf`` if ``v`` is not finite. At most 1 when ``v`` satisfies every speed limit."""
    if not np.all(np.isfinite(v)):
        return math.inf
    base = robot.base
    with np.errstate(over="ignore", divide="ignore", invalid="ignore"):  # huge finite v: inf, said by the ratio
        speeds = np.abs(v)
        if base.is_mobile:  # the yaw rate, then the base-frame speed rows M t <= b
            x, y, yaw = base.indices
            speeds[[x, y, yaw]] = 0.0, 0.0, abs(v[yaw])
        ratios = np.where(np.isfinite(robot.velocity_limit), speeds / robot.velocity_limit, 0.0)
        worst = float(np.max(ratios))
        rows = base.speed_rows()
        if rows.count:
            row = float(np.max(rows.matrix @ base.twist(q, v) / rows.bound))
            worst = math.nan if math.isnan(row) else max(worst, row)
        wheels = base.wheels
        if wheels is not None and math.isfinite(wheels.max_speed):
            wheel = float(np.max(np.abs(wheels.inverse_matrix() @ base.twist(q, v)))) / wheels.max_speed
            worst = math.nan if math.isnan(wheel) else max(worst, wheel)
    return math.inf if math.isnan(worst) else worst  # (NaN: inf - inf of an overflow: not within the limits)


class CommandWriter:
    """The node's writers of commands: one per controller, and the base's."""

    def __init__(self, participant: Participant, config: NodeConfig, robot: Robot) -> None:
        self.robot, self.config = robot, config
        self.scaled = 0  #: commands scaled into the speed limits
        self.replaced = 0  #: non-finite commands replaced by zero
        self._zero = np.zeros(robot.nv)
        self._controllers: list[tuple[DataWriter[Float64MultiArray], Float64MultiArray, ControllerWiring]] = []
        for controller in config.controllers:
            message = Float64MultiArray(layout=MultiArrayLayout(
                dim=[MultiArrayDimension(label="joints", size=len(controller.joints), stride=len(controller.joints))]))
            self._controllers.append((participant.writer(controller.topic, Float64MultiArray), message, controller))
        self._base: tuple[DataWriter[Any], Twist | TwistStamped, Twist] | None = None
        if config.base is not None:
            twist = Twist()
            if config.base.stamped:
                stamped = TwistStamped(twist=twist)
                stamped.header.frame_id = config.base.frame_id
                self._base = (participant.writer(config.base.topic, TwistStamped), stamped, twist)
            else:
                self._base = (participant.writer(config.base.topic, Twist), twist, twist)
        # the projector onto the twists the base's no-slip rows N allow (I - N+ N): a unicycle's
        # twist without its v_y residual, a holonomic base's as it is
        no_slip = robot.base.no_slip_rows().matrix
        self._slip_free = np.eye(3) - np.linalg.pinv(no_slip) @ no_slip

    def publish(self, q: NDArray[np.float64], v: NDArray[np.float64]) -> NDArray[np.float64]:
        """Write command ``v`` at ``q`` (after the check of the module docstring); the command written."""
        ratio = limit_ratio(self.robot, q, v)
        if ratio > 1.0:
            if math.isfinite(ratio):
                v = v / ratio
                self.scaled += 1
            else:
                v = self._zero
                self.replaced += 1
        self._write(q, v)
        return v

    def publish_zero(self, q: NDArray[np.float64]) -> None:
        """Write the zero command (every controller and the base)."""
        self._write(q, self._zero)

    @property
    def writers(self) -> list[DataWriter[Any]]:
        """The DDS writers: one per controller, then the base's."""
        return [writer for writer, _, _ in self._controllers] + ([] if self._base is None else [self._base[0]])

    def flush(self, timeout: float) -> bool:
        """Wait at most ``timeout`` [s] in all for every reader to acknowledge the commands written
        (before the node leaves the domain: the last zero must arrive); whether all did."""
        end = time.monotonic() + timeout
        return all([acknowledged(writer, max(0.0, end - time.monotonic())) for writer in self.writers])

    def _write(self, q: NDArray[np.float64], v: NDArray[np.float64]) -> None:
        for writer, message, controller in self._controllers:
            message.data = (controller.signs * v[controller.v_indices]).tolist()
            writer.write(message)
        if self._base is not None:
            base_writer, sample, twist = self._base
            v_x, v_y, omega = (self._slip_free @ self.robot.base.twist(q, v) + 0.0).tolist()  # (+0.0: no -0.0)
            twist.linear.x, twist.linear.y, twist.angular.z = v_x, v_y, omega
            if isinstance(sample, TwistStamped):
                now = time.time_ns()
                sample.header.stamp.sec, sample.header.stamp.nanosec = divmod(now, 1_000_000_000)
            base_writer.write(sample)
