"""ROS 2 message types on the DDS wire, made from ``rosbags``' message definitions (no ROS 2 install needed).

ROS 2 names a message type ``pkg/msg/T`` on DDS as ``pkg::msg::dds_::T_`` and encodes it as CDR (XCDR1, final
structs, little endian). Each type here is a Cyclone DDS ``IdlStruct`` generated from the field list that
``rosbags`` holds for ROS 2 Jazzy (plus ``nav2_msgs``' particle cloud from its ``.msg`` text), so that two
independent serializers exist for every message: Cyclone's, which writes the wire, and ``rosbags``', which the
rest of PIMM reads and writes bags with. ``to_wire`` and ``from_wire`` cross between them through the CDR bytes;
the tests check that both write the same bytes for every type the node and the simulated robot use.
"""

from __future__ import annotations

from functools import cache
from typing import Any

#: nav2's particle cloud, from nav2_msgs' own .msg files (not in rosbags' ROS 2 store)
NAV2_MSGS = {
    "nav2_msgs/msg/Particle": "geometry_msgs/Pose pose\nfloat64 weight\n",
    "nav2_msgs/msg/ParticleCloud": "std_msgs/Header header\nnav2_msgs/Particle[] particles\n",
}


@cache
def ros_types():
    """``rosbags``' ROS 2 Jazzy typestore (the LTS; sensor, geometry, nav, tf2 and diagnostic messages are as in
    Humble, the graph's ``rmw_dds_common/Gid`` is 16 bytes as from Iron on) with nav2's particle cloud added."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    added: dict[str, Any] = {}
    for name, text in NAV2_MSGS.items():
        added.update(get_types_from_msg(text, name))
    store.register(added)
    return store


def dds_type_name(ros_type: str) -> str:
    """``sensor_msgs/msg/PointCloud2`` -> ``sensor_msgs::msg::dds_::PointCloud2_`` (ROS 2's DDS naming)."""
    package, kind, name = ros_type.split("/")
    return f"{package}::{kind}::dds_::{name}_"


def dds_topic_name(topic: str) -> str:
    """``/points`` -> ``rt/points`` (ROS 2's prefix for topics; a relative name is taken from the root)."""
    return "rt/" + topic.lstrip("/")


@cache
def dds_type(ros_type: str) -> Any:
    """The Cyclone DDS ``IdlStruct`` of a ROS 2 message type, its fields as ``rosbags`` defines them."""
    from cyclonedds.idl import make_idl_struct
    from rosbags.typesys.base import Nodetype

    _, fields = ros_types().fielddefs[ros_type]
    members = {name: _member(node, Nodetype) for name, node in fields}
    if not members:  # ROS 2 gives an empty message one member, as rosidl does
        from cyclonedds.idl import types

        members = {"structure_needs_at_least_one_member": types.uint8}
    return make_idl_struct(ros_type.split("/")[-1], dds_type_name(ros_type), members)


def _member(node: tuple, nodetype: Any) -> Any:
    from cyclonedds.idl import types

    base = {
        "bool": bool, "byte": types.uint8, "char": types.uint8, "int8": types.int8, "uint8": types.uint8,
        "int16": types.int16, "uint16": types.uint16, "int32": types.int32, "uint32": types.uint32,
        "int64": types.int64, "uint64": types.uint64, "float32": types.float32, "float64": types.float64,
        "string": str,
    }  # fmt: skip
    kind, spec = node
    if kind == nodetype.BASE:
        name, bound = spec
        return types.bounded_str[bound] if name == "string" and bound else base[name]  # type: ignore[misc]
    if kind == nodetype.NAME:
        return dds_type(spec)
    element, length = spec
    if kind == nodetype.ARRAY:
        return types.array[_member(element, nodetype), length]  # type: ignore[misc]
    inner = _member(element, nodetype)
    return types.sequence[inner, length] if length else types.sequence[inner]  # type: ignore[misc]


def to_wire(msg: Any, ros_type: str) -> Any:
    """A ``rosbags`` message as the Cyclone sample that carries the same CDR bytes."""
    raw = bytes(ros_types().serialize_cdr(msg, ros_type))
    return dds_type(ros_type).deserialize(raw)


def from_wire(sample: Any, ros_type: str) -> Any:
    """A received Cyclone sample as the ``rosbags`` message of the same CDR bytes."""
    return ros_types().deserialize_cdr(sample.serialize(), ros_type)
