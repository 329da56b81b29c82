"""Per-point input features of the segmentation network, computed from the organized 3D scan.

The 3D LiDAR's cloud is organized (layers x points per layer), so each point's grid neighbours give a surface
normal for the price of two differences and a cross product. Every feature is invariant to a rotation of the
scan about the vertical axis, so the network's labels and its global descriptor do not depend on the robot's
heading by construction (the thesis had to teach that with random rotations).
"""

from __future__ import annotations

import numpy as np

from pimm_agents.perception.point_arrays import finite_rows
from pimm_env.errors import ObservationError

#: Names of the feature channels, in order.
FEATURES: tuple[str, ...] = (
    "height",  # z in the sensor frame (m)
    "horizontal_range",  # sqrt(x^2 + y^2) (m)
    "normal_z",  # |n_z| of the local surface normal
    "normal_radial",  # |n . radial|: a surface facing the sensor (1) or seen edge-on (0)
    "column_depth",  # horizontal range / the largest horizontal range in the same azimuth column
    "scan_height",  # height / the highest point of the scan: how far up towards the ceiling
    "roughness",  # distance of the point from the plane of its neighbours (m), capped
    "below_column_top",  # how far (m) under the highest return of its azimuth column: beams hang under ceilings
    "before_column_end",  # how far (m) short of the farthest return of its column: posts stand before walls
)
NUM_FEATURES = len(FEATURES)
ROUGHNESS_CAP = 0.2
#: Grid neighbours (layer step, column step) whose features are appended to each point's own: a fixed
#: receptive field on the organized scan, so the network sees whether a surface goes on or stops nearby.
CONTEXT_OFFSETS: tuple[tuple[int, int], ...] = (
    (0, 3), (0, -3), (0, 10), (0, -10), (0, 25), (0, -25),
    (2, 0), (-2, 0), (6, 0), (-6, 0), (12, 0), (-12, 0),
)  # fmt: skip


def organized(values: np.ndarray, layers: int, points_per_layer: int) -> np.ndarray:
    """Reshape a flat per-point array (layer by layer) to (layers, points_per_layer, ...)."""
    expected = layers * points_per_layer
    if values.shape[0] != expected:
        raise ObservationError(
            f"cloud has {values.shape[0]} points; the {layers} x {points_per_layer} scan has {expected}"
        )
    return values.reshape(layers, points_per_layer, *values.shape[1:])


def _shift(grid: np.ndarray, axis: int, step: int) -> np.ndarray:
    """Each cell's neighbour ``step`` cells along ``axis`` (azimuth wraps; layers wrap too, see _shift_ok)."""
    return np.roll(grid, -step, axis=axis)


def _shift_ok(ok: np.ndarray, axis: int, step: int) -> np.ndarray:
    """Whether that neighbour is a return; beyond the top or bottom layer there is none."""
    shifted = np.roll(ok, -step, axis=axis)
    if axis == 0:
        shifted[-1 if step > 0 else 0] = False
    return shifted


def valid_returns(cloud: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """(N,) bool: the rows of the (N, 3) ``cloud`` that are returns, marked in ``mask`` and finite."""
    mask = np.asarray(mask, dtype=bool).reshape(-1)
    if len(mask) != len(cloud):
        raise ObservationError(f"cloud_mask has {len(mask)} entries for {len(cloud)} points")
    return mask & finite_rows(cloud)


def point_features(cloud: np.ndarray, mask: np.ndarray, layers: int, points_per_layer: int) -> np.ndarray:
    """Features (layers * points_per_layer, NUM_FEATURES) float32 of every point; rows of masked points are 0.

    ``cloud`` is the sensor-frame cloud in scan order, ``mask`` marks real returns; NaN points count as masked.
    Coordinates are handled as three (layers, points) planes, so every operation runs on plain 2-D arrays.
    """
    cloud = np.asarray(cloud, dtype=np.float32)
    if cloud.ndim != 2 or cloud.shape[1] != 3:
        raise ObservationError(f"cloud must be (N, 3), got shape {cloud.shape}")
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


def with_context(
    features: np.ndarray,
    index: np.ndarray,
    layers: int,
    points_per_layer: int,
    offsets: tuple[tuple[int, int], ...] = CONTEXT_OFFSETS,
) -> np.ndarray:
    """Rows ``index`` of ``features`` with the features of their grid neighbours at ``offsets`` appended
    (azimuth wraps; a neighbour beyond the top or bottom layer, or without a return, contributes zeros)."""
    index = np.asarray(index)
    steps = np.array([(0, 0), *offsets], dtype=np.int64).reshape(-1, 2)
    rows, cols = np.divmod(index, points_per_layer)
    r = rows[:, None] + steps[:, 0]
    neighbour = np.clip(r, 0, layers - 1) * points_per_layer + (cols[:, None] + steps[:, 1]) % points_per_layer
    # one gather for all neighbours, then zeros where a neighbour lies beyond the scan
    gathered = np.asarray(features, dtype=np.float32).take(neighbour, axis=0)
    gathered[(r < 0) | (r >= layers)] = 0.0
    return gathered.reshape(len(index), -1)
