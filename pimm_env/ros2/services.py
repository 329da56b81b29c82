"""ROS 2 services over Cyclone DDS, as ``rmw_cyclonedds_cpp`` carries them.

A service ``/name`` of type ``pkg/srv/S`` is two DDS topics: requests on ``rq/nameRequest`` of type
``pkg::srv::dds_::S_Request_`` and replies on ``rr/nameReply`` of type ``pkg::srv::dds_::S_Response_``. Cyclone's
ROS 2 middleware puts a request header before the message's own fields, in both: the client's id (8 bytes, the
second half of its GUID) and a sequence number (int64); a reply carries its request's. Other middlewares carry
the request id elsewhere (Fast DDS in the RTPS sample identity), so these services answer clients that use
``rmw_cyclonedds_cpp`` (and this project's own ``call``), not those of ``rmw_fastrtps_cpp``.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import cache
from typing import Any

from pimm_env.ros2.domain import Domain, QosProfile
from pimm_env.ros2.messages import dds_topic_name, dds_type

#: The services' own fields (ROS 2 message types), by service type; an empty side has none.
SERVICES: dict[str, tuple[dict[str, str], dict[str, str]]] = {
    "std_srvs/srv/Empty": ({}, {}),
    "nav2_msgs/srv/SetInitialPose": ({"pose": "geometry_msgs/msg/PoseWithCovarianceStamped"}, {}),
}
#: rmw's default for services: reliable, volatile, keep last 10
SERVICE_QOS = QosProfile()


@cache
def service_type(srv: str, side: str) -> Any:
    """The DDS type of ``srv``'s ``Request`` or ``Response`` with Cyclone's request header in front."""
    from cyclonedds.idl import make_idl_struct
    from cyclonedds.idl import types as t

    package, _, name = srv.split("/")
    fields = SERVICES[srv][0 if side == "Request" else 1]
    members: dict[str, Any] = {"client_guid": t.uint64, "sequence": t.int64}
    members.update({field: dds_type(kind) for field, kind in fields.items()})
    if not fields:  # an empty message gets one member, as rosidl gives it
        members["structure_needs_at_least_one_member"] = t.uint8
    return make_idl_struct(f"{name}_{side}", f"{package}::srv::dds_::{name}_{side}_", members)


def _endpoints(domain: Domain, name: str, srv: str, server: bool) -> tuple[Any, Any, Any, Any]:
    """(reader, writer, request type, reply type) of one side of ``name``: a server reads requests and writes
    replies, a client the other way round."""
    from cyclonedds.pub import DataWriter
    from cyclonedds.sub import DataReader
    from cyclonedds.topic import Topic

    base = dds_topic_name(name)[len("rt/") :]
    request, reply = service_type(srv, "Request"), service_type(srv, "Response")
    topics = (
        Topic(domain.participant, f"rq/{base}Request", request),
        Topic(domain.participant, f"rr/{base}Reply", reply),
    )
    qos = SERVICE_QOS.policies()
    reads, writes = topics if server else topics[::-1]
    return (
        DataReader(domain.participant, reads, qos=qos),
        DataWriter(domain.participant, writes, qos=qos),
        request,
        reply,
    )


def _sample(kind: Any, client: int, sequence: int, fields: dict[str, Any]) -> Any:
    """A request or reply of ``kind`` with Cyclone's header (an empty message's one member set, as rosidl's)."""
    if "structure_needs_at_least_one_member" in kind.__annotations__:
        fields = {"structure_needs_at_least_one_member": 0, **fields}
    return kind(client_guid=client, sequence=sequence, **fields)


class ServiceServer:
    """Answers ``name`` (``srv``): ``handler(request)`` gets the request's fields as the Cyclone sample and
    returns the response's fields (a dict; empty for an empty response). ``spin_once`` answers what waits."""

    def __init__(self, domain: Domain, name: str, srv: str, handler: Callable[[Any], dict[str, Any]]) -> None:
        self.reader, self.writer, _, self.reply_type = _endpoints(domain, name, srv, server=True)
        self.handler, self.name = handler, name
        self.answered = 0

    @property
    def gids(self) -> tuple[bytes, bytes]:
        return self.reader.guid.bytes, self.writer.guid.bytes

    def spin_once(self) -> int:
        from cyclonedds.internal import InvalidSample

        answered = 0
        for request in self.reader.take(N=16):
            if isinstance(request, InvalidSample):
                continue
            fields = self.handler(request)
            self.writer.write(_sample(self.reply_type, request.client_guid, request.sequence, fields))
            answered += 1
        self.answered += answered
        return answered


def call(domain: Domain, name: str, srv: str, fields: dict[str, Any], client: int, sequence: int,
         timeout: float = 5.0) -> Any:  # fmt: skip
    """Call ``name`` once as a Cyclone ROS 2 client would (``client``: its id, ``sequence``: the request's number)
    and return the reply, or raise ``TimeoutError`` after ``timeout`` s."""
    import time

    from cyclonedds.internal import InvalidSample

    reader, writer, request, _ = _endpoints(domain, name, srv, server=False)
    end = time.monotonic() + timeout
    while not writer.get_matched_subscriptions() or not reader.get_matched_publications():
        if time.monotonic() > end:
            raise TimeoutError(f"no server of {name} answered within {timeout} s")
        time.sleep(0.01)
    writer.write(_sample(request, client, sequence, fields))
    while time.monotonic() < end:
        for answer in reader.take(N=16):
            if not isinstance(answer, InvalidSample) and (answer.client_guid, answer.sequence) == (client, sequence):
                return answer
        time.sleep(0.01)
    raise TimeoutError(f"{name} did not reply within {timeout} s")
