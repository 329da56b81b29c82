"""A bag's LiDAR layouts read from its messages, clouds placed into a layout whatever their point order, ROS 1
bags, and sensors files."""

import json
from pathlib import Path

import numpy as np
import pytest
import yaml
from typer.testing import CliRunner

import evaluate
from pimm_agents.experiments.runner import run_shared
from pimm_agents.scoring.trial import TrialSpec
from pimm_env.bags.layout import layouts_from_bag, organize
from pimm_env.bags.messages import point_cloud, typestore
from pimm_env.bags.record import record_scenario
from pimm_env.errors import BagError
from pimm_env.mapping.derived_maps import ensure_derived_maps
from pimm_env.sim.lidar import Lidar3DConfig, directions_3d, non_repetitive_directions
from pimm_env.sim.sensors import LIDAR_2D, LIDAR_3D, sensor_layouts, write_sensors_file
from pimm_env.world.files import load_world
from tests.rooms import AMCL, ROUTES

GEOMETRY_3D = ("layers", "points_per_layer", "vertical_fov_deg")
GEOMETRY_2D = ("beams", "angle_min_deg", "angle_max_deg", "min_range", "max_range", "rate_hz")


@pytest.fixture
def room(room_file: Path) -> str:
    (room_file.parent / "scenarios.yaml").write_text(ROUTES)
    ensure_derived_maps(load_world(room_file))
    return str(room_file)


def test_layouts_read_from_a_recorded_bag_are_the_ones_it_was_recorded_with(room, tmp_path):
    for sensors in ("thesis", "hokuyo-utm30lx"):
        bag = record_scenario("there", tmp_path / sensors, room, seed=0, sensors=sensors)
        lidar3d, lidar2d = layouts_from_bag(bag, "/scan", "/points")
        want3d, want2d = sensor_layouts(sensors)
        assert [getattr(lidar3d, k) for k in GEOMETRY_3D] == [getattr(want3d, k) for k in GEOMETRY_3D]
        assert [getattr(lidar2d, k) for k in GEOMETRY_2D] == pytest.approx([getattr(want2d, k) for k in GEOMETRY_2D])
        # the rate is the stream's: the simulator casts a 10 Hz LiDAR at the first 32 ms step after each 0.1 s
        assert 1 / lidar3d.rate_hz == pytest.approx(0.128, abs=1e-3)


def sphere_cloud(layout: Lidar3DConfig, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Returns at 2-6 m along every ray of ``layout``, a fifth of them missing."""
    rng = np.random.default_rng(seed)
    ranges = rng.uniform(2.0, 6.0, layout.num_points)
    returned = rng.random(layout.num_points) > 0.2
    cloud = (directions_3d(layout) * ranges[:, None]).astype(np.float32)
    cloud[~returned] = 0.0
    return cloud, returned.astype(np.int8)


def test_organize_puts_top_first_shuffled_and_unorganized_clouds_back_in_the_grid():
    layout = LIDAR_3D["os0-64"]
    cloud, mask = sphere_cloud(layout)
    with_nan = np.where(mask[:, None] > 0, cloud, np.nan).astype(np.float32)
    grid = with_nan.reshape(layout.layers, layout.points_per_layer, 3)
    top_first = np.roll(grid[::-1], 100, axis=1).reshape(-1, 3)  # as Ouster's driver: ring 0 on top, azimuth shifted
    shuffled = with_nan[np.random.default_rng(1).permutation(len(with_nan))]
    with_zeros = np.nan_to_num(with_nan)  # a driver that marks no return with zeros (Ouster's)
    for points in (with_nan, top_first, shuffled, with_zeros):
        placed, placed_mask = organize(points, layout, "test")
        assert np.array_equal(placed_mask, mask) and np.array_equal(placed, cloud)
    # two returns on one ray: the nearer stays
    doubled = np.vstack([with_nan, with_nan[mask > 0][:1] * 2])
    assert np.array_equal(organize(doubled, layout, "test")[0], cloud)
    # a cloud from another LiDAR is refused, not squeezed in
    other, other_mask = sphere_cloud(LIDAR_3D["thesis"])
    with pytest.raises(BagError, match=r"test: only \d+ of \d+ returns fit the 3D LiDAR layout \(64 rings"):
        organize(other[other_mask > 0], layout, "test")


def flat_cloud_bag(path: Path, cloud: np.ndarray, mask: np.ndarray) -> Path:
    """A bag of one unorganized PointCloud2 (height 1, no ring field) and one odometry message."""
    from rosbags.rosbag2 import Writer

    from pimm_env.bags.messages import odometry

    store = typestore()
    msg = point_cloud(store, 0.1, cloud, mask, rings=1)  # height 1: no rows to count rings by
    with Writer(path, version=9) as writer:
        points = writer.add_connection("/points", "sensor_msgs/msg/PointCloud2", typestore=store)
        odom = writer.add_connection("/odom", "nav_msgs/msg/Odometry", typestore=store)
        writer.write(points, 100, store.serialize_cdr(msg, "sensor_msgs/msg/PointCloud2"))
        writer.write(odom, 200, store.serialize_cdr(odometry(store, 0.2, np.zeros(3), "odom"), "nav_msgs/msg/Odometry"))
    return path


@pytest.mark.parametrize("name", ["thesis", "vlp-16", "os1-128"])
def test_an_unorganized_cloud_without_rings_has_them_read_from_its_elevations(tmp_path, name):
    layout = LIDAR_3D[name]
    cloud, mask = sphere_cloud(layout)
    order = np.random.default_rng(2).permutation(len(cloud))  # in no order, and only the returns
    returned = cloud[order][mask[order] > 0]
    bag = flat_cloud_bag(tmp_path / name, returned, np.ones(len(returned), np.int8))
    lidar3d, _ = layouts_from_bag(bag, "/scan", "/points")
    assert [getattr(lidar3d, k) for k in GEOMETRY_3D] == pytest.approx([getattr(layout, k) for k in GEOMETRY_3D])
    placed, placed_mask = organize(returned, lidar3d, "test")  # and replay places every return on its ray
    assert np.array_equal(placed_mask, mask) and np.allclose(placed, cloud)


def test_a_cloud_whose_elevations_form_no_rings_says_what_to_give(tmp_path):
    # a non-repetitive pattern: quasi-random directions, no two returns at one elevation
    directions = non_repetitive_directions(20_000, np.random.default_rng(0))
    cloud = (directions * 4.0).astype(np.float32)
    bag = flat_cloud_bag(tmp_path / "flat", cloud, np.ones(len(cloud), np.int8))
    with pytest.raises(BagError, match=r"flat: /points message 0: .* without a ring field .* no rings .*--sensors"):
        layouts_from_bag(bag, "/scan", "/points")


def test_a_ros1_bag_with_no_record_file_replays_with_the_layout_its_messages_give(room, tmp_path):
    from rosbags.convert import convert

    bag = record_scenario("there_kidnap", tmp_path / "bag", room, seed=2)
    ros1 = tmp_path / "there.bag"
    convert([bag], ros1, "sqlite3", 9, None, "file", typestore(), None, [], [], [], [])
    args = ["replay", str(ros1), "--world", room, "--seed", "2", "--localizers", "amcl", "--json", "--out"]
    args += [str(tmp_path / "r"), "--set", "amcl.max_particles=300", "--set", "amcl.min_particles=100"]
    result = CliRunner().invoke(evaluate.app, evaluate.expand_list_options(args))
    assert result.exit_code == 0, result.output
    folder = Path(json.loads(result.output.strip().splitlines()[-1])["folder"])
    read = sensor_layouts(str(folder / "sensors.yaml"))
    assert [getattr(read[1], k) for k in GEOMETRY_2D] == pytest.approx(
        [getattr(LIDAR_2D["thesis"], k) for k in GEOMETRY_2D]
    )
    assert yaml.safe_load((folder / "run.yaml").read_text())["sensors"] == str(folder / "sensors.yaml")
    live = run_shared([TrialSpec("there_kidnap", "amcl", 0, 2, room, AMCL)])[0]
    log = json.loads((folder / "logs" / "there.bag_amcl_trial00.json").read_text())
    assert log["kidnap_row"] == live.log.kidnap_index
    tum = np.loadtxt(folder / "tum" / "there.bag_amcl_trial00" / "est.tum")
    np.testing.assert_allclose(tum[:, 1:3], live.log.estimate[:, :2], atol=1e-6)  # the same estimates as live


def test_sensors_files_name_the_file_and_the_field(tmp_path):
    path = write_sensors_file(tmp_path / "s.yaml", LIDAR_3D["os0-64"], LIDAR_2D["sick-lms200"], "a note")
    assert sensor_layouts(str(path)) == (LIDAR_3D["os0-64"], LIDAR_2D["sick-lms200"])
    assert sensor_layouts(f"hokuyo-utm30lx,{path}")[1] == LIDAR_2D["sick-lms200"]  # later entries win
    cases = {
        "lidar2d: {beam: 10}": r"lidar2d: unknown key 'beam'",
        "lidar3d: {layers: 10.5}": r"lidar3d.layers: expected a int, got 10.5",
        "lidar2d: 5": r"lidar2d: expected a mapping of settings, got 5",
        "lidar2d: {angle_min_deg: 10, angle_max_deg: 0}": r"lidar2d: 2D LiDAR: need beams >= 1",
        "lidars: {}": r"holds a lidar3d and/or a lidar2d section",
        "lidar2d: [1": r"not YAML",
    }
    for text, message in cases.items():
        path.write_text(text)
        with pytest.raises(ValueError, match=rf"{path}: .*{message}"):
            sensor_layouts(str(path))
    with pytest.raises(ValueError, match="cannot read the sensors file"):
        sensor_layouts(str(tmp_path / "missing.yaml"))


def test_a_clockwise_scan_reads_as_the_same_beams_counter_clockwise():
    from pimm_env.bags.layout import scan_layout
    from pimm_env.bags.messages import laser_scan, scan_ranges
    from pimm_env.sim.lidar import Lidar2DConfig, beam_bearings_2d

    lidar = Lidar2DConfig(beams=181, angle_min_deg=-90.0, angle_max_deg=90.0)
    bearings = beam_bearings_2d(lidar)
    ranges = 1.0 + np.arange(lidar.beams) / 100.0  # each beam's range tells it apart
    store = typestore()
    clockwise = laser_scan(store, 0.0, ranges[::-1], bearings[::-1], lidar)  # from +90 down to -90 deg
    assert clockwise.angle_increment < 0
    read = scan_layout(clockwise, "/scan message 0")
    assert (read.beams, read.angle_min_deg, read.angle_max_deg) == (181, -90.0, 90.0)
    assert np.allclose(scan_ranges(clockwise, 181, lidar.max_range, "/scan message 0"), ranges)


def test_a_bag_without_the_lidar_topics_lists_the_topics_it_has(tmp_path):
    from rosbags.rosbag2 import Writer

    from pimm_env.bags.messages import odometry

    store = typestore()
    bag = tmp_path / "other_names"
    with Writer(bag, version=9) as writer:
        odom = writer.add_connection("/odom", "nav_msgs/msg/Odometry", typestore=store)
        writer.add_connection("/front_laser", "sensor_msgs/msg/LaserScan", typestore=store)
        writer.write(odom, 0, store.serialize_cdr(odometry(store, 0.0, np.zeros(3), "odom"), "nav_msgs/msg/Odometry"))
    with pytest.raises(BagError, match=r"no LiDAR to read.*the bag has /front_laser \(sensor_msgs/msg/LaserScan\)"):
        layouts_from_bag(bag, "/scan", "/points")
