import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

import evaluate
from pimm_agents.experiments.replay import replay_bag
from pimm_agents.experiments.runner import run_shared
from pimm_agents.scoring.trial import TrialSpec
from pimm_env.bags.messages import laser_scan, odometry, typestore
from pimm_env.bags.read import BagTopics, read_steps
from pimm_env.bags.record import record_scenario
from pimm_env.envs.base_env import SimConfig
from pimm_env.errors import BagError
from pimm_env.mapping.derived_maps import ensure_derived_maps
from pimm_env.world.files import load_world
from tests.rooms import AMCL, DEAD, ROUTES


@pytest.fixture
def room(room_file: Path) -> str:
    (room_file.parent / "scenarios.yaml").write_text(ROUTES)
    ensure_derived_maps(load_world(room_file))
    return str(room_file)


@pytest.fixture
def kidnap_bag(room: str, tmp_path: Path) -> Path:
    return record_scenario("there_kidnap", tmp_path / "bag", room, seed=2)


def test_a_recorded_bag_replays_to_the_live_runs_estimates(room, kidnap_bag):
    specs = [TrialSpec("there_kidnap", "amcl", 0, 2, room, AMCL), TrialSpec("there_kidnap", DEAD, 0, 2, room)]
    live = run_shared(specs)
    replayed, has_truth = replay_bag(kidnap_bag, specs)
    assert has_truth
    for a, b in zip(live, replayed, strict=True):
        assert len(a.log) == len(b.log) > 50 and a.log.kidnap_index == b.log.kidnap_index is not None
        assert np.array_equal(a.log.estimate, b.log.estimate)  # the localizers saw the same observations
        assert np.allclose(a.log.true, b.log.true, atol=1e-12) and np.allclose(a.log.time, b.log.time, atol=1e-9)
        assert a.metrics.converged == b.metrics.converged
        for key in ("convergence_time_s", "position_error_m", "angle_error_deg"):
            assert getattr(b.metrics, key) == pytest.approx(getattr(a.metrics, key), abs=1e-9)
    from_map, _ = replay_bag(kidnap_bag, specs[:1], map_path=Path(room).parent / "occupancy.yaml")
    assert np.array_equal(from_map[0].log.estimate, live[0].log.estimate)  # the map alone is the world's map


def test_record_and_replay_commands_write_a_results_folder(room, kidnap_bag, tmp_path):
    args = ["replay", str(kidnap_bag), "--world", room, "--seed", "2", "--localizers", "amcl", "--json"]
    args += ["--set", "amcl.max_particles=300", "--set", "amcl.min_particles=100", "--out", str(tmp_path / "r")]
    result = CliRunner().invoke(evaluate.app, evaluate.expand_list_options(args))
    assert result.exit_code == 0, result.output
    summary = json.loads(result.output.strip().splitlines()[-1])
    row = summary["scenarios"]["there_kidnap"]["amcl"]
    live = run_shared([TrialSpec("there_kidnap", "amcl", 0, 2, room, AMCL)])[0]
    assert row["convergence_rate"] == float(live.metrics.converged)
    folder = Path(summary["folder"])
    assert (folder / "tum" / "there_kidnap_amcl_trial00" / "est.tum").is_file()
    assert json.loads((folder / "logs" / "there_kidnap_amcl_trial00.json").read_text())["kidnap_row"] is not None
    again = CliRunner().invoke(
        evaluate.app, ["record", "--scenario", "there", "--world", room, "--out", str(kidnap_bag)]
    )
    assert again.exit_code == 1 and "already exists" in again.output
    blind = CliRunner().invoke(evaluate.app, evaluate.expand_list_options([*args, "--truth-topic", "/nope"]))
    assert blind.exit_code == 0, blind.output
    record = json.loads(blind.output.strip().splitlines()[-1])  # --json gives JSON without truth too
    assert record["ground_truth"] is False and Path(record["estimates"]).is_dir()


def test_bad_bags_name_the_topic_and_the_message(room, kidnap_bag, tmp_path):
    config = SimConfig()
    with pytest.raises(BagError, match=r"no odometry topic '/wheel_odom'; the bag has \['/events', '/ground_truth'"):
        next(read_steps(kidnap_bag, BagTopics(odom="/wheel_odom"), config.lidar2d, config.lidar3d))
    fewer = replace(config.lidar2d, beams=180)
    with pytest.raises(BagError, match="/scan message 0: 360 beams, the 2D LiDAR layout expects 180"):
        next(read_steps(kidnap_bag, BagTopics(), fewer, config.lidar3d))
    from rosbags.rosbag2 import Writer

    store = typestore()
    backwards = tmp_path / "backwards"
    with Writer(backwards, version=9) as writer:
        odom = writer.add_connection("/odom", "nav_msgs/msg/Odometry", typestore=store)
        scan = writer.add_connection("/scan", "sensor_msgs/msg/LaserScan", typestore=store)
        for i, t in enumerate((0.0, 0.1, 0.05)):
            raw = store.serialize_cdr(odometry(store, t, np.zeros(3), "odom"), "nav_msgs/msg/Odometry")
            writer.write(odom, i, raw)
        del scan
    # header stamps that step back (the receive order does not): served as they are, for the guard to set aside
    steps = list(read_steps(backwards, BagTopics(), config.lidar2d, config.lidar3d))
    assert [float(s.obs["time"][0]) for s in steps] == [0.0, 0.1, 0.05]
    with pytest.raises(FileNotFoundError, match="nope: no such bag"):
        next(read_steps(tmp_path / "nope", BagTopics(), config.lidar2d, config.lidar3d))


def test_a_cloud_without_z_is_refused():
    from pimm_env.bags.messages import cloud_points

    store = typestore()
    t = store.types
    fields = [t["sensor_msgs/msg/PointField"](name=n, offset=4 * i, datatype=7, count=1) for i, n in enumerate("xy")]
    header = t["std_msgs/msg/Header"](stamp=t["builtin_interfaces/msg/Time"](sec=0, nanosec=0), frame_id="lidar")

    def two_points(fields: list):
        return t["sensor_msgs/msg/PointCloud2"](
            header=header, height=1, width=2, fields=fields, is_bigendian=False, point_step=8, row_step=16,
            data=np.zeros(16, np.uint8), is_dense=True,
        )  # fmt: skip

    msg = two_points(fields)
    with pytest.raises(BagError, match=r"/points message 3: PointCloud2 has no field\(s\) \['z'\]"):
        cloud_points(msg, "/points message 3")
    msg = two_points([*fields, t["sensor_msgs/msg/PointField"](name="z", offset=8, datatype=7, count=1)])  # past 8
    with pytest.raises(BagError, match=r"message 3: PointCloud2 field\(s\) \['z'\] at offset\(s\) \[8\] do not fit"):
        cloud_points(msg, "/points message 3")


def test_a_cloud_with_ring_and_intensity_fields_reads_its_xyz():
    from pimm_env.bags.messages import cloud_points

    t = typestore().types
    layout = [("intensity", 0, 7), ("x", 4, 7), ("y", 8, 7), ("z", 12, 7), ("ring", 16, 4)]  # 4: uint16
    fields = [t["sensor_msgs/msg/PointField"](name=n, offset=o, datatype=d, count=1) for n, o, d in layout]
    points = np.array([[1.0, 2.0, 3.0], [np.nan, np.nan, np.nan], [-4.0, 5.5, 0.25]], dtype=np.float32)
    rows = np.zeros((3, 20), np.uint8)
    rows[:, 4:16] = points.view(np.uint8).reshape(3, 12)
    rows[:, 0:4] = np.full(3, 7.0, np.float32).view(np.uint8).reshape(3, 4)
    rows[:, 16:18] = np.array([0, 1, 2], np.uint16).view(np.uint8).reshape(3, 2)
    header = t["std_msgs/msg/Header"](stamp=t["builtin_interfaces/msg/Time"](sec=0, nanosec=0), frame_id="lidar")
    msg = t["sensor_msgs/msg/PointCloud2"](
        header=header, height=1, width=3, fields=fields, is_bigendian=False, point_step=20, row_step=60,
        data=rows.reshape(-1), is_dense=False,
    )  # fmt: skip
    read = cloud_points(msg, "/points message 0")
    assert np.array_equal(read[[0, 2]], points[[0, 2]]) and np.isnan(read[1]).all()


def test_messages_received_together_are_read_truth_and_scans_before_the_odometry_they_arrive_with(tmp_path):
    from rosbags.rosbag2 import Writer

    store = typestore()
    bag = tmp_path / "same_times"
    config = SimConfig()
    lidar = config.lidar2d
    angles = np.linspace(-np.pi, np.pi, lidar.beams, endpoint=False)
    with Writer(bag, version=9) as writer:  # odometry's connection first: with equal times it came out first
        odom = writer.add_connection("/odom", "nav_msgs/msg/Odometry", typestore=store)
        truth = writer.add_connection("/ground_truth", "nav_msgs/msg/Odometry", typestore=store)
        scan = writer.add_connection("/scan", "sensor_msgs/msg/LaserScan", typestore=store)
        for i in range(3):
            at, t = int(1e8) * i, 0.1 * i
            pose = np.array([t, 0.0, 0.0])
            writer.write(odom, at, store.serialize_cdr(odometry(store, t, pose, "odom"), "nav_msgs/msg/Odometry"))
            writer.write(truth, at, store.serialize_cdr(odometry(store, t, pose + 1.0, "map"), "nav_msgs/msg/Odometry"))
            ranges = np.full(lidar.beams, 2.0 + i)
            msg = laser_scan(store, t, ranges, angles, lidar)
            writer.write(scan, at, store.serialize_cdr(msg, "sensor_msgs/msg/LaserScan"))
    steps = list(read_steps(bag, BagTopics(), config.lidar2d, config.lidar3d))
    assert [s.true_pose is not None for s in steps] == [True, True, True]
    assert np.allclose([s.true_pose[0] for s in steps], [1.0, 1.1, 1.2])
    assert [float(s.obs["scan"][0]) for s in steps] == [2.0, 3.0, 4.0] and all(s.fresh_scan for s in steps)


def test_replay_runs_trials_from_a_known_start_with_the_recorded_seed(room, kidnap_bag, tmp_path):
    from pimm_agents.experiments.replay import run_replay

    small = {"amcl": dict(AMCL)}
    done = run_replay(kidnap_bag, small, tmp_path / "r", world=room, start="known", trials=2)
    assert [r.spec.seed for r in done.results] == [2, 3]  # the bag was recorded with seed 2
    assert [r.spec.start for r in done.results] == ["known", "known"]
    assert done.summary["scenarios"]["there_kidnap"]["amcl"]["trials"] == 2
    live = run_shared([TrialSpec("there_kidnap", "amcl", 0, 2, room, AMCL, start="known")])[0]
    assert np.array_equal(done.results[0].log.estimate, live.log.estimate)
    args = ["replay", str(kidnap_bag), "--world", room, "--truth-topic", "/nope", "--start", "known"]
    refused = CliRunner().invoke(evaluate.app, evaluate.expand_list_options([*args, "--out", str(tmp_path / "k")]))
    assert refused.exit_code == 1 and "a known start needs a true pose; no step of the bag has one" in refused.output


def test_truth_as_pose_stamped_is_read_and_a_type_without_a_pose_is_named(tmp_path):
    from rosbags.rosbag2 import Writer

    from pimm_env.bags.messages import planar_pose

    store = typestore()
    t = store.types
    config = SimConfig()
    lidar = config.lidar2d
    angles = np.linspace(-np.pi, np.pi, lidar.beams, endpoint=False)
    header = t["std_msgs/msg/Header"](stamp=t["builtin_interfaces/msg/Time"](sec=0, nanosec=0), frame_id="map")
    half = np.radians(30.0) / 2
    pose = t["geometry_msgs/msg/Pose"](
        position=t["geometry_msgs/msg/Point"](x=1.5, y=-2.0, z=0.0),
        orientation=t["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=np.sin(half), w=np.cos(half)),
    )
    stamped = t["geometry_msgs/msg/PoseStamped"](header=header, pose=pose)
    bag = tmp_path / "pose_stamped"
    with Writer(bag, version=9) as writer:
        truth = writer.add_connection("/ground_truth", "geometry_msgs/msg/PoseStamped", typestore=store)
        scan = writer.add_connection("/scan", "sensor_msgs/msg/LaserScan", typestore=store)
        odom = writer.add_connection("/odom", "nav_msgs/msg/Odometry", typestore=store)
        writer.write(truth, 0, store.serialize_cdr(stamped, "geometry_msgs/msg/PoseStamped"))
        msg = laser_scan(store, 0.0, np.full(lidar.beams, 2.0), angles, lidar)
        writer.write(scan, 1, store.serialize_cdr(msg, "sensor_msgs/msg/LaserScan"))
        writer.write(odom, 2, store.serialize_cdr(odometry(store, 0.0, np.zeros(3), "odom"), "nav_msgs/msg/Odometry"))
    (step,) = list(read_steps(bag, BagTopics(), config.lidar2d, config.lidar3d))
    assert np.allclose(step.true_pose, [1.5, -2.0, np.radians(30.0)])
    with pytest.raises(
        BagError, match="/scan message 0: a .*LaserScan holds no pose; give a topic of nav_msgs/Odometry"
    ):
        planar_pose(msg, "/scan message 0")
    quaternion = t["geometry_msgs/msg/Quaternion"]
    longer = t["geometry_msgs/msg/Pose"](
        position=pose.position, orientation=quaternion(x=0.0, y=0.0, z=3 * np.sin(half), w=3 * np.cos(half))
    )
    assert planar_pose(longer)[2] == pytest.approx(np.radians(30.0))  # a quaternion not normalized: the same yaw
    none = t["geometry_msgs/msg/Pose"](position=pose.position, orientation=quaternion(x=0.0, y=0.0, z=0.0, w=0.0))
    assert np.isnan(planar_pose(none)[2])  # no orientation: no yaw (the readers set it aside, counted)


def drive_bag(bag: Path, odom_of, truth_from: int = 0, stamp_of=lambda i: 0.1 * i) -> Path:
    """30 steps 0.1 s apart east along y = 2 from x = 2 (0.05 m a step) in the iilab's free space: a scan of 3 m
    everywhere, the truth from step ``truth_from`` on, and the odometry ``odom_of(step, true pose)``; every
    message of step i stamped ``stamp_of(i)``."""
    from rosbags.rosbag2 import Writer

    store = typestore()
    lidar = SimConfig().lidar2d
    angles = np.linspace(-np.pi, np.pi, lidar.beams, endpoint=False)
    with Writer(bag, version=9) as writer:
        odom = writer.add_connection("/odom", "nav_msgs/msg/Odometry", typestore=store)
        truth = writer.add_connection("/ground_truth", "nav_msgs/msg/Odometry", typestore=store)
        scan = writer.add_connection("/scan", "sensor_msgs/msg/LaserScan", typestore=store)
        for i in range(30):
            at, t = int(1e8) * i, stamp_of(i)
            pose = np.array([2.0 + 0.05 * i, 2.0, 0.0])
            msg = laser_scan(store, t, np.full(lidar.beams, 3.0), angles, lidar)
            writer.write(scan, at, store.serialize_cdr(msg, "sensor_msgs/msg/LaserScan"))
            if i >= truth_from:
                writer.write(truth, at, store.serialize_cdr(odometry(store, t, pose, "map"), "nav_msgs/msg/Odometry"))
            raw = odometry(store, t, odom_of(i, pose), "odom")
            writer.write(odom, at, store.serialize_cdr(raw, "nav_msgs/msg/Odometry"))
    return bag


def test_what_the_guard_sets_aside_is_counted_in_the_log_the_summary_and_the_printout(tmp_path):
    from pimm_agents.results.tables import format_set_aside
    from pimm_agents.scoring.summaries import summary_of

    def one_glitch(i: int, pose: np.ndarray) -> np.ndarray:  # the odometry jumps 100 m at step 15, once
        return np.array([0.05 * i + (100.0 if i == 15 else 0.0), 0.0, 0.0])

    bag = drive_bag(tmp_path / "glitch", one_glitch)
    spec = TrialSpec("glitch", "amcl", 0, 0, "iilab", AMCL)
    (result,), has_truth = replay_bag(bag, [spec], map_path=Path("maps/iilab/occupancy.yaml"))
    assert has_truth and (result.log.set_aside, result.log.rebased) == ({"too_fast": 1}, 0)
    assert summary_of([result])["scenarios"]["glitch"]["amcl"]["per_trial"][0]["set_aside"] == {"too_fast": 1}
    printed = format_set_aside([result])
    assert "amcl trial 0: 1 observation(s) set aside (too_fast 1), 0 odometry re-base(s)" in printed


def test_a_bag_whose_every_odometry_message_is_set_aside_says_so(tmp_path):
    bag = drive_bag(tmp_path / "no_yaw", lambda i, pose: np.array([pose[0], pose[1], np.nan]))
    config = SimConfig()
    with pytest.raises(BagError, match=r"no_yaw: /odom: no odometry message could be replayed \(set aside: 30 non_fi"):
        list(read_steps(bag, BagTopics(), config.lidar2d, config.lidar3d))


def test_a_topic_of_another_type_named_as_the_scan_or_cloud_is_a_bag_error():
    from pimm_env.bags.messages import cloud_points, scan_ranges

    msg = odometry(typestore(), 0.0, np.zeros(3), "odom")  # e.g. a driver's packet topic named as the cloud
    with pytest.raises(BagError, match="/points message 0: a .*Odometry is not a sensor_msgs/PointCloud2"):
        cloud_points(msg, "/points message 0")
    with pytest.raises(BagError, match="/scan message 4: a .*Odometry is not a sensor_msgs/LaserScan"):
        scan_ranges(msg, 360, 10.0, "/scan message 4")


def test_reading_a_bag_gives_the_same_steps_under_any_hash_seed(tmp_path):
    import os
    import subprocess
    import sys

    from rosbags.rosbag2 import Writer

    store = typestore()
    bag = tmp_path / "hashed"
    with Writer(bag, version=9) as writer:
        odom = writer.add_connection("/odom", "nav_msgs/msg/Odometry", typestore=store)
        truth = writer.add_connection("/ground_truth", "nav_msgs/msg/Odometry", typestore=store)
        scan = writer.add_connection("/scan", "sensor_msgs/msg/LaserScan", typestore=store)
        lidar = SimConfig().lidar2d
        angles = np.linspace(-np.pi, np.pi, lidar.beams, endpoint=False)
        for i in range(5):
            at, t = int(1e8) * i, 0.1 * i
            for connection, msg, kind in (
                (odom, odometry(store, t, np.array([t, 0.0, 0.0]), "odom"), "nav_msgs/msg/Odometry"),
                (truth, odometry(store, t, np.array([t, 1.0, 0.0]), "map"), "nav_msgs/msg/Odometry"),
                (scan, laser_scan(store, t, np.full(lidar.beams, 2.0 + i), angles, lidar), "sensor_msgs/msg/LaserScan"),
            ):
                writer.write(connection, at, store.serialize_cdr(msg, kind))
    code = (
        "import sys; from pathlib import Path; from pimm_env.bags.read import BagTopics, read_steps;"
        "from pimm_env.envs.base_env import SimConfig; c = SimConfig();"
        "print([(s.true_pose is not None, float(s.obs['scan'][0])) for s in read_steps(Path(sys.argv[1]),"
        " BagTopics(), c.lidar2d, c.lidar3d)])"
    )
    outputs = {
        subprocess.run(
            [sys.executable, "-c", code, str(bag)],
            env={**os.environ, "PYTHONHASHSEED": seed},
            capture_output=True,
            text=True,
            check=True,
        ).stdout
        for seed in ("1", "2", "3", "4")
    }
    assert outputs == {str([(True, 2.0 + i) for i in range(5)]) + "\n"}


def test_rows_without_truth_are_left_out_of_the_scoring_and_counted_not_the_whole_truth_dropped(tmp_path):
    bag = drive_bag(tmp_path / "late_truth", lambda i, pose: pose - [2.0, 2.0, 0.0], truth_from=5)
    spec = TrialSpec("late", "amcl", 0, 0, "iilab", AMCL)
    (result,), has_truth = replay_bag(bag, [spec], map_path=Path("maps/iilab/occupancy.yaml"))
    assert has_truth and result.log.set_aside == {"no_truth_rows": 5}
    assert np.all(np.isfinite(result.log.true)) and len(result.log) == 25


def test_steps_are_timed_by_header_stamps_or_by_receive_times(tmp_path):
    from rosbags.rosbag2 import Writer

    store = typestore()
    bag = tmp_path / "stamps"
    header_stamps = [0.0, 0.1, 0.05, 0.3]  # a driver's clock that steps back once
    with Writer(bag, version=9) as writer:
        odom = writer.add_connection("/odom", "nav_msgs/msg/Odometry", typestore=store)
        writer.add_connection("/scan", "sensor_msgs/msg/LaserScan", typestore=store)
        for i, stamp in enumerate(header_stamps):
            msg = odometry(store, stamp, np.array([0.1 * i, 0.0, 0.0]), "odom")
            writer.write(odom, 1_000_000_000 + i * 100_000_000, store.serialize_cdr(msg, "nav_msgs/msg/Odometry"))
    config = SimConfig()

    def times(stamps: str) -> list[float]:
        steps = read_steps(bag, BagTopics(stamps=stamps), config.lidar2d, config.lidar3d)
        return [float(step.obs["time"][0]) for step in steps]

    assert np.allclose(times("header"), header_stamps)
    assert np.allclose(times("receive"), [1.0, 1.1, 1.2, 1.3])
    with pytest.raises(BagError, match="stamps must be one of header, receive, order, got 'sensor'"):
        BagTopics(stamps="sensor")


def test_truth_from_tf_is_the_base_in_the_map_direct_or_through_odom():
    from pimm_env.bags.tf_truth import TfTruth

    t = typestore().types

    def transform(parent: str, child: str, x: float, y: float, yaw: float):
        header = t["std_msgs/msg/Header"](stamp=t["builtin_interfaces/msg/Time"](sec=0, nanosec=0), frame_id=parent)
        return t["geometry_msgs/msg/TransformStamped"](
            header=header,
            child_frame_id=child,
            transform=t["geometry_msgs/msg/Transform"](
                translation=t["geometry_msgs/msg/Vector3"](x=x, y=y, z=0.0),
                rotation=t["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=np.sin(yaw / 2), w=np.cos(yaw / 2)),
            ),
        )

    def tf(*transforms):
        return t["tf2_msgs/msg/TFMessage"](transforms=list(transforms))

    truth = TfTruth()
    assert truth.update(tf(transform("odom", "base_link", 1.0, 0.0, 0.0)), "m0") is None  # no map frame yet
    # map -> odom turned a quarter: the base 1 m ahead in odom is 1 m along the map's y
    pose = truth.update(tf(transform("/map", "odom", 2.0, 0.0, np.pi / 2)), "m1")
    assert np.allclose(pose, [2.0, 1.0, np.pi / 2])
    assert truth.update(tf(transform("base_link", "laser", 0.1, 0.0, 0.0)), "m2") is None  # nothing new
    # a direct map -> base transform wins over the chain
    assert np.allclose(truth.update(tf(transform("map", "base_footprint", 5.0, 6.0, 0.3)), "m3"), [5.0, 6.0, 0.3])
    with pytest.raises(BagError, match="m4: a .*Odometry is not a tf2_msgs/TFMessage"):
        truth.update(odometry(typestore(), 0.0, np.zeros(3), "odom"), "m4")


def test_a_bag_with_tf_truth_gives_true_poses(tmp_path):
    from rosbags.rosbag2 import Writer

    store = typestore()
    t = store.types
    bag = tmp_path / "tf_bag"
    with Writer(bag, version=9) as writer:
        tf = writer.add_connection("/tf", "tf2_msgs/msg/TFMessage", typestore=store)
        odom = writer.add_connection("/odom", "nav_msgs/msg/Odometry", typestore=store)
        scan = writer.add_connection("/scan", "sensor_msgs/msg/LaserScan", typestore=store)
        lidar = SimConfig().lidar2d
        angles = np.linspace(-np.pi, np.pi, lidar.beams, endpoint=False)
        for i in range(3):
            header = t["std_msgs/msg/Header"](stamp=t["builtin_interfaces/msg/Time"](sec=i, nanosec=0), frame_id="map")
            moved = t["geometry_msgs/msg/TransformStamped"](
                header=header,
                child_frame_id="base_link",
                transform=t["geometry_msgs/msg/Transform"](
                    translation=t["geometry_msgs/msg/Vector3"](x=1.0 + i, y=2.0, z=0.0),
                    rotation=t["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
                ),
            )
            at = (i + 1) * 1_000_000_000
            ranges = laser_scan(store, float(i), np.full(lidar.beams, 3.0), angles, lidar)
            writer.write(scan, at, store.serialize_cdr(ranges, "sensor_msgs/msg/LaserScan"))
            writer.write(
                tf, at, store.serialize_cdr(t["tf2_msgs/msg/TFMessage"](transforms=[moved]), "tf2_msgs/msg/TFMessage")
            )
            writer.write(
                odom,
                at,
                store.serialize_cdr(
                    odometry(store, float(i), np.array([i, 0.0, 0.0]), "odom"), "nav_msgs/msg/Odometry"
                ),
            )
    config = SimConfig()
    steps = list(read_steps(bag, BagTopics(points=None, truth="/tf"), config.lidar2d, config.lidar3d))
    assert np.allclose([s.true_pose for s in steps], [[1.0, 2.0, 0.0], [2.0, 2.0, 0.0], [3.0, 2.0, 0.0]])


def test_a_message_with_a_nan_is_set_aside_counted_and_the_replay_goes_on(tmp_path):
    def nan_at_12(i: int, pose: np.ndarray) -> np.ndarray:
        return np.array([np.nan if i == 12 else 0.05 * i, 0.0, 0.0])

    bag = drive_bag(tmp_path / "nan_odom", nan_at_12)
    spec = TrialSpec("nan", "amcl", 0, 0, "iilab", AMCL)
    (result,), _ = replay_bag(bag, [spec], map_path=Path("maps/iilab/occupancy.yaml"))
    assert result.log.set_aside == {"non_finite_odometry": 1}
    assert len(result.log) == 29 and np.all(np.isfinite(result.log.estimate))  # every other step replayed


def test_what_is_not_a_bag_is_one_clear_error(tmp_path):
    from pimm_env.bags.read import bag_topics

    folder = tmp_path / "no_metadata"
    folder.mkdir()
    (folder / "x.db3").write_bytes(b"not sqlite")
    garbage = tmp_path / "garbage.bag"
    garbage.write_bytes(b"\x00\x01 this is no ROS 1 bag" * 10)
    named = tmp_path / "intel.bag"
    named.mkdir()
    (named / "metadata.yaml").write_text("rosbag2_bagfile_information: {}\n")
    for path, said in ((folder, "holds a metadata.yaml"), (garbage, "not a readable bag"), (named, "rename it to")):
        with pytest.raises(BagError, match=said) as raised:
            bag_topics(path)
        assert str(path) in str(raised.value)
    bag = drive_bag(tmp_path / "truncated", lambda i, pose: pose)
    db3 = next(bag.glob("*.db3"))
    db3.write_bytes(db3.read_bytes()[:2000])  # cut short
    config = SimConfig()
    with pytest.raises(BagError, match="truncated.*not a readable bag"):
        list(read_steps(bag, BagTopics(), config.lidar2d, config.lidar3d))


def test_a_clock_that_never_advances_says_to_replay_by_receive_time_and_stale_scans_are_counted(tmp_path):
    from rosbags.rosbag2 import Writer

    store = typestore()
    lidar = SimConfig().lidar2d
    angles = np.linspace(-np.pi, np.pi, lidar.beams, endpoint=False)
    bag = tmp_path / "zero"
    with Writer(bag, version=9) as writer:
        odom = writer.add_connection("/odom", "nav_msgs/msg/Odometry", typestore=store)
        scan = writer.add_connection("/scan", "sensor_msgs/msg/LaserScan", typestore=store)
        for i in range(30):  # every header stamp 0, received 0.1 s apart; the scans' stamps stuck too
            msg = laser_scan(store, 0.0, np.full(lidar.beams, 3.0), angles, lidar)
            writer.write(scan, 1_000_000_000 + i * 100_000_000, store.serialize_cdr(msg, "sensor_msgs/msg/LaserScan"))
            raw = store.serialize_cdr(odometry(store, 0.0, np.array([0.01 * i, 0, 0]), "odom"), "nav_msgs/msg/Odometry")
            writer.write(odom, 1_000_000_000 + i * 100_000_000, raw)
    config = SimConfig()
    aside: dict[str, int] = {}
    with pytest.raises(BagError, match=r"/odom: the first 20 header stamps are all 0.0.*--stamps receive"):
        list(read_steps(bag, BagTopics(), config.lidar2d, config.lidar3d, aside))
    assert aside == {"scan_stamp_not_newer": 19}  # counted up to where it stopped
    steps = list(read_steps(bag, BagTopics(stamps="receive"), config.lidar2d, config.lidar3d))
    assert len(steps) == 30 and steps[-1].obs["time"][0] == pytest.approx(3.9)


def test_coarse_stamps_spread_in_order_so_that_every_message_has_a_time_of_its_own(tmp_path):
    """A log printed with too few digits: ten odometry messages share each whole second."""
    from pimm_env.bags.read import spread_equal

    bag = drive_bag(tmp_path / "coarse", lambda i, pose: pose, stamp_of=lambda i: 1000.0 + i // 10)
    config = SimConfig()
    times = [
        float(s.obs["time"][0]) for s in read_steps(bag, BagTopics(stamps="order"), config.lidar2d, config.lidar3d)
    ]
    np.testing.assert_allclose(times, 1000.0 + 0.1 * np.arange(30), atol=1e-9)  # each second's ten, 0.1 s apart
    assert spread_equal(np.array([5.0, 5.0, 6.0, 6.0, 6.0, 7.0])).tolist() == pytest.approx(
        [5, 5.5, 6, 6 + 1 / 3, 6 + 2 / 3, 7]
    )
