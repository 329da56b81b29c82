import numpy as np
import pytest

from pimm_agents.perception.point_features import (
    FEATURES,
    NUM_FEATURES,
    ROUGHNESS_CAP,
    organized,
    point_features,
    valid_returns,
    with_context,
)
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


def _shift(grid: np.ndarray, axis: int, step: int) -> np.ndarray:
    """Each cell's neighbour ``step`` cells along ``axis`` (azimuth wraps; layers wrap too, see _shift_ok)."""
    return np.roll(grid, -step, axis=axis)


def _shift_ok(ok: np.ndarray, axis: int, step: int) -> np.ndarray:
    """Whether that neighbour is a return; beyond the top or bottom layer there is none."""
    shifted = np.roll(ok, -step, axis=axis)
    if axis == 0:
        shifted[-1 if step > 0 else 0] = False
    return shifted


def numpy_point_features(cloud: np.ndarray, mask: np.ndarray, layers: int, points_per_layer: int) -> np.ndarray:
    """The NumPy expression the compiled features replaced (point_features.py before it)."""
    cloud = np.asarray(cloud, dtype=np.float32)
    valid = valid_returns(cloud, mask)
    ok = organized(valid, layers, points_per_layer)
    p = [np.where(ok, organized(cloud[:, k], layers, points_per_layer), np.float32(0.0)) for k in range(3)]

    tangents, sums = [], [np.zeros_like(p[0]) for _ in range(3)]
    count = np.zeros(ok.shape, dtype=np.float32)
    has_tangent = []
    for axis in (1, 0):
        ok_a, ok_b = _shift_ok(ok, axis, 1), _shift_ok(ok, axis, -1)
        both, only_a, only_b = ok_a & ok_b, ok_a & ~ok_b, ~ok_a & ok_b
        tangent = []
        for k in range(3):
            ahead, behind = _shift(p[k], axis, 1), _shift(p[k], axis, -1)
            # central difference where both neighbours exist, one-sided otherwise
            d = np.where(both, ahead - behind, np.float32(0.0))
            d = np.where(only_a, ahead - p[k], d)
            tangent.append(np.where(only_b, p[k] - behind, d))
            sums[k] += np.where(both, ahead + behind, np.float32(0.0))
        tangents.append(tangent)
        has_tangent.append(ok_a | ok_b)
        count += 2 * both
    (ax, ay, az), (bx, by, bz) = tangents
    n = [ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx]
    norm = np.sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2])
    has_normal = (norm > 1e-9) & has_tangent[0] & has_tangent[1]
    scale = np.where(has_normal, 1.0 / np.maximum(norm, 1e-9), np.float32(0.0))
    n = [c * scale for c in n]

    horizontal = np.hypot(p[0], p[1])
    inv_h = np.where(horizontal > 1e-6, 1.0 / np.maximum(horizontal, 1e-6), np.float32(0.0))
    radial = np.abs(n[0] * p[0] * inv_h + n[1] * p[1] * inv_h)
    column_max = np.where(ok, horizontal, np.float32(0.0)).max(axis=0, keepdims=True)
    column_top = np.where(ok, p[2], -np.inf).max(axis=0, keepdims=True)
    column_top = np.where(np.isfinite(column_top), column_top, 0.0)
    top = float(p[2][ok].max()) if ok.any() else 1.0

    # roughness: how far the point is from the mean of its four grid neighbours, along its normal
    divisor = np.maximum(count, 1)
    offset = sum((p[k] - sums[k] / divisor) * n[k] for k in range(3))
    rough = np.where(count > 0, np.abs(offset), ROUGHNESS_CAP)

    features = np.stack(
        [
            p[2],
            horizontal,
            np.abs(n[2]),
            radial,
            horizontal / np.maximum(column_max, 1e-6),
            p[2] / max(top, 1e-3),
            np.minimum(rough, ROUGHNESS_CAP),
            column_top - p[2],
            column_max - horizontal,
        ],
        axis=-1,
    ).reshape(-1, NUM_FEATURES)
    features[~valid] = 0.0
    return features.astype(np.float32)


def test_compiled_features_equal_the_numpy_expression_to_the_bit():
    """The simulator's scans (room, hall, corridor; some returns masked, some NaN), a one-layer and a tiny
    scan: every feature of every point the same float32 value as the NumPy expression gives."""
    from pimm_env.envs.iilab_env import IILabEnv

    env = IILabEnv()
    rng = np.random.default_rng(0)
    clouds = []
    for seed in range(3):
        obs, _ = env.reset(seed=seed)
        cloud, mask = obs["cloud"].copy(), obs["cloud_mask"].copy()
        mask &= rng.random(len(mask)) > 0.1
        cloud[rng.integers(0, len(cloud), 50)] = np.nan
        clouds.append((cloud, mask, 40, 360))  # the thesis LiDAR: 40 layers x 360
    env.close()
    small, small_mask = box_room_cloud()
    clouds.append((small, small_mask, L3.layers, L3.points_per_layer))
    clouds.append((small[:36], small_mask[:36], 1, 36))
    clouds.append((small[:4], np.zeros(4, dtype=bool), 2, 2))
    for cloud, mask, layers, points in clouds:
        np.testing.assert_array_equal(
            point_features(cloud, mask, layers, points), numpy_point_features(cloud, mask, layers, points)
        )


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
