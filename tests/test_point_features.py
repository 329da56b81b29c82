import numpy as np
import pytest

from pimm_agents.perception.point_features import FEATURES, point_features, with_context
from pimm_env.sim.lidar import Lidar3DConfig, directions_3d

L3 = Lidar3DConfig(layers=40, points_per_layer=36, vertical_fov_deg=120.0)


def box_room_cloud(half: float = 3.0, floor: float = -0.5, ceiling: float = 2.0) -> tuple[np.ndarray, np.ndarray]:
    """Rays of a small LiDAR inside a square room (walls at +-half), cast analytically."""
    d = directions_3d(L3)
    with np.errstate(divide="ignore"):
        t_wall = np.minimum(half / np.abs(d[:, 0]), half / np.abs(d[:, 1]))
        t_z = np.where(d[:, 2] > 0, ceiling / d[:, 2], np.where(d[:, 2] < 0, floor / d[:, 2], np.inf))
    t = np.minimum(t_wall, t_z)
    return (d * t[:, None]).astype(np.float32), np.ones(len(d), dtype=bool)


def test_normals_of_walls_floor_and_ceiling():
    cloud, mask = box_room_cloud()
    feats = point_features(cloud, mask, L3.layers, L3.points_per_layer)
    nz = feats[:, FEATURES.index("normal_z")]
    horizontal = np.abs(cloud[:, 2]) > 0
    on_floor = np.isclose(cloud[:, 2], -0.5, atol=1e-4)
    on_ceiling = np.isclose(cloud[:, 2], 2.0, atol=1e-4)
    on_wall = ~(on_floor | on_ceiling) & horizontal
    # interior points of each surface (away from the edges where neighbours are on another surface)
    assert np.median(nz[on_floor]) > 0.99 and np.median(nz[on_ceiling]) > 0.99
    assert np.median(nz[on_wall]) < 0.01
    assert np.allclose(feats[:, FEATURES.index("height")], cloud[:, 2])


def test_features_do_not_change_when_the_robot_turns():
    cloud, mask = box_room_cloud(half=2.5)
    rng = np.random.default_rng(0)
    cloud = cloud * (1 + 0.01 * rng.standard_normal((len(cloud), 1))).astype(np.float32)
    step = 2 * np.pi / L3.points_per_layer
    turn = 5 * step
    c, s = np.cos(turn), np.sin(turn)
    rotated = cloud @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]], dtype=np.float32).T
    # the turned scan is the same rays, five columns further on
    rolled = np.roll(rotated.reshape(L3.layers, L3.points_per_layer, 3), -5, axis=1).reshape(-1, 3)
    a = point_features(cloud, mask, L3.layers, L3.points_per_layer)
    b = point_features(rolled, mask, L3.layers, L3.points_per_layer)
    b = np.roll(b.reshape(L3.layers, L3.points_per_layer, -1), 5, axis=1).reshape(a.shape)
    assert np.allclose(a, b, atol=1e-4)


def test_masked_and_nan_points_are_zero_and_do_not_spread():
    cloud, mask = box_room_cloud()
    cloud[10] = np.nan
    mask[20] = False
    feats = point_features(cloud, mask, L3.layers, L3.points_per_layer)
    assert np.isfinite(feats).all()
    assert not feats[10].any() and not feats[20].any()


def test_wrong_cloud_size_names_the_scan_shape():
    with pytest.raises(ValueError, match="40 x 36"):
        point_features(np.zeros((10, 3)), np.ones(10, bool), L3.layers, L3.points_per_layer)
    with pytest.raises(ValueError, match="cloud must be"):
        point_features(np.zeros((1440, 2)), np.ones(1440, bool), L3.layers, L3.points_per_layer)


def test_context_appends_grid_neighbours_and_zeros_beyond_the_edge():
    layers, per_layer = 4, 10
    feats = np.arange(layers * per_layer, dtype=np.float32)[:, None] * np.ones((1, 2), np.float32)
    index = np.array([0 * per_layer + 9, 3 * per_layer + 0])  # (layer 0, col 9) and (layer 3, col 0)
    out = with_context(feats, index, layers, per_layer, offsets=((0, 1), (1, 0), (-1, 0)))
    assert out.shape == (2, 8)
    # (0, 9): right neighbour wraps to (0, 0); up is (1, 9); down is beyond the bottom layer
    assert out[0].tolist() == [9, 9, 0, 0, 19, 19, 0, 0]
    # (3, 0): right is (3, 1); up is beyond the top layer; down is (2, 0)
    assert out[1].tolist() == [30, 30, 31, 31, 0, 0, 20, 20]
