"""Every message the node and the simulated robot send or read, on the wire: Cyclone DDS's serializer (through
the types made from rosbags' definitions) and rosbags' ROS 2 serializer write the same bytes."""

import numpy as np
import pytest

from pimm_env.ros2.messages import dds_topic_name, dds_type, dds_type_name, from_wire, ros_types, to_wire

TYPES = [
    "sensor_msgs/msg/PointCloud2",
    "sensor_msgs/msg/LaserScan",
    "nav_msgs/msg/Odometry",
    "nav_msgs/msg/OccupancyGrid",
    "tf2_msgs/msg/TFMessage",
    "geometry_msgs/msg/PoseWithCovarianceStamped",
    "geometry_msgs/msg/PoseArray",
    "geometry_msgs/msg/PoseStamped",
    "geometry_msgs/msg/Twist",
    "nav2_msgs/msg/ParticleCloud",
    "diagnostic_msgs/msg/DiagnosticArray",
    "rosgraph_msgs/msg/Clock",
    "std_msgs/msg/String",
    "rmw_dds_common/msg/ParticipantEntitiesInfo",
]
NUMPY = {"int8": np.int8, "uint8": np.uint8, "int16": np.int16, "uint16": np.uint16, "int32": np.int32,
         "uint32": np.uint32, "int64": np.int64, "uint64": np.uint64, "float32": np.float32, "float64": np.float64,
         "char": np.uint8, "byte": np.uint8}  # fmt: skip


def filled(ros_type: str, rng: np.random.Generator):
    """A message of ``ros_type`` with every field drawn: numbers, strings, sequences of 0-3 (0-40 for bytes)."""
    from rosbags.typesys.base import Nodetype

    store = ros_types()
    _, fields = store.fielddefs[ros_type]

    def scalar(name: str):
        if name == "bool":
            return bool(rng.integers(2))
        if name == "string":
            return "".join(rng.choice(list("abc_/xyz"), size=int(rng.integers(0, 9))))
        if name == "byte":  # an octet; rosbags packs it signed, so both read 0-127 alike
            return int(rng.integers(0, 128))
        dtype = np.dtype(NUMPY[name])
        if dtype.kind == "f":
            return float(dtype.type(rng.normal() * 100))
        info = np.iinfo(dtype)
        return int(rng.integers(max(info.min, -1000), min(info.max, 1000), endpoint=True))

    def value(node):
        kind, spec = node
        if kind == Nodetype.BASE:
            return scalar(spec[0])
        if kind == Nodetype.NAME:
            return filled(spec, rng)
        element, length = spec
        count = length if kind == Nodetype.ARRAY else int(rng.integers(0, 41 if element[0] == Nodetype.BASE else 4))
        if element[0] == Nodetype.BASE and element[1][0] != "string" and element[1][0] != "bool":
            return np.array([scalar(element[1][0]) for _ in range(count)], dtype=NUMPY[element[1][0]])
        return [value(element) for _ in range(count)]

    return store.types[ros_type](**{name: value(node) for name, node in fields})


@pytest.mark.parametrize("ros_type", TYPES)
def test_cyclone_and_rosbags_write_the_same_bytes(ros_type: str) -> None:
    rng = np.random.default_rng(7)
    store = ros_types()
    for _ in range(5):
        msg = filled(ros_type, rng)
        raw = bytes(store.serialize_cdr(msg, ros_type))
        sample = dds_type(ros_type).deserialize(raw)
        assert sample.serialize() == raw  # Cyclone re-writes rosbags' bytes exactly
        back = from_wire(sample, ros_type)  # and rosbags reads Cyclone's back to the same message
        assert bytes(store.serialize_cdr(back, ros_type)) == raw
        assert to_wire(back, ros_type) == sample


def test_ros_names_on_dds() -> None:
    assert dds_type_name("sensor_msgs/msg/PointCloud2") == "sensor_msgs::msg::dds_::PointCloud2_"
    assert dds_topic_name("/points") == "rt/points"
    assert dds_topic_name("amcl_pose") == "rt/amcl_pose"
    assert dds_type("nav2_msgs/msg/ParticleCloud").__idl_typename__ == "nav2_msgs::msg::dds_::ParticleCloud_"


def test_the_wire_is_little_endian_xcdr1() -> None:
    msg = ros_types().types["geometry_msgs/msg/Point"](x=1.0, y=2.0, z=3.0)
    raw = to_wire(msg, "geometry_msgs/msg/Point").serialize()
    assert raw[:4] == b"\x00\x01\x00\x00"  # CDR_LE, as ROS 2 writes
    assert np.frombuffer(raw[4:], np.float64).tolist() == [1.0, 2.0, 3.0]
