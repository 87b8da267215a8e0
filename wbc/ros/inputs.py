"""What the node reads from the wire, checked before it reaches the controller.

Every message is checked; one that fails a check is dropped whole, counted by reason in the
diagnostics and said on stderr at most every :data:`SAY_EVERY` seconds per topic and reason
(:class:`DropLog`). Nothing raises: the last good values stay in use while fresh.

* **Joint states** update the joints they name (extra names are ignored; several publishers
  may share the topic, each naming some joints). Dropped: arrays whose length is not the
  number of names, a name given twice, a non-finite position of a model joint, a stamp older
  than that joint's last one (within the watchdog timeout: after a longer silence a new
  stream is taken, whatever its clock -- a restarted driver or simulation). A joint is fresh
  when its last position arrived less than the timeout ago.
* **Odometry**: the base pose ``(x, y, yaw)``; dropped when ``header.frame_id`` is not the
  world frame, a value is not finite, the orientation is not a unit quaternion, or the stamp
  goes back.
* **Target poses** (PoseStamped) and **base twists** (Twist): dropped when not finite, not a
  unit quaternion, or (poses) not in the world frame. A twist older than its timeout is zero.

A stamp of zero (``sec = nanosec = 0``: unstamped) is never out of order.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Sequence
from typing import TextIO

import numpy as np
from numpy.typing import NDArray

from .config import JointWiring
from .messages import JointState, Odometry, PoseStamped, Quaternion, Time, Twist

SAY_EVERY = 2.0  #: [s] at most one stderr line per topic and reason in this time
UNIT_TOLERANCE = 1e-3  #: largest distance of a quaternion's norm from 1 accepted (the quaternion is then normalised)


class DropLog:
    """Dropped messages: counted by (topic, reason), said on ``stream`` at most every
    :data:`SAY_EVERY` seconds per topic and reason, with the count left unsaid meanwhile."""

    def __init__(self, stream: TextIO | None = None) -> None:
        self.stream = stream or sys.stderr
        self.counts: dict[str, int] = {}
        self.total = 0
        self.last = ""  #: the latest drop, in words
        self._said: dict[str, tuple[float, int]] = {}  # key -> (when last said, drops since)

    def drop(self, topic: str, reason: str, detail: str, now: float) -> None:
        """Count a message of ``topic`` dropped for ``reason`` (a short category), ``detail`` the specifics."""
        key = f"{topic}: {reason}"
        self.counts[key] = self.counts.get(key, 0) + 1
        self.total += 1
        self.last = f"{topic}: {detail}"
        self.note(key, f"dropped a message on {topic}: {detail}", now)

    def note(self, key: str, text: str, now: float) -> None:
        """Say ``text`` unless ``key`` was said less than :data:`SAY_EVERY` seconds ago."""
        said, unsaid = self._said.get(key, (-math.inf, 0))
        if now - said >= SAY_EVERY:
            more = f" ({unsaid} more like it since)" if unsaid else ""
            print(f"wbc ros: {text}{more}", file=self.stream, flush=True)
            self._said[key] = (now, 0)
        else:
            self._said[key] = (said, unsaid + 1)


def seconds(stamp: Time) -> float:
    """A ROS time in seconds."""
    return stamp.sec + stamp.nanosec * 1e-9


def _stamp_problem(stamp: Time) -> str | None:
    if not 0 <= stamp.nanosec < 1_000_000_000:
        return f"stamp nanosec = {stamp.nanosec} is not in [0, 10^9)"
    return None


def unit_quaternion(quaternion: Quaternion) -> tuple[float, float, float, float] | None:
    """(x, y, z, w) normalised, or None when not finite or farther than :data:`UNIT_TOLERANCE` from unit length."""
    x, y, z, w = quaternion.x, quaternion.y, quaternion.z, quaternion.w
    norm = math.sqrt(x * x + y * y + z * z + w * w)
    if not math.isfinite(norm) or abs(norm - 1.0) > UNIT_TOLERANCE:
        return None
    return x / norm, y / norm, z / norm, w / norm


def rotation(x: float, y: float, z: float, w: float) -> NDArray[np.float64]:
    """The rotation matrix of the unit quaternion (x, y, z, w)."""
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


class JointStates:
    """The model's joint coordinates from ``sensor_msgs/JointState`` messages (module docstring)."""

    def __init__(self, topic: str, joints: Sequence[JointWiring], timeout: float, drops: DropLog) -> None:
        self.topic, self.joints, self.timeout, self.drops = topic, tuple(joints), timeout, drops
        self._slot = {joint.ros_name: k for k, joint in enumerate(self.joints)}
        count = len(self.joints)
        self.values = np.zeros(count)  #: the model's coordinates: sign (position - zero)
        self.received = np.full(count, -math.inf)  #: [s] monotonic time each joint last arrived
        self.stamps = np.full(count, -math.inf)  #: [s] its last stamp
        self.source_time = 0  #: [ns since the epoch] source timestamp of the last accepted message
        self.accepted = 0  #: messages taken
        self._zero = np.array([joint.zero for joint in self.joints])
        self._sign = np.array([joint.sign for joint in self.joints])
        self._q_index = np.array([joint.q_index for joint in self.joints if not joint.continuous], dtype=np.intp)
        self._plain = np.array([not joint.continuous for joint in self.joints])
        self._continuous = [(k, joint.q_index) for k, joint in enumerate(self.joints) if joint.continuous]

    def fresh(self, now: float) -> bool:
        """Whether every joint arrived less than the timeout before ``now``."""
        return bool(np.all(now - self.received < self.timeout))

    def stale(self, now: float) -> list[str]:
        """The model's joints that did not arrive in the timeout before ``now`` (never: ``"never"``)."""
        return [joint.ros_name for joint, when in zip(self.joints, self.received, strict=True)
                if not now - when < self.timeout]

    def accept(self, message: JointState, now: float, source_time: int = 0) -> bool:
        """Take ``message`` (received at ``now``, monotonic [s]), or drop it saying why; whether it was taken."""
        names, positions = message.name, message.position
        problem = self._problem(message)
        if problem is not None:
            self.drops.drop(self.topic, problem[0], problem[1], now)
            return False
        slots = [(self._slot[name], k) for k, name in enumerate(names) if name in self._slot]
        if not slots:
            if not self.fresh(now):  # only while it matters: the model's joints are missing
                self.drops.note(f"{self.topic}: foreign", f"a message on {self.topic} names none of the model's "
                                f"joints ({', '.join(names[:8]) or 'no names'}); expected "
                                f"{', '.join(j.ros_name for j in self.joints)} (set [joints.NAME] name = ...)", now)
            return False
        mine = [slot for slot, _ in slots]
        values = np.array([positions[k] for _, k in slots], dtype=np.float64)
        bad = ~np.isfinite(values)
        if bad.any():
            name = self.joints[mine[int(np.argmax(bad))]].ros_name
            self.drops.drop(self.topic, "non-finite position", f"position of {name} is {values[bad][0]}", now)
            return False
        stamp = seconds(message.header.stamp)
        if stamp != 0.0:
            recent = now - self.received[mine] < self.timeout
            if np.any(recent & (self.stamps[mine] > stamp)):
                self.drops.drop(self.topic, "stamp went back", f"stamp {stamp:.9f} s is older than the last "
                                f"one ({float(np.max(self.stamps[mine])):.9f} s)", now)
                return False
        self.values[mine] = self._sign[mine] * (values - self._zero[mine])
        self.received[mine] = now
        self.stamps[mine] = stamp
        self.source_time = source_time
        self.accepted += 1
        return True

    def _problem(self, message: JointState) -> tuple[str, str] | None:
        names, count = message.name, len(message.name)
        for field in ("position", "velocity", "effort"):
            size = len(getattr(message, field))
            if size != count and (field == "position" or size != 0):
                return "wrong array length", f"{field} has {size} entries for {count} names"
        if len(set(names)) != count:
            twice = next(name for name in names if names.count(name) > 1)
            return "duplicate name", f"joint {twice!r} is named twice"
        stamp = _stamp_problem(message.header.stamp)
        return None if stamp is None else ("bad stamp", stamp)

    def write(self, q: NDArray[np.float64]) -> None:
        """Write the joints' coordinates into ``q`` (cos and sin of a continuous joint's angle)."""
        q[self._q_index] = self.values[self._plain]
        for k, index in self._continuous:
            q[index], q[index + 1] = math.cos(self.values[k]), math.sin(self.values[k])


class BasePose:
    """The base pose ``(x, y, yaw)`` from ``nav_msgs/Odometry`` in the world frame (module docstring)."""

    def __init__(self, topic: str, world_frame: str, timeout: float, drops: DropLog) -> None:
        self.topic, self.world_frame, self.timeout, self.drops = topic, world_frame, timeout, drops
        self.pose = (0.0, 0.0, 0.0)
        self.received = -math.inf
        self.stamp = -math.inf

    def fresh(self, now: float) -> bool:
        return now - self.received < self.timeout

    def accept(self, message: Odometry, now: float) -> bool:
        """Take ``message`` (received at ``now``), or drop it saying why; whether it was taken."""
        frame, pose = message.header.frame_id, message.pose.pose
        stamp, problem = seconds(message.header.stamp), _stamp_problem(message.header.stamp)
        quaternion = unit_quaternion(pose.orientation)
        if problem is not None:
            reason = ("bad stamp", problem)
        elif frame != self.world_frame:
            reason = ("wrong frame", f"frame_id {frame!r}, expected {self.world_frame!r} ([node] world_frame)")
        elif not (math.isfinite(pose.position.x) and math.isfinite(pose.position.y)):
            reason = ("non-finite pose", f"position ({pose.position.x}, {pose.position.y}) is not finite")
        elif quaternion is None:
            reason = ("not a unit quaternion", f"orientation {_quaternion_text(pose.orientation)} is not a unit "
                                               "quaternion")
        elif stamp != 0.0 and self.fresh(now) and stamp < self.stamp:
            reason = ("stamp went back", f"stamp {stamp:.9f} s is older than the last one ({self.stamp:.9f} s)")
        else:
            x, y, z, w = quaternion
            self.pose = (pose.position.x, pose.position.y, math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z)))
            self.received, self.stamp = now, stamp
            return True
        self.drops.drop(self.topic, reason[0], reason[1], now)
        return False


def _quaternion_text(q: Quaternion) -> str:
    return f"({q.x:.6g}, {q.y:.6g}, {q.z:.6g}, {q.w:.6g})"


class PoseTargets:
    """Target poses from ``geometry_msgs/PoseStamped`` in the world frame (module docstring)."""

    def __init__(self, topic: str, world_frame: str, timeout: float, drops: DropLog) -> None:
        self.topic, self.world_frame, self.timeout, self.drops = topic, world_frame, timeout, drops
        self.received = -math.inf
        self.stamp = -math.inf

    def pose(self, message: PoseStamped, now: float) -> NDArray[np.float64] | None:
        """The 4x4 target of ``message`` (received at ``now``), or None when dropped (said why)."""
        frame, pose = message.header.frame_id, message.pose
        stamp, problem = seconds(message.header.stamp), _stamp_problem(message.header.stamp)
        position = (pose.position.x, pose.position.y, pose.position.z)
        quaternion = unit_quaternion(pose.orientation)
        if problem is not None:
            reason = ("bad stamp", problem)
        elif frame != self.world_frame:
            reason = ("wrong frame", f"frame_id {frame!r}: targets are taken in {self.world_frame!r} "
                                     "([node] world_frame); transform the pose first")
        elif not all(map(math.isfinite, position)):
            reason = ("non-finite pose", f"position {position} is not finite")
        elif quaternion is None:
            reason = ("not a unit quaternion", f"orientation {_quaternion_text(pose.orientation)} is not a unit "
                                               "quaternion")
        elif stamp != 0.0 and now - self.received < self.timeout and stamp < self.stamp:
            reason = ("stamp went back", f"stamp {stamp:.9f} s is older than the last one ({self.stamp:.9f} s)")
        else:
            target = np.eye(4)
            target[:3, :3], target[:3, 3] = rotation(*quaternion), position
            self.received, self.stamp = now, stamp
            return target
        self.drops.drop(self.topic, reason[0], reason[1], now)
        return None


class TwistTargets:
    """Base twists ``(v_x, v_y, omega)`` from ``geometry_msgs/Twist``, zero once older than the timeout."""

    def __init__(self, topic: str, timeout: float, drops: DropLog) -> None:
        self.topic, self.timeout, self.drops = topic, timeout, drops
        self.received = -math.inf

    def twist(self, message: Twist, now: float) -> tuple[float, float, float] | None:
        """The base-frame twist of ``message`` (received at ``now``), or None when dropped (said why)."""
        twist = (message.linear.x, message.linear.y, message.angular.z)
        if not all(map(math.isfinite, twist)):
            self.drops.drop(self.topic, "non-finite twist", f"twist {twist} is not finite", now)
            return None
        self.received = now
        return twist

    def expired(self, now: float) -> bool:
        """Whether the last twist is older than the timeout (it then stands for zero)."""
        return not now - self.received < self.timeout
