"""The ROS 2 messages the node sends and receives, as DDS types.

ROS 2 maps message ``pkg/msg/T`` to the DDS type ``pkg::msg::dds_::T_``: a *final* struct of
the message's fields in their ``.msg`` order, serialized as plain CDR (XCDR1) behind the
little-endian encapsulation header ``00 01 00 00``. Each class below is that struct, declared
for ``cyclonedds`` with the fields, types and order of the ROS 2 Jazzy message definition
(unchanged since Humble for every type here); ``tests/test_ros_wire.py`` compares the bytes
of each with those of ``rosbags``, an independent implementation, and its RIHS01 type hash
(:mod:`wbc.ros.type_hash`) with the one ROS 2 computes.

Field types are written ``Annotated[python type, cyclonedds type]``: cyclonedds reads the
second argument, type checkers the first. (No ``from __future__ import annotations`` here:
cyclonedds resolves string annotations in this module's namespace, where ``str`` is not.)
"""

from dataclasses import dataclass, field
from typing import Annotated

import cyclonedds.idl.types as idl
from cyclonedds.idl import IdlStruct

Float64Sequence = Annotated[list[float], idl.sequence(idl.float64)]
StringSequence = Annotated[list[str], idl.sequence(str)]
Covariance = Annotated[list[float], idl.array(idl.float64, 36)]


def _covariance() -> list[float]:
    return [0.0] * 36


# ------------------------------------------------------------------------------ builtin_interfaces
@dataclass
class Time(IdlStruct, typename="builtin_interfaces::msg::dds_::Time_"):
    """``builtin_interfaces/msg/Time``: seconds and nanoseconds since the epoch of the clock."""

    sec: idl.int32 = 0
    nanosec: idl.uint32 = 0


# ------------------------------------------------------------------------------------- std_msgs
@dataclass
class Header(IdlStruct, typename="std_msgs::msg::dds_::Header_"):
    """``std_msgs/msg/Header``."""

    stamp: Time = field(default_factory=Time)
    frame_id: str = ""


@dataclass
class MultiArrayDimension(IdlStruct, typename="std_msgs::msg::dds_::MultiArrayDimension_"):
    """``std_msgs/msg/MultiArrayDimension``."""

    label: str = ""
    size: idl.uint32 = 0
    stride: idl.uint32 = 0


@dataclass
class MultiArrayLayout(IdlStruct, typename="std_msgs::msg::dds_::MultiArrayLayout_"):
    """``std_msgs/msg/MultiArrayLayout``."""

    dim: Annotated[list[MultiArrayDimension], idl.sequence(MultiArrayDimension)] = field(default_factory=list)
    data_offset: idl.uint32 = 0


@dataclass
class Float64MultiArray(IdlStruct, typename="std_msgs::msg::dds_::Float64MultiArray_"):
    """``std_msgs/msg/Float64MultiArray``: what ros2_control's ``JointGroupVelocityController``
    reads on ``/<controller>/commands`` (one velocity per joint of the controller, in its order)."""

    layout: MultiArrayLayout = field(default_factory=MultiArrayLayout)
    data: Float64Sequence = field(default_factory=list)


# ---------------------------------------------------------------------------------- sensor_msgs
@dataclass
class JointState(IdlStruct, typename="sensor_msgs::msg::dds_::JointState_"):
    """``sensor_msgs/msg/JointState``: positions [rad or m] by joint name."""

    header: Header = field(default_factory=Header)
    name: StringSequence = field(default_factory=list)
    position: Float64Sequence = field(default_factory=list)
    velocity: Float64Sequence = field(default_factory=list)
    effort: Float64Sequence = field(default_factory=list)


# -------------------------------------------------------------------------------- geometry_msgs
@dataclass
class Vector3(IdlStruct, typename="geometry_msgs::msg::dds_::Vector3_"):
    """``geometry_msgs/msg/Vector3``."""

    x: idl.float64 = 0.0
    y: idl.float64 = 0.0
    z: idl.float64 = 0.0


@dataclass
class Point(IdlStruct, typename="geometry_msgs::msg::dds_::Point_"):
    """``geometry_msgs/msg/Point``."""

    x: idl.float64 = 0.0
    y: idl.float64 = 0.0
    z: idl.float64 = 0.0


@dataclass
class Quaternion(IdlStruct, typename="geometry_msgs::msg::dds_::Quaternion_"):
    """``geometry_msgs/msg/Quaternion`` (x, y, z, w); the default is the identity."""

    x: idl.float64 = 0.0
    y: idl.float64 = 0.0
    z: idl.float64 = 0.0
    w: idl.float64 = 1.0


@dataclass
class Pose(IdlStruct, typename="geometry_msgs::msg::dds_::Pose_"):
    """``geometry_msgs/msg/Pose``."""

    position: Point = field(default_factory=Point)
    orientation: Quaternion = field(default_factory=Quaternion)


@dataclass
class PoseStamped(IdlStruct, typename="geometry_msgs::msg::dds_::PoseStamped_"):
    """``geometry_msgs/msg/PoseStamped``: a target pose of a frame, in ``header.frame_id``."""

    header: Header = field(default_factory=Header)
    pose: Pose = field(default_factory=Pose)


@dataclass
class Twist(IdlStruct, typename="geometry_msgs::msg::dds_::Twist_"):
    """``geometry_msgs/msg/Twist``: linear [m/s] and angular [rad/s] velocity."""

    linear: Vector3 = field(default_factory=Vector3)
    angular: Vector3 = field(default_factory=Vector3)


@dataclass
class TwistStamped(IdlStruct, typename="geometry_msgs::msg::dds_::TwistStamped_"):
    """``geometry_msgs/msg/TwistStamped`` (what ros2_controllers' drive controllers read since Jazzy)."""

    header: Header = field(default_factory=Header)
    twist: Twist = field(default_factory=Twist)


@dataclass
class PoseWithCovariance(IdlStruct, typename="geometry_msgs::msg::dds_::PoseWithCovariance_"):
    """``geometry_msgs/msg/PoseWithCovariance``."""

    pose: Pose = field(default_factory=Pose)
    covariance: Covariance = field(default_factory=_covariance)


@dataclass
class TwistWithCovariance(IdlStruct, typename="geometry_msgs::msg::dds_::TwistWithCovariance_"):
    """``geometry_msgs/msg/TwistWithCovariance``."""

    twist: Twist = field(default_factory=Twist)
    covariance: Covariance = field(default_factory=_covariance)


# ------------------------------------------------------------------------------------ nav_msgs
@dataclass
class Odometry(IdlStruct, typename="nav_msgs::msg::dds_::Odometry_"):
    """``nav_msgs/msg/Odometry``: the base pose in ``header.frame_id`` (the odometry frame)."""

    header: Header = field(default_factory=Header)
    child_frame_id: str = ""
    pose: PoseWithCovariance = field(default_factory=PoseWithCovariance)
    twist: TwistWithCovariance = field(default_factory=TwistWithCovariance)


# ---------------------------------------------------------------------------- diagnostic_msgs
@dataclass
class KeyValue(IdlStruct, typename="diagnostic_msgs::msg::dds_::KeyValue_"):
    """``diagnostic_msgs/msg/KeyValue``."""

    key: str = ""
    value: str = ""


@dataclass
class DiagnosticStatus(IdlStruct, typename="diagnostic_msgs::msg::dds_::DiagnosticStatus_"):
    """``diagnostic_msgs/msg/DiagnosticStatus``; ``level`` is OK 0, WARN 1, ERROR 2, STALE 3."""

    level: idl.byte = 0
    name: str = ""
    message: str = ""
    hardware_id: str = ""
    values: Annotated[list[KeyValue], idl.sequence(KeyValue)] = field(default_factory=list)


@dataclass
class DiagnosticArray(IdlStruct, typename="diagnostic_msgs::msg::dds_::DiagnosticArray_"):
    """``diagnostic_msgs/msg/DiagnosticArray``: what ``/diagnostics`` carries (rqt_robot_monitor reads it)."""

    header: Header = field(default_factory=Header)
    status: Annotated[list[DiagnosticStatus], idl.sequence(DiagnosticStatus)] = field(default_factory=list)


# ----------------------------------------------------------------------------- rmw_dds_common
Bytes16 = Annotated[list[int], idl.array(idl.uint8, 16)]


def _gid() -> list[int]:
    return [0] * 16


@dataclass
class Gid(IdlStruct, typename="rmw_dds_common::msg::dds_::Gid_"):
    """``rmw_dds_common/msg/Gid``: the 16 bytes of a DDS entity's GUID (written from a list of
    ints; cyclonedds reads them back as ``bytes``)."""

    data: Bytes16 = field(default_factory=_gid)  # char[16]: see CHAR_FIELDS


@dataclass
class NodeEntitiesInfo(IdlStruct, typename="rmw_dds_common::msg::dds_::NodeEntitiesInfo_"):
    """``rmw_dds_common/msg/NodeEntitiesInfo``: a node and the GIDs of its readers and writers."""

    node_namespace: Annotated[str, idl.bounded_str(256)] = ""
    node_name: Annotated[str, idl.bounded_str(256)] = ""
    reader_gid_seq: Annotated[list[Gid], idl.sequence(Gid)] = field(default_factory=list)
    writer_gid_seq: Annotated[list[Gid], idl.sequence(Gid)] = field(default_factory=list)


@dataclass
class ParticipantEntitiesInfo(IdlStruct, typename="rmw_dds_common::msg::dds_::ParticipantEntitiesInfo_"):
    """``rmw_dds_common/msg/ParticipantEntitiesInfo``: what a ROS 2 process publishes on the DDS
    topic ``ros_discovery_info`` so that ``ros2 node list`` knows its nodes and their endpoints."""

    gid: Gid = field(default_factory=Gid)
    node_entities_info_seq: Annotated[list[NodeEntitiesInfo], idl.sequence(NodeEntitiesInfo)] = field(
        default_factory=list)


#: ROS 2 message name (``pkg/msg/T``) of each type
ROS_NAMES: dict[type[IdlStruct], str] = {
    cls: "/".join(cls.__idl_typename__.replace("::dds_::", "::").removesuffix("_").split("::"))
    for cls in (Time, Header, MultiArrayDimension, MultiArrayLayout, Float64MultiArray, JointState, Vector3, Point,
                Quaternion, Pose, PoseStamped, Twist, TwistStamped, PoseWithCovariance, TwistWithCovariance,
                Odometry, KeyValue, DiagnosticStatus, DiagnosticArray, Gid, NodeEntitiesInfo,
                ParticipantEntitiesInfo)
}

#: fields declared ``char`` in their ``.msg``: a uint8 on the wire, but its own type id in the type hash
CHAR_FIELDS: set[tuple[type[IdlStruct], str]] = {(Gid, "data")}
