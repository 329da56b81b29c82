"""What makes a DDS participant a ROS 2 node: its entry on ``ros_discovery_info``.

ROS 2's graph (``ros2 node list``, ``ros2 topic info -v``) is not read from DDS discovery alone: every
participant publishes a ``rmw_dds_common/msg/ParticipantEntitiesInfo`` on the DDS topic ``ros_discovery_info``
(reliable, transient local, keep last 1) naming its nodes and the readers and writers (by GID, the DDS GUID)
each owns. ``announce`` writes that entry for one node; call it again when the node adds a publisher or
subscription.
"""

from __future__ import annotations

from typing import Any

from pimm_env.ros2.domain import Domain, Publisher, QosProfile, Subscription
from pimm_env.ros2.messages import dds_type, ros_types, to_wire

DISCOVERY_TOPIC = "ros_discovery_info"  # a DDS topic name as it is (no rt/ prefix)
ENTITIES_TYPE = "rmw_dds_common/msg/ParticipantEntitiesInfo"
GID_BYTES = 16  # rmw_dds_common/Gid from Iron on (Humble's is 24)


def gid(guid: bytes) -> Any:
    t = ros_types().types
    import numpy as np

    return t["rmw_dds_common/msg/Gid"](data=np.frombuffer(guid[:GID_BYTES].ljust(GID_BYTES, b"\0"), np.uint8))


class GraphEntry:
    """One node's entry in the ROS 2 graph, for a ``Domain`` whose endpoints it lists."""

    def __init__(self, domain: Domain, name: str, namespace: str = "/") -> None:
        from cyclonedds.pub import DataWriter
        from cyclonedds.topic import Topic

        if not name or not name.replace("_", "a").isalnum() or name[0].isdigit():
            raise ValueError(f"node name {name!r}: ROS 2 names are letters, digits and _, not starting with a digit")
        self.domain, self.name, self.namespace = domain, name, namespace
        topic = Topic(domain.participant, DISCOVERY_TOPIC, dds_type(ENTITIES_TYPE))
        self._writer = DataWriter(domain.participant, topic, qos=QosProfile(transient_local=True, depth=1).policies())

    def announce(self, endpoints: list[Publisher | Subscription], services: tuple = ()) -> None:
        """Say the node's readers and writers: its ``endpoints`` and each service server's (reader, writer)."""
        t = ros_types().types
        readers = [gid(e.gid) for e in endpoints if isinstance(e, Subscription)] + [gid(s.gids[0]) for s in services]
        writers = [gid(e.gid) for e in endpoints if isinstance(e, Publisher)] + [gid(s.gids[1]) for s in services]
        node = t["rmw_dds_common/msg/NodeEntitiesInfo"](
            node_namespace=self.namespace, node_name=self.name, reader_gid_seq=readers, writer_gid_seq=writers
        )
        info = t[ENTITIES_TYPE](gid=gid(self.domain.participant.guid.bytes), node_entities_info_seq=[node])
        self._writer.write(to_wire(info, ENTITIES_TYPE))
