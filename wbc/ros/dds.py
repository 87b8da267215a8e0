"""DDS as ROS 2 uses it (``rmw_cyclonedds``), through ``cyclonedds``: the domain and its
discovery settings, the two QoS profiles, and the readers and writers of ROS 2 topics.

* **Domain**: ``ROS_DOMAIN_ID`` (0 when unset). Discovery follows the environment variables
  of ROS 2 Jazzy as ``rmw_cyclonedds`` reads them: ``ROS_AUTOMATIC_DISCOVERY_RANGE``
  (``SUBNET``, the default: multicast discovery; ``LOCALHOST``: multicast off, this machine
  as the only peer; ``OFF``: no discovery; ``SYSTEM_DEFAULT``: Cyclone's own settings),
  ``ROS_STATIC_PEERS`` (``;``-separated addresses), the older ``ROS_LOCALHOST_ONLY=1``
  (``LOCALHOST``), then the Cyclone configuration of ``CYCLONEDDS_URI`` on top.
* **Endpoints**: every reader and writer carries the type hash in its USER_DATA
  (:func:`wbc.ros.type_hash.user_data`), keeps samples alive after the writer goes
  (no auto-dispose) and is pinned to XCDR1 (``DataRepresentation``), the encoding of ROS 2.
* **QoS**: ROS 2's default profile (reliable, volatile, keep last 10) for commands, targets and
  diagnostics; the sensor-data profile (best effort, volatile, keep last 5) for the state
  readers, which so match best-effort and reliable publishers alike.
"""

from __future__ import annotations

import fcntl
import os
import socket
import struct
from collections.abc import Mapping, Sequence
from typing import Any, TypeVar

from cyclonedds.core import DDSException, Entity, Qos
from cyclonedds.domain import Domain, DomainParticipant
from cyclonedds.idl import IdlStruct
from cyclonedds.pub import DataWriter
from cyclonedds.qos import Policy
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic

from .errors import RosError
from .messages import Gid, NodeEntitiesInfo, ParticipantEntitiesInfo
from .names import dds_topic
from .type_hash import user_data

_Message = TypeVar("_Message", bound=IdlStruct)

DEFAULT_DEPTH = 10  #: history depth of ROS 2's default QoS profile
SENSOR_DATA_DEPTH = 5  #: history depth of ROS 2's sensor-data QoS profile
#: the DDS topic (no "rt/" prefix: not a ROS topic) on which each ROS 2 process lists its nodes' endpoints
DISCOVERY_TOPIC = "ros_discovery_info"
MAX_DOMAIN_ID = 232  #: the largest DDS domain id whose ports fit (ROS 2 recommends 0-101 on Linux)
DISCOVERY_RANGES = ("SUBNET", "LOCALHOST", "OFF", "SYSTEM_DEFAULT")
#: participants discovered on one machine by unicast (rmw_cyclonedds' value)
MAX_AUTO_PARTICIPANT_INDEX = 32

#: a Cyclone configuration that keeps every packet on this machine: the loopback interface only,
#: multicast off, 127.0.0.1 the only peer (tests and benchmarks use it, in CYCLONEDDS_URI)
LOOPBACK_CONFIG = (
    "<CycloneDDS><Domain id=\"any\"><General><Interfaces><NetworkInterface address=\"127.0.0.1\"/></Interfaces>"
    "<AllowMulticast>false</AllowMulticast></General><Discovery><ParticipantIndex>auto</ParticipantIndex>"
    f"<MaxAutoParticipantIndex>{MAX_AUTO_PARTICIPANT_INDEX}</MaxAutoParticipantIndex>"
    "<Peers><Peer address=\"127.0.0.1\"/></Peers></Discovery></Domain></CycloneDDS>"
)


SIOCGIFFLAGS, SIOCSIFFLAGS, IFF_UP = 0x8913, 0x8914, 0x1  # Linux: get and set an interface's flags; "up"


def loopback_only() -> None:
    """Bring ``lo`` up in this process's network namespace and check it is the only interface
    (for tests and benchmarks run under ``unshare -rn``: then no DDS packet can leave the machine).

    Raises:
        RosError: another interface exists (not a private network namespace).
    """
    names = [name for _, name in socket.if_nameindex()]
    if names != ["lo"]:
        raise RosError(f"interfaces {names}: not a private network namespace with lo only (unshare -rn)")
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        request = struct.pack("16sh", b"lo", 0)
        flags = struct.unpack("16sh", fcntl.ioctl(sock, SIOCGIFFLAGS, request))[1]
        fcntl.ioctl(sock, SIOCSIFFLAGS, struct.pack("16sh", b"lo", flags | IFF_UP))


def domain_id(environment: Mapping[str, str]) -> int:
    """The DDS domain of ``ROS_DOMAIN_ID`` (0 when unset or empty).

    Raises:
        RosError: it is not an integer in 0..232.
    """
    text = environment.get("ROS_DOMAIN_ID", "").strip()
    if not text:
        return 0
    if not text.isdigit() or int(text) > MAX_DOMAIN_ID:
        raise RosError(f"ROS_DOMAIN_ID={text!r}: must be an integer from 0 to {MAX_DOMAIN_ID} (0-101 are safe on "
                       "Linux); use the robot's ROS_DOMAIN_ID")
    return int(text)


def domain_config(environment: Mapping[str, str]) -> str:
    """The Cyclone configuration of the domain, as ``rmw_cyclonedds`` builds it from the environment
    (see the module docstring): a fragment for the discovery range and static peers, then
    ``CYCLONEDDS_URI``; ``""`` when neither says anything.

    Raises:
        RosError: ``ROS_AUTOMATIC_DISCOVERY_RANGE`` has an unknown value.
    """
    scope = environment.get("ROS_AUTOMATIC_DISCOVERY_RANGE", "").strip().upper()
    if not scope:
        scope = "LOCALHOST" if environment.get("ROS_LOCALHOST_ONLY", "").strip() == "1" else "SUBNET"
    if scope not in DISCOVERY_RANGES:
        raise RosError(f"ROS_AUTOMATIC_DISCOVERY_RANGE={scope!r}: must be one of {', '.join(DISCOVERY_RANGES)}")
    peers = [peer.strip() for peer in environment.get("ROS_STATIC_PEERS", "").split(";") if peer.strip()]
    fragment = ""
    if scope != "SYSTEM_DEFAULT":
        multicast = scope == "SUBNET"
        if scope == "LOCALHOST":
            peers = ["localhost", *peers]
        elif scope == "OFF":
            peers = []
        if not multicast or peers:
            general = "" if multicast else "<General><AllowMulticast>false</AllowMulticast></General>"
            if scope == "OFF":  # a tag nobody else has: nothing is discovered
                discovery = f"<ParticipantIndex>none</ParticipantIndex><Tag>ros_discovery_off_{os.getpid()}</Tag>"
            else:
                discovery = ("<ParticipantIndex>auto</ParticipantIndex>"
                             f"<MaxAutoParticipantIndex>{MAX_AUTO_PARTICIPANT_INDEX}</MaxAutoParticipantIndex>")
            if peers:
                discovery += "<Peers>" + "".join(f"<Peer address=\"{peer}\"/>" for peer in peers) + "</Peers>"
            fragment = f"<CycloneDDS><Domain>{general}<Discovery>{discovery}</Discovery></Domain></CycloneDDS>"
    uri = environment.get("CYCLONEDDS_URI", "").strip()
    return ",".join(part for part in (fragment, uri) if part)


def endpoint_qos(message: type[IdlStruct], reliable: bool = True, depth: int = DEFAULT_DEPTH) -> Qos:
    """The QoS of a ROS 2 reader or writer of ``message``: ROS 2's default profile (reliable,
    volatile, keep last 10), or with ``reliable=False`` and ``depth=5`` its sensor-data profile;
    with the type hash in USER_DATA, no auto-dispose, XCDR1. A reliable writer never blocks:
    with keep-last history an old sample is replaced instead."""
    reliability = Policy.Reliability.Reliable(max_blocking_time=0) if reliable else Policy.Reliability.BestEffort
    return Qos(reliability, Policy.Durability.Volatile, Policy.History.KeepLast(depth=depth),
               Policy.Userdata(data=user_data(message)), Policy.WriterDataLifecycle(autodispose=False),
               Policy.DataRepresentation(use_cdrv0_representation=True))


_domains: dict[int, tuple[Domain, str]] = {}  # one Domain per id and process (Cyclone allows no second)


class Participant:
    """A DDS domain participant of ROS 2: joins the domain of ``ROS_DOMAIN_ID`` with the discovery
    settings of the environment (:func:`domain_config`), or those given, and makes ROS 2 readers
    and writers. Its USER_DATA is ``enclave=/;``, as a ROS 2 process's.

    Raises:
        RosError: the domain cannot be created (a bad ``CYCLONEDDS_URI``, ``ROS_DOMAIN_ID`` or
            ``ROS_AUTOMATIC_DISCOVERY_RANGE``, or another configuration of the same domain in
            this process).
    """

    def __init__(self, environment: Mapping[str, str] | None = None) -> None:
        environment = os.environ if environment is None else environment
        self.domain_id = domain_id(environment)
        self.config = domain_config(environment)
        known = _domains.get(self.domain_id)
        if known is None:
            try:
                _domains[self.domain_id] = (Domain(self.domain_id, self.config or None), self.config)
            except DDSException as exc:
                raise RosError(f"cannot create DDS domain {self.domain_id} (ROS_DOMAIN_ID) with the configuration "
                               f"{self.config or '(Cyclone defaults)'!r}: {exc}; check CYCLONEDDS_URI") from exc
        elif known[1] != self.config:
            raise RosError(f"DDS domain {self.domain_id} already exists in this process with another configuration")
        try:
            self.participant = DomainParticipant(self.domain_id, qos=Qos(Policy.Userdata(data=b"enclave=/;")))
        except DDSException as exc:
            raise RosError(f"cannot join DDS domain {self.domain_id}: {exc}; check CYCLONEDDS_URI") from exc
        self._topics: dict[str, Topic[Any]] = {}

    def _topic(self, ros_topic: str, message: type[_Message]) -> Topic[_Message]:
        topic = self._topics.get(ros_topic)
        if topic is None:
            topic = self._topics[ros_topic] = Topic(self.participant, dds_topic(ros_topic), message)
        elif topic.data_type is not message:
            raise RosError(f"topic {ros_topic} is used with two message types: {topic.data_type.__name__} and "
                           f"{message.__name__}")
        return topic

    def writer(self, ros_topic: str, message: type[_Message], reliable: bool = True,
               depth: int = DEFAULT_DEPTH) -> DataWriter[_Message]:
        """A writer of ``message`` on the fully qualified ROS 2 topic ``ros_topic`` (:func:`endpoint_qos`)."""
        return DataWriter(self.participant, self._topic(ros_topic, message), endpoint_qos(message, reliable, depth))

    def reader(self, ros_topic: str, message: type[_Message], reliable: bool = True,
               depth: int = DEFAULT_DEPTH) -> DataReader[_Message]:
        """A reader of ``message`` on the fully qualified ROS 2 topic ``ros_topic`` (:func:`endpoint_qos`)."""
        return DataReader(self.participant, self._topic(ros_topic, message), endpoint_qos(message, reliable, depth))

    def close(self) -> None:
        """Leave the domain: delete the participant and, with it, its readers and writers (the
        domain stays, for the next participant of this process)."""
        self._topics.clear()
        del self.participant


def gid(entity: Entity) -> Gid:
    """The ROS 2 GID of a DDS entity: the 16 bytes of its GUID."""
    return Gid(data=list(entity.guid.bytes))


def announce_node(participant: Participant, namespace: str, name: str, readers: Sequence[Entity],
                  writers: Sequence[Entity]) -> DataWriter[ParticipantEntitiesInfo]:
    """Publish, as a ROS 2 process does on :data:`DISCOVERY_TOPIC` (reliable, transient local, keep
    last 1: late joiners get it), that node ``namespace``/``name`` of ``participant`` owns
    ``readers`` and ``writers``: then ``ros2 node list`` lists the node and ``ros2 topic info -v``
    names it for each endpoint. Returns the writer (keep it: the announcement lives with it)."""
    info = ParticipantEntitiesInfo(gid=gid(participant.participant), node_entities_info_seq=[NodeEntitiesInfo(
        node_namespace=namespace, node_name=name, reader_gid_seq=[gid(reader) for reader in readers],
        writer_gid_seq=[gid(writer) for writer in writers])])
    qos = Qos(Policy.Reliability.Reliable(max_blocking_time=0), Policy.Durability.TransientLocal,
              Policy.History.KeepLast(depth=1), Policy.Userdata(data=user_data(ParticipantEntitiesInfo)),
              Policy.DataRepresentation(use_cdrv0_representation=True))
    writer = DataWriter(participant.participant, Topic(participant.participant, DISCOVERY_TOPIC,
                                                       ParticipantEntitiesInfo), qos)
    writer.write(info)
    return writer


def take_one(reader: DataReader[_Message]) -> tuple[_Message | None, bool]:
    """``(sample, more)``: the oldest unread sample of ``reader`` (None if it did not deserialize:
    bytes that are not the message -- dropped, it is taken all the same) and whether there was
    one at all."""
    try:
        samples = reader.take(1)
    except Exception:  # (deserialization of foreign bytes raises anything: struct.error, UnicodeError, ...)
        return None, True
    if not samples:
        return None, False
    sample = samples[0]
    return (sample if getattr(sample, "sample_info").valid_data else None), True  # noqa: B009


def source_timestamp(sample: IdlStruct) -> int:
    """The writer's timestamp [ns since the epoch] of a sample taken by :func:`take_one`."""
    return int(getattr(sample, "sample_info").source_timestamp)  # noqa: B009 (set by the reader, not declared)


def acknowledged(writer: DataWriter[Any], timeout: float) -> bool:
    """Whether every reliable reader matched by ``writer`` acknowledged its samples within ``timeout``
    [s]. (cyclonedds 11.0.1's ``wait_for_acks`` raises AttributeError on a time-out instead of
    returning False: taken as False here.)"""
    try:
        return bool(writer.wait_for_acks(int(timeout * 1e9)))
    except (AttributeError, DDSException):
        return False
