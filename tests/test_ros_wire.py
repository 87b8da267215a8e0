"""The ROS 2 wire format of the node's messages (wbc.ros.messages), against rosbags -- an
independent, pure-Python implementation of ROS 2's CDR and of REP 2011's RIHS01 type hashes:
for every type the node sends or receives, the serialized bytes (encapsulation header
included) and the type hash equal rosbags', and the DDS names follow ROS 2's mapping."""

from __future__ import annotations

import math

import pytest

pytest.importorskip("cyclonedds", reason='the ROS 2 node needs cyclonedds: pip install "wbc[ros]"')
pytest.importorskip("rosbags", reason='the wire oracle is rosbags: pip install "wbc[test]"')

from rosbags.typesys import Stores, get_typestore  # noqa: E402

from wbc.ros import messages as m  # noqa: E402
from wbc.ros.errors import RosConfigError  # noqa: E402
from wbc.ros.names import dds_topic, resolve_topic  # noqa: E402
from wbc.ros.type_hash import type_hash, user_data  # noqa: E402

STORE = get_typestore(Stores.ROS2_JAZZY)
#: the types the node sends or receives (and, as fields, every type they contain)
WIRE_TYPES = [m.JointState, m.Odometry, m.PoseStamped, m.Twist, m.TwistStamped, m.Float64MultiArray,
              m.DiagnosticArray, m.ParticipantEntitiesInfo]


def _pair(build) -> tuple[object, object]:
    """The same message built with wbc.ros.messages and with rosbags' classes (``build(make)``,
    ``make(ros_name, **fields)``; sequences of floats become numpy arrays for rosbags)."""
    import numpy as np

    def ours(name, /, **fields):
        return getattr(m, name.rsplit("/", 1)[1])(**fields)

    def theirs(name, /, **fields):
        cls = STORE.types[name]
        converted = {}
        for key, value in fields.items():
            if isinstance(value, list) and value and isinstance(value[0], float):
                value = np.array(value, dtype=np.float64)
            elif isinstance(value, list) and not value and key in ("position", "velocity", "effort", "data"):
                value = np.array([], dtype=np.float64)
            converted[key] = value
        if name == "rmw_dds_common/msg/Gid":
            return cls(data=np.array(fields["data"], dtype=np.uint8))
        if name == "builtin_interfaces/msg/Time":
            return cls(sec=fields.get("sec", 0), nanosec=fields.get("nanosec", 0))
        return cls(**converted)

    return build(ours), build(theirs)


def _time(make, sec=1_700_000_123, nanosec=987_654_321):
    return make("builtin_interfaces/msg/Time", sec=sec, nanosec=nanosec)


def _header(make, frame="odom", **stamp):
    return make("std_msgs/msg/Header", stamp=_time(make, **stamp), frame_id=frame)


def _vector(make, name, x, y, z):
    return make(name, x=x, y=y, z=z)


def _twist(make, a=0.25, b=-1.5, c=3.0):
    return make("geometry_msgs/msg/Twist", linear=_vector(make, "geometry_msgs/msg/Vector3", a, b, 0.0),
                angular=_vector(make, "geometry_msgs/msg/Vector3", 0.0, -0.0, c))


def _pose(make):
    return make("geometry_msgs/msg/Pose", position=_vector(make, "geometry_msgs/msg/Point", 1.0, -2.0, 0.5),
                orientation=make("geometry_msgs/msg/Quaternion", x=0.0, y=0.0, z=math.sin(0.3), w=math.cos(0.3)))


SAMPLES = {
    # odd-length names and frame ids: the alignment of what follows each string is exercised
    "sensor_msgs/msg/JointState": lambda make: make(
        "sensor_msgs/msg/JointState", header=_header(make, "base"), name=["arm_joint_1", "j", "wheel_fl"],
        position=[0.1, -2.5, 1e-300], velocity=[], effort=[1.0, 2.0, 3.0]),
    "sensor_msgs/msg/JointState (empty)": lambda make: make(
        "sensor_msgs/msg/JointState", header=_header(make, "", sec=0, nanosec=0), name=[], position=[],
        velocity=[], effort=[]),
    "nav_msgs/msg/Odometry": lambda make: make(
        "nav_msgs/msg/Odometry", header=_header(make, "odom"), child_frame_id="base_footprint",
        pose=make("geometry_msgs/msg/PoseWithCovariance", pose=_pose(make),
                  covariance=[float(k) / 7 for k in range(36)]),
        twist=make("geometry_msgs/msg/TwistWithCovariance", twist=_twist(make),
                   covariance=[-float(k) for k in range(36)])),
    "geometry_msgs/msg/PoseStamped": lambda make: make(
        "geometry_msgs/msg/PoseStamped", header=_header(make, "odom"), pose=_pose(make)),
    "geometry_msgs/msg/Twist": _twist,
    "geometry_msgs/msg/TwistStamped": lambda make: make(
        "geometry_msgs/msg/TwistStamped", header=_header(make, "base_link"), twist=_twist(make)),
    "std_msgs/msg/Float64MultiArray": lambda make: make(
        "std_msgs/msg/Float64MultiArray", layout=make(
            "std_msgs/msg/MultiArrayLayout", dim=[make("std_msgs/msg/MultiArrayDimension", label="joints", size=5,
                                                       stride=5)], data_offset=0),
        data=[0.5, -0.25, 1e-3, 0.0, 3.25]),
    "diagnostic_msgs/msg/DiagnosticArray": lambda make: make(
        "diagnostic_msgs/msg/DiagnosticArray", header=_header(make, ""), status=[make(
            "diagnostic_msgs/msg/DiagnosticStatus", level=1, name="/wbc", message="watchdog: état périmé",
            hardware_id="", values=[make("diagnostic_msgs/msg/KeyValue", key="latency_p50_us", value="123.4"),
                                    make("diagnostic_msgs/msg/KeyValue", key="k", value="")])]),
    "rmw_dds_common/msg/ParticipantEntitiesInfo": lambda make: make(
        "rmw_dds_common/msg/ParticipantEntitiesInfo", gid=make("rmw_dds_common/msg/Gid", data=list(range(200, 216))),
        node_entities_info_seq=[make(
            "rmw_dds_common/msg/NodeEntitiesInfo", node_namespace="/r1", node_name="wbc",
            reader_gid_seq=[make("rmw_dds_common/msg/Gid", data=[k] * 16) for k in (1, 255)],
            writer_gid_seq=[make("rmw_dds_common/msg/Gid", data=list(range(16)))])]),
}


def _ros_name(key: str) -> str:
    return key.split(" ")[0]


@pytest.mark.parametrize("key", SAMPLES)
def test_serialized_bytes_equal_rosbags(key):
    ours, theirs = _pair(SAMPLES[key])
    expected = STORE.serialize_cdr(theirs, _ros_name(key))
    assert expected[:4] == b"\x00\x01\x00\x00"  # plain CDR, little endian: what ROS 2 writes
    assert ours.serialize() == expected


@pytest.mark.parametrize("key", SAMPLES)
def test_rosbags_bytes_read_back_as_the_message(key):
    """What a ROS 2 publisher writes (rosbags' bytes) deserializes to the same message here."""
    ours, theirs = _pair(SAMPLES[key])
    expected = STORE.serialize_cdr(theirs, _ros_name(key))
    decoded = type(ours).deserialize(expected)
    assert decoded.serialize() == expected
    if "rmw_dds_common" not in key:  # (there, cyclonedds reads the uint8[16] GIDs back as bytes)
        assert decoded == ours


@pytest.mark.parametrize("message", WIRE_TYPES + [m.Header, m.Time, m.Pose, m.Vector3, m.KeyValue,
                                                  m.DiagnosticStatus, m.MultiArrayLayout, m.Gid])
def test_names_and_type_hash_match_ros2(message):
    ros_name = m.ROS_NAMES[message]
    package, kind, name = ros_name.split("/")
    assert message.__idl_typename__ == f"{package}::{kind}::dds_::{name}_"
    assert ros_name in STORE.types
    assert type_hash(message) == STORE.hash_rihs01(ros_name)
    assert user_data(message) == f"typehash={STORE.hash_rihs01(ros_name)};".encode()


def test_known_type_hashes():
    """Two hashes as ``ros2 topic info -v`` prints them on Jazzy (written out: a third oracle)."""
    assert type_hash(m.Twist) == "RIHS01_9c45bf16fe0983d80e3cfe750d6835843d265a9a6c46bd2e609fcddde6fb8d2a"
    assert type_hash(m.JointState) == "RIHS01_a13ee3a330e346c9d87b5aa18d24e11690752bd33a0350f11c5882bc9179260e"


@pytest.mark.parametrize(("name", "namespace", "expected"), [
    ("/joint_states", "/", "/joint_states"), ("joint_states", "/", "/joint_states"),
    ("joint_states", "/robot1", "/robot1/joint_states"), ("~/ee/target", "/", "/wbc/ee/target"),
    ("~/ee/target", "robot1", "/robot1/wbc/ee/target"), ("/a/b", "/robot1", "/a/b")])
def test_topic_names_resolve_as_ros2(name, namespace, expected):
    assert resolve_topic(name, namespace, "wbc") == expected
    assert dds_topic(expected) == "rt" + expected


@pytest.mark.parametrize("bad", ["", "/", "a//b", "a/", "1abc", "a-b", "/a/1b", "~x"])
def test_bad_topic_names_are_refused(bad):
    with pytest.raises(RosConfigError, match="not a ROS 2 topic name"):
        resolve_topic(bad)
