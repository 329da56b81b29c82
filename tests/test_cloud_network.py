"""The layout-free network: its features, its datasets of any LiDAR, training, and segmenting with it."""

import numpy as np
import pytest

from pimm_agents.perception.cloud_features import CLOUD_FEATURES, cloud_features, smallest_eigen, voxelize
from pimm_agents.perception.pointnet import PointNetConfig, PointNetSegmenter, load_checkpoint, save_checkpoint

TINY = PointNetConfig(
    points=256, local_widths=(8, 16), global_widths=(16, 32), head_widths=(16, 8), descriptor_dim=8,
    inputs="cloud", context_offsets=(),
)  # fmt: skip


def test_the_closed_form_eigenpair_matches_numpy():
    rng = np.random.default_rng(0)
    c = rng.normal(size=(500, 3, 3))
    c = c @ c.transpose(0, 2, 1)
    value, vector = smallest_eigen(c[:, 0, 0], c[:, 1, 1], c[:, 2, 2], c[:, 0, 1], c[:, 1, 2], c[:, 0, 2])
    w, v = np.linalg.eigh(c)
    assert np.allclose(value, w[:, 0], atol=1e-9)
    assert np.allclose(np.abs(np.einsum("ij,ij->i", vector, v[:, :, 0])), 1.0, atol=1e-9)


def box_room(rng, height=2.5, sensor=0.5):
    """Returns of a 6 x 4 m room's walls, floor and ceiling seen from a sensor ``sensor`` m up at (1, 0.5)."""
    n = 20_000
    u, v = rng.uniform(0, 1, n), rng.uniform(0, 1, n)
    side = rng.integers(0, 6, n)
    x = np.select([side == 0, side == 1], [np.zeros(n), np.full(n, 6.0)], 6 * u)
    y = np.select([side == 2, side == 3], [np.zeros(n), np.full(n, 4.0)], 4 * np.where(side < 2, u, v))
    z = np.select([side == 4, side == 5], [np.zeros(n), np.full(n, height)], height * v)
    labels = np.select([side < 4, side == 4], [0, 2], 1)
    return np.column_stack([x - 1.0, y - 0.5, z - sensor]), labels


def test_features_say_what_a_surface_is():
    points, labels = box_room(np.random.default_rng(1))
    thinned = cloud_features(points, 0.5, 1000)
    f = dict(zip(CLOUD_FEATURES, thinned.features.T, strict=True))
    chosen = labels[np.unique(thinned.voxel_of, return_index=True)[1]][thinned.chosen]  # a voxel of one surface
    walls, floors = chosen == 0, chosen == 2
    assert np.median(f["normal_z"][walls]) < 0.1 and np.median(f["normal_z"][floors]) > 0.9
    assert np.median(f["surface_span"][walls]) > 2.0  # a wall runs from floor to ceiling at its range
    assert np.allclose(np.median(f["height"][floors]), 0.0, atol=0.05)  # height above the floor, not the sensor
    assert thinned.features.shape == (1000, len(CLOUD_FEATURES)) and thinned.features.dtype == np.float32


def test_voxels_hold_the_mean_of_their_returns():
    points = np.array([[0.01, 0.01, 0.01], [0.03, 0.01, 0.01], [0.5, 0.5, 0.5]])
    means, voxel_of = voxelize(points, 0.08)
    assert len(means) == 2 and voxel_of[0] == voxel_of[1] != voxel_of[2]
    assert np.allclose(means[voxel_of[0]], [0.02, 0.01, 0.01])


def test_cloud_weights_round_trip_and_segment_any_point_set(tmp_path):
    import torch

    from pimm_agents.perception.segmenter import CloudSegmenter, load_segmenter
    from pimm_agents.scans.segment import segment_cloud

    torch.manual_seed(0)
    path = tmp_path / "cloud.pt"
    save_checkpoint(PointNetSegmenter(TINY).eval(), path, {"command": "test"})
    model, _ = load_checkpoint(path)
    assert model.config.inputs == "cloud" and model.config.input_channels == len(CLOUD_FEATURES)
    segmenter = load_segmenter(path)
    assert isinstance(segmenter, CloudSegmenter)
    points, _ = box_room(np.random.default_rng(2), sensor=0.9)
    result = segment_cloud(points, segmenter)
    assert result.labels.shape == (len(points),) and set(np.unique(result.labels)) <= {0, 1, 2, 3}
    assert result.sensor_height == pytest.approx(0.9, abs=0.03)
    assert np.linalg.norm(result.descriptor) == pytest.approx(1.0, abs=1e-5)
    shuffled = np.random.default_rng(3).permutation(len(points))
    again = segment_cloud(points[shuffled], segmenter)  # no order, no rings: the same classes per point
    assert np.mean(again.labels == result.labels[shuffled]) > 0.95


def test_a_dataset_of_any_lidar_trains_the_cloud_network(tmp_path):
    from training.cloud_dataset import LAYOUTS, RandomizationConfig, generate, load, save
    from training.train import TrainConfig, train

    config = RandomizationConfig(walkers=1, unmapped=2)
    clouds = generate(["iilab"], 10, seed=4, config=config, progress=False)
    assert len(clouds) == 10 and set(clouds.layouts) <= set(LAYOUTS) and clouds.starts[-1] == len(clouds.points)
    assert np.all((clouds.heights >= 0.2) & (clouds.heights <= 1.8))
    save(clouds, tmp_path / "clouds.npz")
    again = load(tmp_path / "clouds.npz")
    assert np.array_equal(again.labels, clouds.labels) and np.array_equal(again.starts, clouds.starts)
    again_made = generate(["iilab"], 10, seed=4, config=config, progress=False)
    assert np.array_equal(again_made.points, clouds.points)  # seeded: the same scans
    from scipy.spatial import cKDTree

    from pimm_agents.perception.cloud_features import cloud_features
    from training.train import CloudSampler

    sampler = CloudSampler(again, TINY)
    for i in range(3):  # the labels the network learns are those of the stored points where it looks
        _, labels = sampler.sample(i, 0)
        points, stored = again.scan(i)
        thinned = cloud_features(points, float(again.heights[i]), TINY.points)
        _, nearest = cKDTree(points).query(thinned.points[thinned.chosen])
        assert np.mean(labels == stored[nearest]) > 0.99
    _, history = train(
        again.subset(np.arange(8)),
        again.subset(np.arange(8, 10)),
        TrainConfig(epochs=1, batch_pairs=2),
        TINY,
        progress=False,
    )
    assert len(history) == 1 and np.isfinite(history[0]["loss"])


def test_a_held_out_building_cannot_be_made_into_training_clouds(tmp_path):
    from typer.testing import CliRunner

    from training.__main__ import app

    result = CliRunner().invoke(
        app, ["clouds", "--world", "build/worlds/gen-915/world.yaml", "--out", str(tmp_path / "c.npz")]
    )
    assert result.exit_code == 2 and "gen-915/world.yaml is a held-out" in " ".join(result.output.split())


def test_pimm_with_cloud_weights_reads_another_lidar_as_it_is(tmp_path):
    """No resampling into a grid: a 16-ring scan goes to the layout-free network, told the mount height."""
    import torch

    from pimm_agents.perception.fingerprint_map import FingerprintMap
    from pimm_agents.perception.segmenter import CloudSegmenter
    from pimm_agents.pimm.config import PimmConfig
    from pimm_agents.pimm.localizer import PimmLocalizer
    from pimm_env.envs.iilab_env import IILabEnv
    from pimm_env.mapping.derived_maps import ensure_derived_maps
    from pimm_env.sim.sensors import LIDAR_3D
    from pimm_env.world.files import load_world

    torch.manual_seed(0)
    path = tmp_path / "cloud.pt"
    save_checkpoint(PointNetSegmenter(TINY).eval(), path, {"command": "test"})
    segmenter = CloudSegmenter(path)
    maps = ensure_derived_maps(load_world("iilab"))
    rng = np.random.default_rng(0)
    descriptors = rng.normal(size=(20, TINY.descriptor_dim)).astype(np.float32)
    descriptors /= np.linalg.norm(descriptors, axis=1, keepdims=True)
    fingerprints = FingerprintMap(descriptors, rng.uniform(-20, 0, (20, 2)))
    lidar = LIDAR_3D["vlp-16"]
    pimm = PimmLocalizer(maps.occupancy, maps.corners, segmenter, fingerprints, PimmConfig(), lidar3d=lidar)
    assert pimm.resample is None and segmenter.sensor_height == lidar.height
    env = IILabEnv(sensors="vlp-16")
    obs, _ = env.reset(seed=0)
    pimm.reset(seed=0)
    perceived = 0
    for _ in range(60):
        estimate = pimm.update(obs)
        assert np.isfinite(estimate.pose).all()
        perceived += "segmentation" in estimate.timings
        obs, *_ = env.step(np.array([0.3, 0.0], dtype=np.float32))
    env.close()
    assert perceived >= 2
