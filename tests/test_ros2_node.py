"""The localization node in one process: a scripted localizer behind it, the robot's topics written on the same
loopback domain, and what nav2 would read checked on the node's own topics."""

import time

import numpy as np
import pytest

from pimm_agents.localizer import Hypothesis, PoseEstimate
from pimm_agents.ros2.node import LocalizationNode, covariance_3x3
from pimm_agents.ros2.node_config import NodeConfig, read_node_params
from pimm_env.bags.messages import point_cloud
from pimm_env.errors import Ros2Error
from pimm_env.geometry import compose
from pimm_env.ros2 import domain as qos
from pimm_env.ros2.domain import Domain
from pimm_env.ros2.frames import header, planar, quaternion, tf_message, transform
from pimm_env.ros2.messages import ros_types
from pimm_env.sim.lidar import Lidar2DConfig, Lidar3DConfig, directions_3d

LIDAR3D = Lidar3DConfig(layers=8, points_per_layer=90, vertical_fov_deg=40.0)
ESTIMATE = np.array([2.0, 3.0, 0.5])


class Scripted:
    """A localizer that says what the test tells it and keeps what it was given."""

    name = "scripted"
    sensors = ("odom", "cloud")

    def __init__(self) -> None:
        self.status, self.hypotheses = "localized", ()
        self.resets: list[tuple] = []
        self.observations: list[dict] = []

    def reset(self, seed=None, initial_pose=None, initial_cov=None) -> None:
        self.resets.append((seed, initial_pose, initial_cov))

    def update(self, obs) -> PoseEstimate:
        self.observations.append(obs)
        cov = np.diag([0.01, 0.01, 0.001])
        return PoseEstimate(*ESTIMATE, covariance=cov, status=self.status, hypotheses=self.hypotheses)


@pytest.fixture
def robot(ros_domain):
    """(node, the scripted localizer, the mounts it was made with, the robot's publishers, nav2's readers)."""
    with Domain() as domain:
        made: list = []
        localizer = Scripted()

        def make(mount):
            made.append(mount)
            return localizer

        node = LocalizationNode(make, LIDAR3D, Lidar2DConfig(), domain, NodeConfig(mount_wait=0.0, seed=3))
        pubs = {
            "static": domain.publisher("/tf_static", "tf2_msgs/msg/TFMessage", qos.LATCHED),
            "tf": domain.publisher("/tf", "tf2_msgs/msg/TFMessage", qos.TF),
            "points": domain.publisher("/points", "sensor_msgs/msg/PointCloud2", qos.SENSOR),
            "initialpose": domain.publisher("/initialpose", "geometry_msgs/msg/PoseWithCovarianceStamped"),
        }
        subs = {
            "pose": domain.subscription("amcl_pose", "geometry_msgs/msg/PoseWithCovarianceStamped", qos.LATCHED),
            "tf": domain.subscription("/tf", "tf2_msgs/msg/TFMessage", qos.TF),
            "diagnostics": domain.subscription("/diagnostics", "diagnostic_msgs/msg/DiagnosticArray"),
        }
        yield node, localizer, made, pubs, subs
        node.close()


def cloud(seconds: float):
    points = (directions_3d(LIDAR3D) * 4.0).astype(np.float32)
    return point_cloud(ros_types(), seconds, points, np.ones(len(points)), LIDAR3D.layers)


def until(condition, seconds: float = 3.0) -> None:
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        if condition():
            return
        time.sleep(0.005)
    raise AssertionError("not within the time given")


def drive(node, pubs, clouds: int, stamp: float = 1.0, odom=(1.0, 0.0, 0.2)) -> PoseEstimate:
    for i in range(clouds):
        pubs["points"].publish(cloud(stamp - 0.01 * (clouds - i)))
    time.sleep(0.2)  # all of them waiting before the odometry closes the step
    pubs["tf"].publish(tf_message([transform(stamp, "odom", "base_link", np.array(odom))]))
    got: list = []
    until(lambda: got.append(node.spin_once()) or got[-1] is not None)
    return got[-1]


def test_the_mount_comes_from_tf_static_and_waiting_clouds_are_counted(robot) -> None:
    node, localizer, made, pubs, _ = robot
    mount = transform(0.0, "base_link", "lidar", np.array([0.1, 0.0, 0.0]), z=0.7)
    pubs["static"].publish(tf_message([mount]))
    drive(node, pubs, clouds=3)
    assert made == [
        {
            "mount_x": 0.1,
            "mount_y": 0.0,
            "height": 0.7,
            "mount_roll_deg": 0.0,
            "mount_pitch_deg": 0.0,
            "mount_yaw_deg": 0.0,
        }
    ]
    assert localizer.resets == [(3, None, None)]  # a global start with the node's seed
    assert node.inputs.counts["skipped_clouds"] == 2  # the newest of three was used, two counted
    obs = localizer.observations[-1]
    assert int(obs["cloud_mask"].sum()) == LIDAR3D.num_points  # every return placed into the layout's grid
    assert obs["odom"].tolist() == pytest.approx([1.0, 0.0, 0.2])


def test_map_to_odom_carries_odometry_onto_the_estimate(robot) -> None:
    node, _, _, pubs, subs = robot
    drive(node, pubs, clouds=1, stamp=5.0)
    sent: list = []
    until(lambda: sent.extend(subs["tf"].take()) or any(m.transforms[0].header.frame_id == "map" for _, m in sent))
    map_odom = next(m.transforms[0] for _, m in sent if m.transforms[0].header.frame_id == "map")
    assert map_odom.child_frame_id == "odom"
    assert map_odom.header.stamp.sec == 6  # future-dated by nav2's transform_tolerance, 1 s
    base = compose(planar(map_odom), np.array([1.0, 0.0, 0.2]))[0]
    assert base == pytest.approx(ESTIMATE)


def test_the_published_covariance_covers_every_live_place_unless_localized(robot) -> None:
    node, localizer, _, pubs, subs = robot
    twin = Hypothesis(8.0, 3.0, 0.5, 0.5, np.diag([0.01, 0.01, 0.001]))
    here = Hypothesis(*ESTIMATE, 0.5, np.diag([0.01, 0.01, 0.001]))
    localizer.status, localizer.hypotheses = "ambiguous", (here, twin)
    drive(node, pubs, clouds=1)
    poses: list = []
    until(lambda: poses.extend(subs["pose"].take()) or bool(poses))
    cov = covariance_3x3(poses[-1][1].pose.covariance)
    assert cov[0, 0] >= 0.5 * 6.0**2  # the twin 6 m east is inside the ellipse
    localizer.status = "localized"
    drive(node, pubs, clouds=1, stamp=2.0)
    until(lambda: poses.extend(subs["pose"].take()) or len(poses) > 1)
    assert covariance_3x3(poses[-1][1].pose.covariance)[0, 0] == pytest.approx(0.01)
    diagnostics: list = []
    until(lambda: diagnostics.extend(subs["diagnostics"].take()) or len(diagnostics) > 1)
    first, last = (d[1].status[0] for d in diagnostics[:2])
    assert (first.message, first.level, last.message, last.level) == ("ambiguous", 1, "localized", 0)
    assert {kv.key: kv.value for kv in first.values}["skipped_clouds"] == "0"


def test_initialpose_restarts_the_localizer_there(robot) -> None:
    node, localizer, _, pubs, _ = robot
    drive(node, pubs, clouds=1)
    t = ros_types().types
    cov = np.zeros(36)
    cov[[0, 7, 35]] = [0.25, 0.25, 0.07]
    pose = t["geometry_msgs/msg/Pose"](
        position=t["geometry_msgs/msg/Point"](x=4.0, y=-1.0, z=0.0), orientation=quaternion(0.0, 0.0, 1.0)
    )
    pubs["initialpose"].publish(
        t["geometry_msgs/msg/PoseWithCovarianceStamped"](
            header=header(1.5, "map"), pose=t["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=cov)
        )
    )
    time.sleep(0.2)
    drive(node, pubs, clouds=1, stamp=2.0)
    seed, start, start_cov = localizer.resets[-1]
    assert seed == 3 and start == pytest.approx([4.0, -1.0, 1.0])
    assert np.diag(start_cov) == pytest.approx([0.25, 0.25, 0.07])


def test_nav2s_services_as_cyclone_carries_them(robot) -> None:
    """``reinitialize_global_localization`` and ``set_initial_pose``, called as a Cyclone ROS 2 client calls them;
    each reply carries its request's id, and the next update restarts the localizer as asked."""
    import threading

    from pimm_env.ros2.services import call, service_type

    node, localizer, _, pubs, _ = robot
    drive(node, pubs, clouds=1)
    stop = threading.Event()
    spinner = threading.Thread(target=lambda: node.spin(should_stop=stop.is_set), daemon=True)
    spinner.start()
    try:
        reply = call(node.domain, "reinitialize_global_localization", "std_srvs/srv/Empty", {}, client=77, sequence=5)
        assert (reply.client_guid, reply.sequence) == (77, 5)
        t = ros_types().types
        pose = t["geometry_msgs/msg/Pose"](position=t["geometry_msgs/msg/Point"](x=1.0, y=2.0, z=0.0),
                                           orientation=quaternion(0.0, 0.0, 0.5))  # fmt: skip
        cov = np.zeros(36)
        cov[[0, 7, 35]] = [0.25, 0.25, 0.07]
        stamped = t["geometry_msgs/msg/PoseWithCovarianceStamped"](
            header=header(1.0, "map"), pose=t["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=cov)
        )
        from pimm_env.ros2.messages import to_wire

        request = {"pose": to_wire(stamped, "geometry_msgs/msg/PoseWithCovarianceStamped")}
        reply = call(node.domain, "set_initial_pose", "nav2_msgs/srv/SetInitialPose", request, client=77, sequence=6)
        assert reply.sequence == 6
    finally:
        stop.set()
        spinner.join(timeout=5)
    resets = len(localizer.resets)
    drive(node, pubs, clouds=1, stamp=3.0)
    assert len(localizer.resets) == resets + 1 and localizer.resets[-1][1] == pytest.approx([1.0, 2.0, 0.5])
    raw = service_type("std_srvs/srv/Empty", "Request")(
        client_guid=1, sequence=2, structure_needs_at_least_one_member=0
    )
    assert raw.serialize() == b"\x00\x01\x00\x00" + (1).to_bytes(8, "little") + (2).to_bytes(8, "little") + b"\x00"
    assert service_type("nav2_msgs/srv/SetInitialPose", "Request").__idl_typename__ == (
        "nav2_msgs::srv::dds_::SetInitialPose_Request_"
    )


def test_the_node_is_in_the_ros2_graph(robot) -> None:
    """``ros2 node list`` reads ``ros_discovery_info``: the node's name and the GIDs of its readers and writers."""
    from cyclonedds.sub import DataReader
    from cyclonedds.topic import Topic

    from pimm_env.ros2.graph import DISCOVERY_TOPIC, ENTITIES_TYPE
    from pimm_env.ros2.messages import dds_type, from_wire

    node = robot[0]
    participant = node.domain.participant
    topic = Topic(participant, DISCOVERY_TOPIC, dds_type(ENTITIES_TYPE))
    reader = DataReader(participant, topic, qos=qos.LATCHED.policies())
    entries: list = []
    until(lambda: entries.extend(from_wire(s, ENTITIES_TYPE) for s in reader.take(N=10)) or bool(entries))
    (info,) = [e for e in entries if e.node_entities_info_seq[0].node_name == "pimm_localization"]
    entry = info.node_entities_info_seq[0]
    assert entry.node_namespace == "/"
    writers = {bytes(g.data) for g in entry.writer_gid_seq}
    assert node.pubs["pose"].gid[:16] in writers and len(writers) == len(node.pubs) + len(node.services)
    subs = [*node.inputs.subs.values(), node.initialpose]
    readers = {s.gid[:16] for s in subs} | {server.gids[0][:16] for server in node.services}
    assert {bytes(g.data) for g in entry.reader_gid_seq} == readers
    assert bytes(info.gid.data) == participant.guid.bytes[:16]


def test_params_file_in_nav2_shape(tmp_path) -> None:
    path = tmp_path / "params.yaml"
    path.write_text(
        "pimm_localization:\n  ros__parameters:\n    base_frame_id: base_footprint\n"
        "    transform_tolerance: 0.5\n    filter:\n      particles: 3000\n"
    )
    config, settings = read_node_params(path, "pimm_localization")
    assert (config.base_frame_id, config.transform_tolerance, config.odom_frame_id) == ("base_footprint", 0.5, "odom")
    assert settings == {"filter": {"particles": 3000}}
    with pytest.raises(Ros2Error, match="no section 'amcl'.*pimm_localization"):
        read_node_params(path, "amcl")
    path.write_text("pimm_localization:\n  ros__parameters:\n    odom_source: wheels\n")
    with pytest.raises(Ros2Error, match="odom_source 'wheels'"):
        read_node_params(path, "pimm_localization")


def test_domain_ids_are_checked(monkeypatch) -> None:
    from pimm_env.ros2.domain import domain_id

    monkeypatch.setenv("ROS_DOMAIN_ID", "300")
    with pytest.raises(Ros2Error, match="0 to 232"):
        domain_id()
    with pytest.raises(Ros2Error, match="discovery 'wan'"):
        Domain("wan")
