"""Any scan through the segmenter: the mount height measured from the floor, a tilted or unorganized scan of
another LiDAR, and the ``segment`` command on a file."""

import json

import numpy as np
import pytest

from pimm_agents.perception.files import SHIPPED_WEIGHTS
from pimm_agents.perception.floor import estimate_floor
from pimm_env.envs.iilab_env import IILabEnv
from pimm_env.envs.sim_config import SimConfig
from pimm_env.geometry import rotation_onto_z
from pimm_env.sim.lidar import Lidar3DConfig


def simulated_scan(lidar: Lidar3DConfig, seed: int = 0):
    env = IILabEnv(config=SimConfig(lidar3d=lidar))
    obs, _ = env.reset(seed=seed)
    obs, _, _, _, info = env.step(np.zeros(2, dtype=np.float32))
    env.close()
    keep = obs["cloud_mask"].astype(bool)
    return obs["cloud"][keep].astype(np.float64), info["labels"][keep]


@pytest.mark.parametrize("height", [0.5, 1.2])
def test_the_measured_mount_height_agrees_with_the_given_one_within_5_cm(height):
    points, _ = simulated_scan(Lidar3DConfig(height=height))
    floor = estimate_floor(points)
    assert floor.height == pytest.approx(height, abs=0.05)
    assert floor.tilt_deg < 1.0


def test_a_leaning_sensor_is_levelled_on_the_floor():
    points, _ = simulated_scan(Lidar3DConfig())
    lean = rotation_onto_z(np.array([np.sin(np.radians(4)), 0.0, np.cos(np.radians(4))])).T  # 4 deg of pitch
    floor = estimate_floor(points @ lean.T)
    assert floor.tilt_deg == pytest.approx(4.0, abs=0.3)
    assert floor.height == pytest.approx(0.5, abs=0.05)


def test_a_scan_without_floor_below_the_sensor_asks_for_the_height():
    from pimm_env.errors import PerceptionError

    with pytest.raises(PerceptionError, match="--sensor-height"):
        estimate_floor(np.random.default_rng(0).uniform(0, 3, (500, 3)))


def _accuracy(labels, truth):
    return float(np.mean(labels == truth))


@pytest.mark.parametrize("weights", ["grid", "cloud"])
def test_an_unorganized_scan_gets_the_classes_of_an_organized_one(weights):
    """The thesis LiDAR's scan handed over as a bare point set (no rings), shuffled, with the height measured:
    through the grid network's own layout, or the layout-free network."""
    from pimm_agents.perception.files import SHIPPED_CLOUD_WEIGHTS
    from pimm_agents.perception.segmenter import load_segmenter
    from pimm_agents.scans.segment import segment_cloud

    segmenter = load_segmenter(SHIPPED_WEIGHTS if weights == "grid" else SHIPPED_CLOUD_WEIGHTS)
    rng = np.random.default_rng(0)
    for lidar in (Lidar3DConfig(),):
        points, truth = simulated_scan(lidar, seed=2)
        order = rng.permutation(len(points))
        result = segment_cloud(points[order], segmenter)
        assert result.height_measured and result.sensor_height == pytest.approx(0.5, abs=0.05)
        assert _accuracy(result.labels, truth[order]) > 0.8, lidar.layers


@pytest.mark.parametrize("stray", [[100.0, 0.0, 0.0], [0.0, 0.0, -2.0e5]])
def test_a_stray_return_far_off_is_set_aside_and_changes_nothing_else(stray):
    """One return 100 m (or 200 km) away must not set the floor's bins or the height features' scale."""
    from pimm_agents.perception.files import SHIPPED_CLOUD_WEIGHTS
    from pimm_agents.perception.segmenter import load_segmenter
    from pimm_agents.scans.segment import segment_cloud
    from pimm_env.world.semantics import SemanticClass

    segmenter = load_segmenter(SHIPPED_CLOUD_WEIGHTS)
    points, _ = simulated_scan(Lidar3DConfig(), seed=2)
    clean = segment_cloud(points, segmenter)
    strayed = segment_cloud(np.vstack([points, [stray]]), segmenter)
    assert (clean.far_outliers, strayed.far_outliers) == (0, 1)
    np.testing.assert_array_equal(strayed.labels[:-1], clean.labels)
    assert strayed.labels[-1] == int(SemanticClass.CLUTTER)
    assert strayed.sensor_height == clean.sensor_height and len(strayed.corners) == len(clean.corners)


def test_segment_writes_labels_corners_and_pictures(tmp_path):
    import open3d as o3d
    from typer.testing import CliRunner

    import evaluate

    points, _ = simulated_scan(Lidar3DConfig(height=0.9))
    path = tmp_path / "scan.pcd"
    o3d.io.write_point_cloud(str(path), o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points)), compressed=True)
    result = CliRunner().invoke(evaluate.app, ["segment", str(path), "--out", str(tmp_path / "out"), "--json"])
    assert result.exit_code == 0, result.output
    record = json.loads(result.output)
    assert record["sensor_height_m"] == pytest.approx(0.9, abs=0.05) and record["height_measured"]
    assert sum(record["shares"].values()) == pytest.approx(1.0, abs=1e-3) and record["shares"]["wall"] > 0.1
    folder = tmp_path / "out"
    (written,) = list(folder.iterdir())
    labels = np.load(written / "labels.npy")
    assert labels.shape == (len(points),) and set(np.unique(labels)) <= {0, 1, 2, 3}
    for name in ("labelled.ply", "corners.json", "views.png", "segment.json"):
        assert (written / name).stat().st_size > 0, name
    given = CliRunner().invoke(evaluate.app, ["segment", str(path), "--sensor-height", "0.9", "--out", str(folder)])
    assert given.exit_code == 0 and "0.900 m above the floor (given)" in given.output
    bad = tmp_path / "bad.npy"
    np.save(bad, np.full((5, 3), np.nan))
    failed = CliRunner().invoke(evaluate.app, ["segment", str(bad), "--out", str(tmp_path / "none")])
    assert failed.exit_code != 0 and "bad.npy" in failed.output
    assert not (tmp_path / "none").exists() or not any((tmp_path / "none").iterdir())  # no empty results


def test_the_layout_free_network_labels_a_16_ring_scan_and_one_without_rings():
    """One network, two LiDARs: 16-ring spinning scans and thesis scans of the iiLab, each as a bare shuffled point
    set. Over the scans of seeds 1-8 the shipped network labels 0.62 of the 16-ring returns right and 0.77 of
    the thesis LiDAR's (scan by scan 0.32-0.81 and 0.58-0.86: one scan says little; the previous network,
    0.63 and 0.76)."""
    from pimm_agents.perception.files import SHIPPED_CLOUD_WEIGHTS
    from pimm_agents.perception.segmenter import load_segmenter
    from pimm_agents.scans.segment import segment_cloud
    from pimm_env.sim.sensors import LIDAR_3D

    cloud = load_segmenter(SHIPPED_CLOUD_WEIGHTS)
    rng = np.random.default_rng(1)
    for name, least in (("vlp-16", 0.55), ("thesis", 0.7)):
        right = []
        for seed in range(1, 9):
            points, truth = simulated_scan(LIDAR_3D[name], seed=seed)
            order = rng.permutation(len(points))
            right.append(_accuracy(segment_cloud(points[order], cloud).labels, truth[order]))
        assert np.mean(right) > least, (name, right)


def test_a_scan_turned_upside_down_is_said_to_look_so_and_the_real_one_is_not(tmp_path):
    from pimm_agents.scans.segment import hanging_ratio
    from pimm_env.clouds.read import read_cloud
    from tests.conftest import shared_file

    points = read_cloud(shared_file("real", "scans", "room_scan1.pcd")).points.astype(float)
    for scan, upside_down in ((points, False), (points * [1.0, -1.0, -1.0], True)):
        floor = estimate_floor(scan)
        assert (hanging_ratio(scan @ floor.leveling.T, floor.height) > 1.0) == upside_down
    sim, _ = simulated_scan(Lidar3DConfig(height=0.9))
    floor = estimate_floor(sim)
    assert hanging_ratio(sim @ floor.leveling.T, floor.height) < 1.0  # a simulated upright scan of the iiLab


def test_a_scan_on_its_side_in_its_file_is_said_not_to_stand_z_up():
    from pimm_agents.scans.upright import spin_axis, standing_off_faces, upright_warnings
    from pimm_env.clouds.read import read_cloud
    from tests.conftest import shared_file

    def warnings(scan):
        floor = estimate_floor(scan)
        return upright_warnings(scan, standing_off_faces(scan @ floor.leveling.T), False)

    room = read_cloud(shared_file("real", "scans", "room_scan1.pcd")).points.astype(float)
    y_up, x_up = np.array([[1, 0, 0], [0, 0, 1], [0, -1, 0]]), np.array([[0, 0, 1], [0, 1, 0], [-1, 0, 0]])
    assert warnings(room) == []
    for turn in (y_up, x_up, y_up.T):  # a full-sphere scanner: told by what stands off the floor it was levelled on
        assert "may be a wall" in " ".join(warnings(room @ turn.T))
    assert warnings(room @ y_up.T) != [] and upright_warnings(room @ y_up.T, {}, True) == []  # the mount was given
    narrow, _ = simulated_scan(Lidar3DConfig(layers=16, vertical_fov_deg=30.0, height=0.9))  # a spinning LiDAR
    assert spin_axis(narrow) == "z" and spin_axis(narrow @ y_up.T) == "y" and spin_axis(room) is None
    assert "looks Y-up" in " ".join(upright_warnings(narrow @ y_up.T, {"floor": 0}, False))


def test_a_scan_out_of_its_sensor_frame_or_scale_is_said_so_when_no_floor_is_found():
    from pimm_agents.scans.segment import segment_cloud
    from pimm_env.clouds.read import read_cloud
    from pimm_env.errors import PerceptionError
    from tests.conftest import shared_file

    room = read_cloud(shared_file("real", "scans", "room_scan1.pcd")).points.astype(float)
    with pytest.raises(PerceptionError, match=r"lie around \[0.0, 0.0, 50.0\], 50.0 m from the origin"):
        segment_cloud(room + np.array([0.0, 0.0, 50.0]), None)  # type: ignore[arg-type]
    with pytest.raises(PerceptionError, match=r"median range is 0.00\d+ m: is it in kilometres"):
        segment_cloud(room / 1000.0, None)  # type: ignore[arg-type]
