"""Runs the ROS 2 node and a simulated robot as real DDS processes, for tests/test_ros_node.py.

Run only inside a private network namespace (``unshare -rn python tests/ros_harness.py CASE``):
it brings ``lo`` up, refuses to run if any other interface exists, and points every
participant (its own and its children's) at Cyclone's loopback configuration (the loopback
interface, multicast off, 127.0.0.1 the only peer): no DDS packet can leave the machine.
It prints one JSON object (the case's observations) on stdout. Every wait has a deadline.

Cases: ``loop`` (closed loop on youbot_circle), ``integration`` (the same without odometry),
``tiago`` (closed loop on TIAGo's URDF, differential base, the shipped ``tiago`` configuration),
``watchdog`` (robot killed, restarted, then
the node stopped by SIGINT), ``fuzz`` (malformed messages on every input topic).
"""


import json
import math
import os
import random
import signal
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated

SCENARIO, CONFIG = "youbot_circle", "youbot"
ARM, BASE, STATES, ODOM, TARGET = "/arm_velocity_controller/commands", "/cmd_vel", "/joint_states", "/odom", \
    "/wbc/ee_target"
DEADLINE = 90.0  #: [s] longest wait for anything (first start includes numba's compile on a fresh machine)


def isolate() -> None:
    """Bring ``lo`` up in this (private) network namespace, refusing to run if any other interface
    exists; every participant of this process and its children on Cyclone's loopback configuration."""
    from wbc.ros.dds import LOOPBACK_CONFIG, loopback_only

    loopback_only()
    os.environ["CYCLONEDDS_URI"] = LOOPBACK_CONFIG
    os.environ.pop("ROS_DOMAIN_ID", None)


SPAWNED: list[subprocess.Popen[str]] = []


def spawn(*args: str) -> subprocess.Popen[str]:
    process = subprocess.Popen([sys.executable, *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    SPAWNED.append(process)
    return process


def node(*extra: str, config: str = CONFIG, scenario: str = SCENARIO) -> subprocess.Popen[str]:
    return spawn("-m", "wbc", "ros", scenario, "--config", config, "--json", *extra)


def robot(config: str = CONFIG, scenario: str = SCENARIO) -> subprocess.Popen[str]:
    return spawn("-m", "wbc.ros.simulated", scenario, "--config", config)


def finish(process: subprocess.Popen[str], sig: int | None = signal.SIGTERM) -> dict[str, object]:
    """Signal ``process`` (if given and still running), wait for it; its exit code, JSON output and stderr tail."""
    if sig is not None and process.poll() is None:
        process.send_signal(sig)
    try:
        out, err = process.communicate(timeout=30)
    except subprocess.TimeoutExpired:
        process.kill()
        out, err = process.communicate()
        return {"returncode": "hung", "stderr": err[-20000:]}
    try:
        output = json.loads(out) if out.strip() else None
    except json.JSONDecodeError:
        output = out[-2000:]
    return {"returncode": process.returncode, "output": output, "stderr": err[-20000:]}


@dataclass
class Command:
    """One complete command seen on the wire: the arm's velocities and the base twist (vx, vy, wz)."""

    time: float
    arm: list[float]
    base: tuple[float, float, float]

    @property
    def zero(self) -> bool:
        return not any(self.arm) and not any(self.base)


@dataclass
class Observer:
    """A participant reading every command the node writes for ``scenario`` under ``config`` and
    checking each against the robot's limits (formulas written out here: |v_i| <= limit of each
    commanded joint; the base twist within the base's speed limits, and no lateral speed for a
    differential base; each wheel's speed within its limit: mecanum u = W^-1 (vx, vy, wz),
    differential u = (vx -+ half_track wz) / radius)."""

    scenario: str = SCENARIO
    config: str = CONFIG
    commands: list[Command] = field(default_factory=list)
    unsafe: list[str] = field(default_factory=list)

    def __post_init__(self) -> None:
        import numpy as np

        from wbc.app.scenario import load_scenario
        from wbc.ros.config import load_config
        from wbc.ros.dds import Participant
        from wbc.ros.messages import Float64MultiArray, Twist

        scenario = load_scenario(self.scenario)
        robot = scenario.robot
        wiring = load_config(self.config, robot, scenario.tasks)
        self.participant = Participant()
        self.readers = [self.participant.reader(c.topic, Float64MultiArray) for c in wiring.controllers]
        self.base_reader = self.participant.reader(wiring.base.topic, Twist)
        self.joint_limit = np.concatenate([robot.velocity_limit[c.v_indices] for c in wiring.controllers])
        base = robot.base
        self.base_limit = np.array([base.max_linear_speed, base.max_linear_speed, base.max_yaw_rate])
        self.wheels, self.differential = base.wheels, base.kind.name in ("UNICYCLE", "DIFFERENTIAL")
        self._pending: list[list[list[float]]] = [[] for _ in self.readers]  # per controller, not yet paired
        self._np = np

    def poll(self) -> None:
        from wbc.ros.dds import take_one

        for reader, pending in zip(self.readers, self._pending, strict=True):
            while True:
                sample, more = take_one(reader)
                if not more:
                    break
                if sample is not None:
                    pending.append(list(sample.data))
        while all(self._pending):  # (each tick writes every controller's command, then the base's)
            sample, more = take_one(self.base_reader)
            if not more:
                break
            if sample is not None:
                base = (sample.linear.x, sample.linear.y, sample.angular.z)
                joints = [value for pending in self._pending for value in pending.pop(0)]
                self._check(joints, base)
                self.commands.append(Command(time.monotonic(), joints, base))

    def _check(self, joints: list[float], base: tuple[float, float, float]) -> None:
        np = self._np
        values = np.array([*base, *joints])
        if not np.all(np.isfinite(values)):
            self.unsafe.append(f"non-finite command {values.tolist()}")
            return
        tolerance = 1 + 1e-9
        if len(joints) != self.joint_limit.size or np.any(np.abs(joints) > self.joint_limit * tolerance):
            self.unsafe.append(f"joint command {joints} beyond {self.joint_limit.tolist()}")
        if np.any(np.abs(base) > self.base_limit * tolerance):
            self.unsafe.append(f"base twist {base} beyond {self.base_limit.tolist()}")
        vx, vy, wz = base
        if self.differential:
            if vy != 0.0:
                self.unsafe.append(f"a lateral speed {vy} for a differential base")
            wheels = np.array([vx - self.wheels.half_track * wz, vx + self.wheels.half_track * wz]) / self.wheels.radius
        else:
            wheels = self.wheels.inverse_matrix() @ np.array(base)
        if np.any(np.abs(wheels) > self.wheels.max_speed * tolerance):
            self.unsafe.append(f"wheel speeds {wheels.tolist()} beyond {self.wheels.max_speed}")

    def wait(self, condition, timeout: float = DEADLINE, what: str = "") -> bool:
        """Poll until ``condition()`` (True) or ``timeout`` [s] (False)."""
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            self.poll()
            if condition():
                return True
            time.sleep(0.001)
        return False

    def moving(self, since: int = 0, count: int = 50) -> bool:
        """At least ``count`` non-zero commands after the first ``since``."""
        return sum(not c.zero for c in self.commands[since:]) >= count


def case_loop(duration: float = 6.0, config: str = CONFIG, scenario: str = SCENARIO) -> dict[str, object]:
    from wbc.ros.messages import DiagnosticArray

    observer = Observer(scenario, config)
    diagnostics_reader = observer.participant.reader("/diagnostics", DiagnosticArray)
    diagnostics = []
    sim = robot(config, scenario)
    ros = node("--duration", str(duration), config=config, scenario=scenario)
    graph = _graph(observer)

    def ended() -> bool:
        for sample in diagnostics_reader.take(16):
            if sample.sample_info.valid_data:
                status = sample.status[0]
                diagnostics.append({"level": status.level, "name": status.name, "message": status.message,
                                    "values": {value.key: value.value for value in status.values}})
        return ros.poll() is not None

    done = observer.wait(ended, DEADLINE + duration)
    observer.poll()
    return {"node": finish(ros, None if done else signal.SIGTERM), "robot": finish(sim),
            "commands": len(observer.commands), "unsafe": observer.unsafe[:20], "diagnostics": diagnostics,
            "graph": graph}


def _graph(observer: Observer) -> dict[str, object]:
    """What the node announces on ros_discovery_info, and the GUIDs DDS discovery reports for the
    endpoints of its topics: {"nodes": [...], "participant", "writers": {topic: [guid hex]}, "readers"}."""
    from cyclonedds.builtin import BuiltinDataReader, BuiltinTopicDcpsPublication, BuiltinTopicDcpsSubscription
    from cyclonedds.core import Qos
    from cyclonedds.qos import Policy
    from cyclonedds.sub import DataReader
    from cyclonedds.topic import Topic

    from wbc.ros.dds import DISCOVERY_TOPIC
    from wbc.ros.messages import ParticipantEntitiesInfo

    domain = observer.participant.participant
    reader = DataReader(domain, Topic(domain, DISCOVERY_TOPIC, ParticipantEntitiesInfo),
                        Qos(Policy.Reliability.Reliable(0), Policy.Durability.TransientLocal,
                            Policy.History.KeepLast(1), Policy.DataRepresentation(use_cdrv0_representation=True)))
    publications, subscriptions = (BuiltinDataReader(domain, BuiltinTopicDcpsPublication),
                                   BuiltinDataReader(domain, BuiltinTopicDcpsSubscription))
    infos: list = []
    endpoints: dict[str, dict[str, list[str]]] = {"writers": {}, "readers": {}}
    participants: dict[str, str] = {}

    def announced() -> bool:
        infos.extend(sample for sample in reader.take(8) if sample.sample_info.valid_data)
        for kind, builtin in (("writers", publications), ("readers", subscriptions)):
            for endpoint in builtin.take(64):
                if endpoint.sample_info.valid_data and endpoint.topic_name.startswith("rt/"):
                    endpoints[kind].setdefault(endpoint.topic_name, []).append(endpoint.key.hex)
                    participants[endpoint.key.hex] = endpoint.participant_key.hex
        return any(info.node_entities_info_seq for info in infos) and "rt/diagnostics" in endpoints["writers"]

    observer.wait(announced, DEADLINE)
    observer.wait(lambda: announced() and False, 0.5)  # the rest of discovery
    nodes = [{"participant": bytes(info.gid.data).hex(), "namespace": node.node_namespace, "name": node.node_name,
              "readers": [bytes(g.data).hex() for g in node.reader_gid_seq],
              "writers": [bytes(g.data).hex() for g in node.writer_gid_seq]}
             for info in infos for node in info.node_entities_info_seq]
    return {"nodes": nodes, "endpoints": endpoints, "participants": participants}


def case_integration() -> dict[str, object]:
    """The loop with no odometry: the node integrates its own base commands."""
    import tempfile

    from wbc.ros.config import config_file

    text = config_file(CONFIG).read_text()
    assert 'odometry = "/odom"' in text
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "no_odometry.toml"
        path.write_text(text.replace('odometry = "/odom"', ""))
        return case_loop(config=str(path))


#: TIAGo's URDF on a declared differential base, its hand and head locked (docs/ros.md)
TIAGO_SIDECAR = """name = "tiago"
urdf = "{urdf}"
end_effector = "arm_tool_link"

[base]
kind = "differential"
lock = {locked}
max_linear_speed = 1.0
max_yaw_rate = 1.0

[base.wheels]
joints = ["wheel_left_joint", "wheel_right_joint"]
"""

#: the tool to a point 2 m to the left of where it starts (the platform must turn and drive)
TIAGO_SCENARIO = """name = "tiago_reach"

[robot]
name = "tiago.toml"

[controller]
dt = 0.01
duration = 6.0

[[tasks]]
type = "PositionTask"
frame = "arm_tool_link"
gain = 0.5
max_speed = 0.5

[[tasks]]
type = "DampingTask"
cost = 1e-3

[[constraints]]
type = "JointPositionLimits"

[[constraints]]
type = "JointVelocityLimits"

[[constraints]]
type = "NonholonomicBase"

[[constraints]]
type = "WheelSpeedLimits"

[reference]
type = "point"
position = [0.108, 1.2195, 0.7065]
"""


def tiago_scenario(folder: str) -> str:
    """Write TIAGo's sidecar and scenario (the URDF of the installed example-robot-data) into
    ``folder``; the scenario's path."""
    import importlib.metadata
    import xml.etree.ElementTree as ElementTree

    urdf = Path(str(importlib.metadata.distribution("example-robot-data").locate_file(
        "cmeel.prefix/share/example-robot-data/robots/tiago_description/robots/tiago.urdf")))
    locked = sorted({joint.get("name") for joint in ElementTree.parse(urdf).getroot().findall("joint")
                     if joint.get("type") != "fixed" and joint.get("name").startswith(("hand_", "head_"))})
    (Path(folder) / "tiago.toml").write_text(TIAGO_SIDECAR.format(urdf=urdf, locked=json.dumps(locked)))
    scenario = Path(folder) / "tiago_reach.toml"
    scenario.write_text(TIAGO_SCENARIO)
    return str(scenario)


def case_tiago() -> dict[str, object]:
    """The closed loop on TIAGo (differential base) with the shipped tiago configuration."""
    import tempfile

    with tempfile.TemporaryDirectory() as folder:
        scenario = tiago_scenario(folder)
        result = case_loop(config="tiago", scenario=scenario)
        result["scenario"] = (Path(scenario).parent / "tiago.toml").read_text(), Path(scenario).read_text()
        return result


def case_watchdog() -> dict[str, object]:
    observer = Observer()
    sim = robot()
    ros = node()
    result: dict[str, object] = {}
    result["controlled"] = observer.wait(lambda: observer.moving(0, 100))
    sim.kill()  # SIGKILL: the robot vanishes without a word
    killed = time.monotonic()
    before = len(observer.commands)
    result["zero_after_kill"] = observer.wait(lambda: any(c.zero for c in observer.commands[before:]), 10.0)
    zeros = [c for c in observer.commands[before:] if c.zero]
    result["reaction_s"] = zeros[0].time - killed if zeros else None
    result["nonzero_after_zero"] = sum(not c.zero for c in observer.commands[before:]
                                       if zeros and c.time > zeros[0].time)
    held = len(observer.commands)
    observer.wait(lambda: False, 1.0)  # one second of silence from the robot
    result["commands_while_stale"] = len(observer.commands) - held
    result["robot_killed"] = finish(sim, None)["returncode"]
    sim = robot()  # fresh states: the node resumes
    resumed_from = len(observer.commands)
    result["resumed"] = observer.wait(lambda: observer.moving(resumed_from, 50), 30.0)
    before = len(observer.commands)
    ros.send_signal(signal.SIGINT)
    ended = observer.wait(lambda: ros.poll() is not None, 10.0)
    observer.wait(lambda: False, 0.2)
    after = observer.commands[before:]
    result["after_sigint"] = [c.zero for c in after]
    result["node"] = finish(ros, None if ended else signal.SIGKILL)
    result["robot"] = finish(sim)
    result["unsafe"] = observer.unsafe[:20]
    return result


def _fuzz_messages(rng: random.Random):
    """Malformed (and merely strange) messages for every input topic, forever: (topic, message)."""
    from wbc.ros import messages as m

    names = ["arm_joint_1", "arm_joint_2", "arm_joint_3", "arm_joint_4", "arm_joint_5", "wheel", "", "ärm"]
    specials = [math.nan, math.inf, -math.inf, 1e308, -1e308, 0.0, 1e-320, 3.0]

    def number() -> float:
        return rng.choice(specials) if rng.random() < 0.5 else rng.uniform(-10, 10)

    def stamp() -> m.Time:
        return m.Time(sec=rng.choice([0, 1, 2**31 - 1, -5, int(time.time())]),
                      nanosec=rng.choice([0, 999_999_999, 1_000_000_000, 2**32 - 1]))

    while True:
        kind = rng.randrange(3)
        if kind == 0:
            count = rng.randrange(0, 8)
            chosen = [rng.choice(names) for _ in range(count)]
            length = max(0, count + rng.choice([0, 0, -1, 1]))
            message = m.JointState(header=m.Header(stamp=stamp(), frame_id=rng.choice(["", "x"])), name=chosen,
                                   position=[number() for _ in range(length)],
                                   velocity=[number() for _ in range(rng.choice([0, count, count + 2]))],
                                   effort=[])
            yield STATES, message
        elif kind == 1:
            message = m.Odometry(header=m.Header(stamp=stamp(), frame_id=rng.choice(["odom", "map", ""])))
            message.pose.pose.position.x, message.pose.pose.position.y = number(), number()
            o = message.pose.pose.orientation
            o.x, o.y, o.z, o.w = number(), number(), number(), number()
            yield ODOM, message
        else:
            message = m.PoseStamped(header=m.Header(stamp=stamp(), frame_id=rng.choice(["odom", "base_link"])))
            message.pose.position.x, message.pose.position.y, message.pose.position.z = number(), number(), number()
            o = message.pose.orientation
            o.x, o.y, o.z, o.w = rng.choice([(0.0, 0.0, 0.0, 1.0), (number(), number(), number(), number())])
            yield TARGET, message


def case_fuzz(seconds: float = 3.0, seed: int = 27) -> dict[str, object]:
    import cyclonedds.idl.types as idl
    from cyclonedds.idl import IdlStruct

    from wbc.ros import messages as m

    @dataclass
    class NotAJointState(IdlStruct, typename="sensor_msgs::msg::dds_::JointState_"):
        """Bytes under JointState's name that are no JointState (what a wrong type support sends)."""

        blob: Annotated[list[int], idl.sequence(idl.uint8)]

    observer = Observer()
    sim = robot()
    ros = node()
    result: dict[str, object] = {"controlled": observer.wait(lambda: observer.moving(0, 50))}
    from wbc.ros.dds import Participant

    # the fuzzer: its own process's participant is the observer's; the raw writer needs another (its
    # topic has JointState's name with another type)
    writers = {STATES: observer.participant.writer(STATES, m.JointState, reliable=False, depth=5),
               ODOM: observer.participant.writer(ODOM, m.Odometry, reliable=False, depth=5),
               TARGET: observer.participant.writer(TARGET, m.PoseStamped)}
    from cyclonedds.core import Qos
    from cyclonedds.pub import DataWriter
    from cyclonedds.qos import Policy
    from cyclonedds.topic import Topic

    raw_participant = Participant()
    raw = DataWriter(raw_participant.participant, Topic(raw_participant.participant, "rt" + STATES, NotAJointState),
                     Qos(Policy.Reliability.BestEffort, Policy.History.KeepLast(5),
                         Policy.DataRepresentation(use_cdrv0_representation=True)))
    rng = random.Random(seed)
    messages = _fuzz_messages(rng)
    sent = raw_sent = 0
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        topic, message = next(messages)
        try:
            writers[topic].write(message)
            sent += 1
        except Exception:  # (a message cyclonedds refuses to serialize, e.g. a negative uint: never sent)
            pass
        if rng.random() < 0.2:
            raw.write(NotAJointState(blob=[rng.randrange(256) for _ in range(rng.randrange(0, 64))]))
            raw_sent += 1
        observer.poll()
        time.sleep(0.0005)
    result["sent"], result["raw_sent"] = sent, raw_sent
    result["alive_after_fuzz"] = ros.poll() is None
    # the fuzz set targets from the wire: the node follows them now; it must still command the robot
    resumed_from = len(observer.commands)
    result["commands_after_fuzz"] = observer.wait(lambda: len(observer.commands) - resumed_from >= 20, 30.0)
    before = len(observer.commands)
    ros.send_signal(signal.SIGTERM)  # (the watchdog case stops the node with SIGINT)
    observer.wait(lambda: ros.poll() is not None, 10.0)
    observer.wait(lambda: False, 0.2)
    result["last_is_zero"] = bool(observer.commands[before:]) and observer.commands[-1].zero
    result["node"] = finish(ros, signal.SIGKILL)
    result["robot"] = finish(sim)
    result["unsafe"] = observer.unsafe[:20]
    raw_participant.close()
    return result


def main() -> None:
    isolate()
    case = sys.argv[1]
    try:
        result = {"loop": case_loop, "integration": case_integration, "watchdog": case_watchdog,
                  "fuzz": case_fuzz, "tiago": case_tiago}[case]()
    finally:
        for process in SPAWNED:  # whatever a failed case left running
            if process.poll() is None:
                process.kill()
                process.wait()
    print(json.dumps(result))


if __name__ == "__main__":
    main()
