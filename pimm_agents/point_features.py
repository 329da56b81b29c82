"""Per-point input features of the segmentation network, computed from the organized 3D scan.

The 3D LiDAR's cloud is organized (layers x points per layer), so each point's grid neighbours give a surface
normal for the price of two differences and a cross product. Every feature is invariant to a rotation of the
scan about the vertical axis, so the network's labels and its global descriptor do not depend on the robot's
heading by construction (the thesis had to teach that with random rotations).
"""

from __future__ import annotations

import numpy as np

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
        raise ValueError(f"cloud has {values.shape[0]} points; the {layers} x {points_per_layer} scan has {expected}")
    return values.reshape(layers, points_per_layer, *values.shape[1:])


def _neighbour(grid: np.ndarray, valid: np.ndarray, axis: int, step: int) -> tuple[np.ndarray, np.ndarray]:
    """Each point's neighbour ``step`` cells along ``axis`` (azimuth wraps around, layers do not)."""
    shifted = np.roll(grid, -step, axis=axis)
    ok = np.roll(valid, -step, axis=axis)
    if axis == 0:
        edge = slice(-1, None) if step > 0 else slice(0, 1)
        ok = ok.copy()
        ok[edge] = False
    return shifted, ok


def point_features(cloud: np.ndarray, mask: np.ndarray, layers: int, points_per_layer: int) -> np.ndarray:
    """Features (layers * points_per_layer, NUM_FEATURES) float32 of every point; rows of masked points are 0.

    ``cloud`` is the sensor-frame cloud in scan order, ``mask`` marks real returns; NaN points count as masked.
    """
    cloud = np.asarray(cloud, dtype=np.float32)
    if cloud.ndim != 2 or cloud.shape[1] != 3:
        raise ValueError(f"cloud must be (N, 3), got shape {cloud.shape}")
    valid = np.asarray(mask, dtype=bool).reshape(-1) & np.isfinite(cloud).all(axis=1)
    if valid.shape[0] != cloud.shape[0]:
        raise ValueError(f"cloud_mask has {valid.shape[0]} entries for {cloud.shape[0]} points")
    pts = organized(np.where(valid[:, None], cloud, 0.0), layers, points_per_layer)
    ok = organized(valid, layers, points_per_layer)

    tangents = []
    for axis in (1, 0):
        ahead, ok_ahead = _neighbour(pts, ok, axis, 1)
        behind, ok_behind = _neighbour(pts, ok, axis, -1)
        # central difference where both neighbours exist, one-sided otherwise
        both = ok_ahead & ok_behind
        diff = np.where(both[..., None], ahead - behind, 0.0)
        diff = np.where((ok_ahead & ~ok_behind)[..., None], ahead - pts, diff)
        diff = np.where((~ok_ahead & ok_behind)[..., None], pts - behind, diff)
        tangents.append((diff, ok_ahead | ok_behind, ahead, behind, both))
    normal = np.cross(tangents[0][0], tangents[1][0])
    norm = np.linalg.norm(normal, axis=-1, keepdims=True)
    has_normal = (norm[..., 0] > 1e-9) & tangents[0][1] & tangents[1][1]
    normal = np.where(has_normal[..., None], normal / np.maximum(norm, 1e-9), 0.0)

    horizontal = np.hypot(pts[..., 0], pts[..., 1])
    radial = np.where(horizontal[..., None] > 1e-6, pts[..., :2] / np.maximum(horizontal, 1e-6)[..., None], 0.0)
    column_max = np.where(ok, horizontal, 0.0).max(axis=0, keepdims=True)
    column_top = np.where(ok, pts[..., 2], -np.inf).max(axis=0, keepdims=True)
    column_top = np.where(np.isfinite(column_top), column_top, 0.0)
    top = float(pts[..., 2][ok].max()) if ok.any() else 1.0

    # roughness: how far the point is from the mean of its four grid neighbours, along its normal
    neighbour_sum = np.zeros_like(pts)
    neighbour_count = np.zeros(pts.shape[:2], dtype=np.float32)
    for _, _, ahead, behind, both in tangents:
        neighbour_sum += np.where(both[..., None], ahead + behind, 0.0)
        neighbour_count += 2 * both
    mean = neighbour_sum / np.maximum(neighbour_count, 1)[..., None]
    rough = np.where(neighbour_count > 0, np.abs(np.sum((pts - mean) * normal, axis=-1)), ROUGHNESS_CAP)

    features = np.stack(
        [
            pts[..., 2],
            horizontal,
            np.abs(normal[..., 2]),
            np.abs(np.sum(normal[..., :2] * radial, axis=-1)),
            horizontal / np.maximum(column_max, 1e-6),
            pts[..., 2] / max(top, 1e-3),
            np.minimum(rough, ROUGHNESS_CAP),
            column_top - pts[..., 2],
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
    outside = (r < 0) | (r >= layers)
    # one gather for all neighbours; rows beyond the scan read a zero row appended at the end
    padded = np.concatenate([features, np.zeros((1, features.shape[1]), dtype=features.dtype)])
    neighbour[outside] = len(features)
    return padded[neighbour].reshape(len(index), -1).astype(np.float32, copy=False)
