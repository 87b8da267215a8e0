"""The node: a controller ticking at the fixed rate ``1 / dt`` between the robot's ROS 2 topics.

Each tick (:meth:`Node.tick`) takes every sample DDS holds (joint states, odometry, targets:
checked by :mod:`wbc.ros.inputs`, bad ones dropped and counted), then

* **state fresh** (every joint, and the odometry if configured, newer than ``[state]
  timeout``): the configuration ``q`` is assembled (the base pose from the odometry or, with
  no ``odometry`` configured, from the node's own integration of the base commands it sent),
  the scenario's reference motion (if any) sets its task's target at ``t = control ticks x
  dt`` until a target message for that task arrives, :meth:`wbc.Controller.step` computes
  ``v`` and :class:`~wbc.ros.commands.CommandWriter` writes it -- checked finite and within
  every speed limit;
* **state stale** (or missing): the zero command is written once, the first tick it is so
  (the watchdog), and nothing more until fresh states arrive; before the first state, nothing.

Ticks are due at ``t0 + k dt`` (monotonic clock); a tick that ends after the next one was
due is an overrun: counted, and the schedule restarts from now (no burst of late ticks).
Between ticks the node sleeps; SIGINT or SIGTERM (:func:`stop_on_signals`) ends the sleep's
loop at the next check (at most ``dt`` later): the zero command is written, then the node
leaves the domain. Diagnostics (:mod:`wbc.ros.status`) go out every ``[diagnostics]
period``.
"""

from __future__ import annotations

import math
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator
from types import FrameType
from typing import Any, TextIO, TypeVar

import numpy as np
from cyclonedds.idl import IdlStruct
from cyclonedds.sub import DataReader
from numpy.typing import NDArray

from ..app.scenario import Scenario
from ..control.controller import Controller
from ..core.errors import WbcError
from ..tasks import FrameTask
from ..tasks.frame_task import FrameTaskData
from ..tasks.position_task import PositionTaskData
from .commands import CommandWriter
from .config import NodeConfig
from .dds import SENSOR_DATA_DEPTH, Participant, announce_node, source_timestamp, take_one
from .inputs import BasePose, DropLog, JointStates, PoseTargets, TwistTargets
from .messages import DiagnosticArray, JointState, Odometry, PoseStamped, Twist
from .status import NodeStatus, diagnostics_message

_Message = TypeVar("_Message", bound=IdlStruct)
MAX_SAMPLES_PER_TICK = 64  #: samples taken per reader and tick at most (a flood cannot starve the loop)
SLEEP_SLICE = 0.005  #: [s] longest single sleep: a stop request waits at most this long


class Node:
    """A controller of ``scenario`` on the ROS 2 topics of ``config``, in ``participant``'s domain.

    Args:
        scenario: the robot, tasks, constraints, ``dt`` and reference motion.
        config: the topics and joint wiring fitted to ``scenario`` (:func:`wbc.ros.config.resolve`).
        participant: the DDS participant (:class:`wbc.ros.dds.Participant`).
        controller: the controller to run (default ``scenario.make_controller()``).
        stream: where the startup line and dropped-message notes go (default stderr).
    """

    def __init__(self, scenario: Scenario, config: NodeConfig, participant: Participant,
                 controller: Controller | None = None, stream: TextIO | None = None) -> None:
        self.scenario, self.config, self.participant = scenario, config, participant
        self.controller = controller or scenario.make_controller()
        self.robot, self.dt = scenario.robot, scenario.dt
        self.stream = stream or sys.stderr
        self.status = NodeStatus()
        self.drops = DropLog(self.stream)
        self.q = scenario.q0.copy()  #: the configuration of the latest tick (base: odometry or own integration)
        self._joints = JointStates(config.joint_states, config.joints, config.timeout, self.drops)
        self._joint_reader = participant.reader(config.joint_states, JointState, reliable=False,
                                                depth=SENSOR_DATA_DEPTH)
        self._odometry = None if config.odometry is None else BasePose(config.odometry, config.world_frame,
                                                                        config.timeout, self.drops)
        self._odometry_reader = None if config.odometry is None else participant.reader(
            config.odometry, Odometry, reliable=False, depth=SENSOR_DATA_DEPTH)
        self._base_q = self._base_coordinates()
        self._poses = [(target, PoseTargets(target.topic, config.world_frame, config.timeout, self.drops),
                        participant.reader(target.topic, PoseStamped)) for target in config.pose_targets]
        twist = config.twist_target
        self._twist = None if twist is None else (twist, TwistTargets(twist.topic, twist.timeout, self.drops),
                                                  participant.reader(twist.topic, Twist))
        self.commands = CommandWriter(participant, config, self.robot)
        self._diagnostics = participant.writer(config.diagnostics, DiagnosticArray)
        readers: list[Any] = [self._joint_reader, *(reader for _, _, reader in self._poses)]
        readers += [reader for reader in (self._odometry_reader, None if self._twist is None else self._twist[2])
                    if reader is not None]
        self._announcement = announce_node(participant, config.namespace, config.node, readers,
                                           [*self.commands.writers, self._diagnostics])
        self._next_diagnostics = -math.inf
        self._reference = scenario.reference
        self._reference_task = scenario.reference_task
        self._reference_data: FrameTaskData | PositionTaskData | None = None
        if self._reference_task is not None:
            data = self.controller.data(self._reference_task)
            assert isinstance(data, (FrameTaskData, PositionTaskData))  # what FrameTask / PositionTask.bind return
            self._reference_data = data
        self._zero_twist = np.zeros(3)
        self._accepted = 0  # joint state messages taken up to the last control tick

    # ------------------------------------------------------------------------------ startup
    def startup_line(self) -> str:
        """What the node says when it starts: its name, rate, where the base pose comes from, its topics."""
        config = self.config
        if not self.robot.base.is_mobile:
            base = "fixed base"
        elif config.odometry is not None:
            base = f"base pose from odometry on {config.odometry}"
        else:
            base = "base pose from its own integration of the base commands (no [state] odometry)"
        outputs = [c.topic for c in config.controllers] + ([] if config.base is None else [config.base.topic])
        targets = [t.topic for t in config.pose_targets] + ([] if config.twist_target is None
                                                            else [config.twist_target.topic])
        reference = ("" if self._reference is None or self._reference_task is None
                     else f"; reference motion of {self._reference_task.name} until a target arrives")
        return (f"wbc ros: node {config.node_name} (ROS_DOMAIN_ID {self.participant.domain_id}), scenario "
                f"{self.scenario.name!r} at {1 / self.dt:g} Hz; joint states on {config.joint_states}, {base}; "
                f"commands on {', '.join(outputs)}; targets on {', '.join(targets) or 'none'}{reference}; "
                f"watchdog {config.timeout:g} s")

    def _base_coordinates(self) -> NDArray[np.intp]:
        """The q indices of the base pose ``(x, y, yaw)`` (empty for a fixed base)."""
        if not self.robot.base.is_mobile:
            return np.zeros(0, dtype=np.intp)
        joints = list(self.robot.model.joints)[1:]
        by_v = {joint.idx_v: joint for joint in joints}
        if any(by_v[index].nq != 1 for index in self.robot.base.indices):
            raise WbcError(f"robot {self.robot.name!r}: the node needs one q coordinate per base coordinate")
        return np.array([by_v[index].idx_q for index in self.robot.base.indices], dtype=np.intp)

    # -------------------------------------------------------------------------------- inputs
    def _drain(self, reader: DataReader[_Message], topic: str, now: float) -> Iterator[_Message]:
        """The samples DDS holds for ``reader`` (at most :data:`MAX_SAMPLES_PER_TICK`); bytes that
        do not decode are dropped and counted."""
        for _ in range(MAX_SAMPLES_PER_TICK):
            sample, more = take_one(reader)
            if not more:
                return
            if sample is None:
                self.drops.drop(topic, "undecodable", "bytes that are not the topic's message type", now)
            else:
                yield sample

    def _read_inputs(self, now: float) -> None:
        for state in self._drain(self._joint_reader, self.config.joint_states, now):
            self._joints.accept(state, now, source_timestamp(state))
        if self._odometry is not None and self._odometry_reader is not None:
            for odometry in self._drain(self._odometry_reader, self._odometry.topic, now):
                self._odometry.accept(odometry, now)
        for target, check, reader in self._poses:
            for pose_message in self._drain(reader, target.topic, now):
                pose = check.pose(pose_message, now)
                if pose is None:
                    continue
                if isinstance(target.task, FrameTask):
                    target.task.set_target(pose)
                else:
                    target.task.set_target(pose[:3, 3])
                if target.task is self._reference_task:
                    self._reference = None  # a target from the wire replaces the scenario's motion
        if self._twist is not None:
            twist_target, twists, twist_reader = self._twist
            for twist_message in self._drain(twist_reader, twist_target.topic, now):
                twist = twists.twist(twist_message, now)
                if twist is not None:
                    twist_target.task.set_target(twist)
            if twists.expired(now):
                twist_target.task.set_target(self._zero_twist)

    def _stale_reason(self, now: float) -> str | None:
        """Why the state is not fresh at ``now`` (None when it is)."""
        if not self._joints.fresh(now):
            missing = self._joints.stale(now)
            return f"no fresh joint state for {', '.join(missing[:5])}{' ...' if len(missing) > 5 else ''}"
        if self._odometry is not None and not self._odometry.fresh(now):
            return f"no fresh odometry on {self._odometry.topic}"
        return None

    # ---------------------------------------------------------------------------------- tick
    def tick(self, now: float) -> None:
        """One tick at monotonic time ``now`` [s] (module docstring)."""
        status = self.status
        status.ticks += 1
        self._read_inputs(now)
        reason = self._stale_reason(now)
        if reason is not None:
            if status.state == "control":
                self.commands.publish_zero(self.q)
                status.watchdog_trips += 1
                oldest = float(np.min(self._joints.received))
                if self._odometry is not None:
                    oldest = min(oldest, self._odometry.received)
                status.trip_ages.append(now - oldest)  # what went stale: >= the timeout
                status.zero_sent = True
                status.stale_reason = reason
                self.drops.note("watchdog", f"watchdog: {reason}; zero command sent, held until fresh states", now)
            if status.state != "waiting":
                status.state = "stale"
            status.stale_reason = reason
            return
        if status.state == "control" and self._joints.accepted == self._accepted:
            status.repeated_state_ticks += 1
        self._accepted = self._joints.accepted
        status.state = "control"
        status.zero_sent = False
        self._joints.write(self.q)
        if self._odometry is not None:  # yaw unwrapped: q's heading stays continuous past +-pi
            x, y, yaw = self._odometry.pose
            heading = self._base_q[2]
            self.q[self._base_q] = x, y, self.q[heading] + math.remainder(yaw - self.q[heading], math.tau)
        if self._reference is not None and self._reference_task is not None:
            self._reference_task.set_target(*self._reference(status.control_ticks * self.dt))
        try:
            v = self.controller.step(self.q)
        except WbcError as exc:  # e.g. a joint state outside the model's range: stop, say why
            self.commands.publish_zero(self.q)
            status.zero_sent = True
            self.drops.note("controller", f"controller refused the state: {exc}; zero command sent", now)
            return
        last = self.controller.last
        sent = self.commands.publish(self.q, v)
        status.control_ticks += 1
        status.record_outcome(last.success, lambda: last.conflicts)  # after the command went out
        status.last_status, status.last_solve_time = last.status, last.solve_time
        status.step.add(last.tick_time)
        status.latency.add(time.monotonic() - now)
        if self._joints.source_time:
            status.state_age.add(max(0.0, time.time() - self._joints.source_time * 1e-9))
        if self._reference_data is not None:
            error = self._reference_data.error
            status.record_error(math.hypot(error[0], error[1], error[2]))  # (inf, not a warning, on a far target)
        if self._odometry is None and self._base_q.size:
            self.q[self._base_q] = self.robot.integrate(self.q, sent, self.dt)[self._base_q]

    def publish_diagnostics(self, now: float, force: bool = False) -> None:
        """Write the diagnostics if their period is over (or ``force``)."""
        if not force and now < self._next_diagnostics:
            return
        self._next_diagnostics = now + self.config.diagnostics_period
        status, us = self.status, 1e6
        values = {"ticks": str(status.ticks), "control_ticks": str(status.control_ticks),
                  "overruns": str(status.overruns), "watchdog_trips": str(status.watchdog_trips),
                  "fallback_ticks": str(status.fallback_ticks), "solver_status": status.last_status,
                  "conflict_episodes": str(status.conflict_episodes),
                  "conflicts": ", ".join(status.last_conflicts),
                  "latency_p50_us": f"{status.latency.percentile(50) * us:.1f}",
                  "latency_p99_us": f"{status.latency.percentile(99) * us:.1f}",
                  "dropped_messages": str(self.drops.total), "last_dropped": self.drops.last,
                  "commands_scaled_into_limits": str(self.commands.scaled),
                  "commands_replaced_by_zero": str(self.commands.replaced)}
        values |= {f"dropped {key}": str(count) for key, count in self.drops.counts.items()}
        warnings = []
        if status.last_status and status.last_status != "optimal":
            warnings.append(f"fallback: {status.last_status}"
                            + (f" (conflict: {', '.join(status.last_conflicts)})" if status.last_conflicts else ""))
        if self.drops.total:
            warnings.append(f"{self.drops.total} messages dropped (last: {self.drops.last})")
        if status.overruns:
            warnings.append(f"{status.overruns} overruns")
        values["warnings"] = "; ".join(warnings)
        self._diagnostics.write(diagnostics_message(self.config.node_name, status, values, time.time_ns()))

    # ---------------------------------------------------------------------------------- loop
    def run(self, stop: threading.Event, duration: float | None = None) -> dict[str, Any]:
        """Tick until ``stop`` is set (or ``duration`` [s] has passed), then write the zero command;
        the summary of :meth:`wbc.ros.status.NodeStatus.summary`."""
        print(self.startup_line(), file=self.stream, flush=True)
        start = due = time.monotonic()
        try:
            while not stop.is_set() and (duration is None or due - start < duration):
                now = time.monotonic()
                self.tick(now)
                self.publish_diagnostics(now)
                due += self.dt
                after = time.monotonic()
                if after > due:
                    self.status.overruns += 1
                    due = after
                _sleep_until(due, stop)
        finally:
            self.commands.publish_zero(self.q)
            self.publish_diagnostics(time.monotonic(), force=True)
        return self.summary()

    def summary(self) -> dict[str, Any]:
        """The node's numbers so far (:meth:`wbc.ros.status.NodeStatus.summary`)."""
        return self.status.summary(self.drops.counts, self.commands.scaled, self.commands.replaced)


def _sleep_until(due: float, stop: threading.Event) -> None:
    """Sleep until monotonic time ``due`` in slices of at most :data:`SLEEP_SLICE`, returning early on ``stop``."""
    while not stop.is_set():
        left = due - time.monotonic()
        if left <= 0:
            return
        time.sleep(min(left, SLEEP_SLICE))


def stop_on_signals(stop: threading.Event) -> Callable[[], None]:
    """Set ``stop`` on SIGINT and SIGTERM (instead of raising KeyboardInterrupt or exiting);
    returns the function that restores the previous handlers."""
    def handler(signum: int, frame: FrameType | None) -> None:
        stop.set()

    previous = {signum: signal.signal(signum, handler) for signum in (signal.SIGINT, signal.SIGTERM)}

    def restore() -> None:
        for signum, old in previous.items():
            signal.signal(signum, old)

    return restore
