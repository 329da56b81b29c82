"""A ROS 2 domain over Cyclone DDS: one participant, its publishers and subscriptions, and the QoS ROS 2 uses.

Discovery stays on this computer unless asked otherwise: ``discovery="localhost"`` (the default, as ROS 2's
``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``) binds Cyclone to 127.0.0.1 with multicast off and 127.0.0.1 as the
only peer, so nothing leaves the machine; ``discovery="subnet"`` uses the Cyclone configuration in
``CYCLONEDDS_URI`` (or Cyclone's defaults), as a robot's other computers need. The domain id is
``ROS_DOMAIN_ID`` (0 when unset), as in ROS 2.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass
from typing import Any

from pimm_env.errors import Ros2Error
from pimm_env.ros2.messages import dds_topic_name, dds_type, from_wire, to_wire

#: Cyclone's configuration for discovery on this computer only (loopback, no multicast, one peer: itself).
LOCALHOST_CONFIG = (
    "<CycloneDDS><Domain id='any'><General><Interfaces><NetworkInterface address='127.0.0.1'/></Interfaces>"
    "<AllowMulticast>false</AllowMulticast></General><Discovery><ParticipantIndex>auto</ParticipantIndex>"
    "<MaxAutoParticipantIndex>60</MaxAutoParticipantIndex><Peers><Peer address='127.0.0.1'/></Peers></Discovery>"
    "</Domain></CycloneDDS>"
)
DISCOVERY_RANGES = ("localhost", "subnet")


@dataclass(frozen=True)
class QosProfile:
    """The QoS a ROS 2 endpoint declares: reliable or best effort, volatile or transient local, keep last N."""

    reliable: bool = True
    transient_local: bool = False
    depth: int = 10

    def policies(self) -> Any:
        from cyclonedds.core import Policy, Qos
        from cyclonedds.util import duration

        reliability = Policy.Reliability.Reliable(duration(milliseconds=100)) if self.reliable else \
            Policy.Reliability.BestEffort  # fmt: skip
        durability = Policy.Durability.TransientLocal if self.transient_local else Policy.Durability.Volatile
        return Qos(
            reliability,
            durability,
            Policy.History.KeepLast(self.depth),
            Policy.DataRepresentation(use_cdrv0_representation=True),  # XCDR1, as ROS 2 writes
        )


#: rclcpp's SystemDefaultsQoS / rmw_qos_profile_default: reliable, volatile, keep last 10
DEFAULT = QosProfile()
#: rclcpp's SensorDataQoS: best effort, volatile, keep last 5 (drivers publish clouds and scans this way)
SENSOR = QosProfile(reliable=False, depth=5)
#: a latched topic (nav2's amcl_pose and map, tf2's /tf_static): reliable, transient local, keep last 1
LATCHED = QosProfile(transient_local=True, depth=1)
#: tf2's /tf: reliable, volatile, keep last 100
TF = QosProfile(depth=100)
#: rclcpp's ClockQoS: best effort, volatile, keep last 1
CLOCK = QosProfile(reliable=False, depth=1)


def domain_id() -> int:
    """``ROS_DOMAIN_ID`` (0 when unset), checked as ROS 2 does (0-232)."""
    text = os.environ.get("ROS_DOMAIN_ID", "").strip() or "0"
    try:
        value = int(text)
    except ValueError:
        raise Ros2Error(f"ROS_DOMAIN_ID={text!r} is not an integer") from None
    if not 0 <= value <= 232:
        raise Ros2Error(f"ROS_DOMAIN_ID={value}: ROS 2 domain ids run from 0 to 232")
    return value


class Domain:
    """One DDS participant in the ROS 2 domain, with ROS 2's names for topics and types. ``publisher`` and
    ``subscription`` take ROS names (``/points``, ``sensor_msgs/msg/PointCloud2``); what is sent and received
    are ``rosbags`` messages. ``close`` ends the participant and everything it made."""

    def __init__(self, discovery: str = "localhost", domain: int | None = None) -> None:
        from cyclonedds.domain import Domain as CycloneDomain
        from cyclonedds.domain import DomainParticipant

        if discovery not in DISCOVERY_RANGES:
            raise Ros2Error(f"discovery {discovery!r}: expected one of {', '.join(DISCOVERY_RANGES)}")
        self.id = domain_id() if domain is None else domain
        # the configuration is the process's own (not CYCLONEDDS_URI) unless a wider range was asked for
        self._domain = CycloneDomain(self.id, LOCALHOST_CONFIG) if discovery == "localhost" else None
        self.participant = DomainParticipant(self.id)
        self._topics: dict[str, Any] = {}
        self.closed = False

    def _topic(self, topic: str, ros_type: str) -> Any:
        from cyclonedds.topic import Topic

        name = dds_topic_name(topic)
        if name not in self._topics:
            self._topics[name] = Topic(self.participant, name, dds_type(ros_type))
        found = self._topics[name]
        if found.data_type is not dds_type(ros_type):
            raise Ros2Error(f"{topic}: already used with another type ({found.data_type.__name__})")
        return found

    def publisher(self, topic: str, ros_type: str, qos: QosProfile = DEFAULT) -> Publisher:
        from cyclonedds.pub import DataWriter

        return Publisher(DataWriter(self.participant, self._topic(topic, ros_type), qos=qos.policies()), ros_type)

    def subscription(self, topic: str, ros_type: str, qos: QosProfile = DEFAULT) -> Subscription:
        from cyclonedds.sub import DataReader

        reader = DataReader(self.participant, self._topic(topic, ros_type), qos=qos.policies())
        return Subscription(reader, topic, ros_type)

    def close(self) -> None:
        """End the participant (its readers, writers and topics with it); a second call does nothing."""
        if self.closed:
            return
        self.closed = True
        self._topics.clear()
        self.participant.__del__()  # dds_delete: the participant and every entity it made
        if self._domain is not None:
            self._domain.__del__()

    def __enter__(self) -> Domain:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class Publisher:
    """Writes ``rosbags`` messages of one type to one topic."""

    def __init__(self, writer: Any, ros_type: str) -> None:
        self.writer, self.ros_type = writer, ros_type
        self.sent = 0

    @property
    def gid(self) -> bytes:
        return self.writer.guid.bytes

    def publish(self, msg: Any) -> None:
        self.writer.write(to_wire(msg, self.ros_type))
        self.sent += 1

    def matched(self) -> int:
        """How many subscriptions this writer has found."""
        return len(self.writer.get_matched_subscriptions())


class Subscription:
    """Takes what arrived on one topic, oldest first, as ``rosbags`` messages with their arrival times."""

    def __init__(self, reader: Any, topic: str, ros_type: str) -> None:
        self.reader, self.topic, self.ros_type = reader, topic, ros_type
        self.received = 0

    @property
    def gid(self) -> bytes:
        return self.reader.guid.bytes

    def take(self, limit: int = 256) -> list[tuple[float, Any]]:
        """Every message waiting (at most ``limit``), as (arrival time in s, message): arrival is this process's
        monotonic clock when it was taken, the moment the message became the node's."""
        from cyclonedds.internal import InvalidSample

        samples = self.reader.take(N=limit)
        now = time.monotonic()
        out = []
        for sample in samples:
            if isinstance(sample, InvalidSample):  # a writer went away: no data
                continue
            out.append((now, from_wire(sample, self.ros_type)))
        self.received += len(out)
        return out
