"""A simulated ROS 2 robot for the node (``python -m wbc.ros.simulated SCENARIO --config FILE``):
what a robot's drivers do, on the topics of the same configuration, with wbc's kinematic
integrator standing in for the hardware -- to try the node without a robot, and to test it.

It publishes the joint states (every configured joint, by its ROS name, ``position = sign q
+ zero``) and, if ``[state] odometry`` is set, the base pose as ``nav_msgs/Odometry`` in the
world frame; it reads each controller's ``Float64MultiArray`` and the base ``Twist``. Once
every command topic has a new message it integrates ``q <- q + v dt`` (the base twist turned
into the world frame) and publishes the new state at once, so that the node's next tick sees
the state its last command produced -- the kinematic loop of ``wbc run``, over DDS. With no
new command it republishes the current state every ``dt`` (a driver's steady stream).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import threading
import time
from typing import Any

import numpy as np
from cyclonedds.sub import DataReader
from numpy.typing import NDArray

from ..model.robot import Robot
from .config import NodeConfig
from .dds import SENSOR_DATA_DEPTH, Participant, take_one
from .messages import Float64MultiArray, JointState, Odometry, Twist, TwistStamped

POLL = 0.0005  #: [s] between looks for new commands


class SimulatedRobot:
    """The robot of ``config`` at configuration ``q0``, stepping ``dt`` per complete command."""

    def __init__(self, participant: Participant, config: NodeConfig, robot: Robot, q0: NDArray[np.float64],
                 dt: float) -> None:
        self.config, self.robot, self.dt = config, robot, dt
        self.q = np.array(q0, dtype=np.float64)
        self.v = np.zeros(robot.nv)
        self.steps = 0  #: commands applied
        self.zero_commands = 0  #: complete commands that were all zero
        self._joint_writer = participant.writer(config.joint_states, JointState, reliable=False,
                                                depth=SENSOR_DATA_DEPTH)
        self._odometry_writer = None if config.odometry is None else participant.writer(
            config.odometry, Odometry, reliable=False, depth=SENSOR_DATA_DEPTH)
        self._controllers = [(participant.reader(c.topic, Float64MultiArray), c) for c in config.controllers]
        self._base: DataReader[Any] | None = None
        if config.base is not None:
            kind: type[Twist | TwistStamped] = TwistStamped if config.base.stamped else Twist
            self._base = participant.reader(config.base.topic, kind)
        self._fresh = [False] * (len(self._controllers) + (self._base is not None))
        self._message = JointState(name=[joint.ros_name for joint in config.joints])
        self._message.header.frame_id = ""

    def publish_state(self) -> None:
        """Write the joint states (and odometry) of the current ``q``, stamped now."""
        sec, nanosec = divmod(time.time_ns(), 1_000_000_000)
        message = self._message
        message.header.stamp.sec, message.header.stamp.nanosec = sec, nanosec
        message.position = [joint.sign * self._angle(joint.q_index, joint.continuous) + joint.zero
                            for joint in self.config.joints]
        self._joint_writer.write(message)
        if self._odometry_writer is not None:
            x, y, yaw = (float(self.q[k]) for k in self.robot.base.indices)
            odometry = Odometry()
            odometry.header.stamp.sec, odometry.header.stamp.nanosec = sec, nanosec
            odometry.header.frame_id, odometry.child_frame_id = self.config.world_frame, "base_link"
            odometry.pose.pose.position.x, odometry.pose.pose.position.y = x, y
            odometry.pose.pose.orientation.z, odometry.pose.pose.orientation.w = math.sin(yaw / 2), math.cos(yaw / 2)
            self._odometry_writer.write(odometry)

    def _angle(self, index: int, continuous: bool) -> float:
        return math.atan2(self.q[index + 1], self.q[index]) if continuous else float(self.q[index])

    def poll(self) -> bool:
        """Take the commands DDS holds; once each topic has a new one, integrate and publish. Whether it stepped."""
        for k, (reader, controller) in enumerate(self._controllers):
            while True:
                command, more = take_one(reader)
                if not more:
                    break
                if command is not None and len(command.data) == len(controller.joints):
                    self.v[controller.v_indices] = controller.signs * np.array(command.data)
                    self._fresh[k] = True
        if self._base is not None:
            while True:
                sample, more = take_one(self._base)
                if not more:
                    break
                if sample is not None:
                    twist = sample.twist if isinstance(sample, TwistStamped) else sample
                    x, y, heading = self.robot.base.indices
                    yaw = float(self.q[heading])
                    v_x, v_y = twist.linear.x, twist.linear.y
                    self.v[x] = math.cos(yaw) * v_x - math.sin(yaw) * v_y
                    self.v[y] = math.sin(yaw) * v_x + math.cos(yaw) * v_y
                    self.v[heading] = twist.angular.z
                    self._fresh[-1] = True
        if not all(self._fresh):
            return False
        self._fresh = [False] * len(self._fresh)
        self.zero_commands += not np.any(self.v)
        self.q = self.robot.integrate(self.q, self.v, self.dt)
        self.steps += 1
        self.publish_state()
        return True

    def run(self, stop: threading.Event, duration: float | None = None) -> None:
        """Poll for commands until ``stop`` (or ``duration`` [s]), republishing the state every ``dt`` without one."""
        start = last = time.monotonic()
        self.publish_state()
        while not stop.is_set() and (duration is None or time.monotonic() - start < duration):
            if self.poll():
                last = time.monotonic()
            elif time.monotonic() - last >= self.dt:
                self.publish_state()
                last = time.monotonic()
            time.sleep(POLL)


def main(argv: list[str] | None = None) -> int:
    """``python -m wbc.ros.simulated SCENARIO --config FILE [--duration S]``: prints a JSON summary at exit."""
    from ..app.scenario import load_scenario
    from .config import load_config
    from .node import stop_on_signals

    parser = argparse.ArgumentParser(prog="python -m wbc.ros.simulated", description=__doc__.split("\n\n")[0])
    parser.add_argument("scenario")
    parser.add_argument("--config", required=True)
    parser.add_argument("--duration", type=float)
    args = parser.parse_args(argv)
    scenario = load_scenario(args.scenario)
    config = load_config(args.config, scenario.robot, scenario.tasks)
    participant = Participant()
    stop = threading.Event()
    stop_on_signals(stop)
    robot = SimulatedRobot(participant, config, scenario.robot, scenario.q0, scenario.dt)
    print(f"wbc ros simulated robot: {scenario.robot.name} on {config.joint_states}", file=sys.stderr, flush=True)
    robot.run(stop, args.duration)
    print(json.dumps({"steps": robot.steps, "zero_commands": robot.zero_commands, "q": robot.q.tolist()}),
          flush=True)
    participant.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
