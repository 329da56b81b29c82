"""Any scan through the segmenter: a cloud from a file or from a sensor of any layout.

``segment_cloud(points, segmenter)`` takes the returns of one scan in the sensor's frame, organized or not,
from any LiDAR, and gives every point a class, the scan's descriptor and its corners:

1. the floor is found (``floor.py``): the scan is levelled on it, and the mount height is measured, unless the
   height and the mount's roll and pitch are given;
2. a layout-free network (:class:`CloudSegmenter`, weights of ``cloud`` inputs) reads the levelled points
   themselves: their voxels' features (``cloud_features.py``) with the height above the floor; every voxel
   takes the class of the nearest voxel the network looked at in voxel order, every return its voxel's class;
   a grid network (:class:`Segmenter`, ``grid`` inputs, trained on one layout) reads the scan in its layout
   instead: each of its rays takes the nearest return by elevation and azimuth (``network_layout_cells``),
   heights moved so that the sensor sits at the trained mount height, and each return takes its ray's class;
3. corners are detected on the levelled returns (``corners/detector.py``), in the level sensor frame.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from pimm_agents.corners.detector import CornerDetectorConfig, FeatureList, detect_corners
from pimm_agents.perception.floor import Floor, FloorConfig, estimate_floor
from pimm_agents.perception.segmenter import CloudSegmenter, Segmenter
from pimm_env.errors import PerceptionError
from pimm_env.sim.lidar import Lidar3DConfig, azimuths_3d, elevations_3d, mount_rotation
from pimm_env.world.semantics import SemanticClass


@dataclass(frozen=True)
class CloudSegmentation:
    labels: np.ndarray  # (N,) class per return, as given
    descriptor: np.ndarray
    level_points: np.ndarray  # (N, 3) the returns in the level sensor frame
    sensor_height: float  # m above the floor: given, or measured
    height_measured: bool
    tilt_deg: float  # how far the sensor leaned from level (0 when no floor was found and a height was given)
    corners: FeatureList
    in_view: float  # share of the returns inside the network's vertical field
    leveling: np.ndarray = field(default_factory=lambda: np.eye(3))  # sensor frame -> level frame
    far_outliers: int = 0  # returns set aside as stray (``FAR_OUTLIER``), labelled clutter
    #: returns within a metre under the highest against within a metre over the floor (``hanging_share``): over 1,
    #: more hangs from the ceiling than stands on the floor, and the scan is likely upside down
    hanging_ratio: float = 0.0


#: A return farther than this many times the 99th percentile of the scan's ranges is a stray (a multipath echo, a
#: glitch, a wrong unit): it is set aside from the levelling, the features and the corners, labelled clutter and
#: counted. A room's walls lie within its scan's range spread; one return 100 m off must not set the scale.
FAR_OUTLIER = 3.0


def mount_leveling(roll_deg: float, pitch_deg: float) -> np.ndarray:
    """The rotation from the sensor's frame to the level frame for a mount of this roll and pitch."""
    return mount_rotation(Lidar3DConfig(mount_roll_deg=roll_deg, mount_pitch_deg=pitch_deg))


def network_layout_cells(level: np.ndarray, layout: Lidar3DConfig) -> tuple[np.ndarray, np.ndarray]:
    """For each return, its ray (cell) of ``layout``, and whether it lies within the layout's vertical field.

    Returns outside the field go to the nearest ring, so that each has a cell and a class."""
    horizontal = np.hypot(level[:, 0], level[:, 1])
    elevation = np.arctan2(level[:, 2], horizontal)
    azimuth = np.arctan2(level[:, 1], level[:, 0])
    rings = elevations_3d(layout)
    spacing = (rings[-1] - rings[0]) / max(1, layout.layers - 1)
    ring = np.clip(np.round((elevation - rings[0]) / spacing), 0, layout.layers - 1).astype(np.int64)
    inside = np.abs(elevation - rings[ring]) <= spacing / 2 + 1e-9
    step = 2 * np.pi / layout.points_per_layer
    column = np.round((azimuth - azimuths_3d(layout)[0]) / step).astype(np.int64) % layout.points_per_layer
    return ring * layout.points_per_layer + column, inside


def hanging_ratio(level: np.ndarray, height: float) -> float:
    """Returns between 0.15 and 1.2 m under the scan's top (its 99.5th height percentile) over those between 0.15
    and 1.2 m over its floor. Desks, chairs and cabinets stand on a floor: under an upright scan's ceiling there
    is less (on the real room scan, 0.33; turned upside down, 2.48)."""
    z = np.asarray(level, dtype=float)[:, 2] + height
    top = float(np.percentile(z, 99.5))
    lower = np.count_nonzero((z > 0.15) & (z < 1.2))
    upper = np.count_nonzero((z > top - 1.2) & (z < top - 0.15))
    return float(upper) / float(max(int(lower), 1))


def segment_cloud(
    points: np.ndarray,
    segmenter: Segmenter | CloudSegmenter,
    sensor_height: float | None = None,
    roll_pitch_deg: tuple[float, float] | None = None,
    corners: CornerDetectorConfig | None = None,
    floor: FloorConfig = FloorConfig(),
    seed: int = 0,
) -> CloudSegmentation:
    """Classes, descriptor and corners of one scan's returns ``points`` (N, 3, sensor frame, finite).

    ``roll_pitch_deg``: the mount's roll and pitch (deg, as a URDF joint's), which level the scan instead of its
    floor."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if len(points) == 0 or not np.isfinite(points).all():
        raise PerceptionError("segment_cloud takes the scan's returns: a non-empty (N, 3) array of finite points")
    ranges = np.linalg.norm(points, axis=1)
    kept = ranges <= FAR_OUTLIER * max(float(np.percentile(ranges, 99)), 1e-6)
    if not kept.all():
        inner = segment_cloud(points[kept], segmenter, sensor_height, roll_pitch_deg, corners, floor, seed)
        labels = np.full(len(points), int(SemanticClass.CLUTTER), dtype=inner.labels.dtype)
        labels[kept] = inner.labels
        level = np.empty_like(points)
        level[kept] = inner.level_points
        level[~kept] = points[~kept] @ inner.leveling.T
        return replace(inner, labels=labels, level_points=level, far_outliers=int(np.count_nonzero(~kept)))
    found: Floor | None
    try:
        found = estimate_floor(points, floor, seed)
    except PerceptionError as error:
        if sensor_height is None:
            raise PerceptionError(f"{error}{_frame_hint(points)}") from None
        found = None  # the height is given; the scan is taken as level
    if roll_pitch_deg is not None:
        leveling = mount_leveling(*roll_pitch_deg)
    else:
        leveling = found.leveling if found is not None else np.eye(3)
    level = points @ leveling.T
    height = float(sensor_height if sensor_height is not None else found.height)  # type: ignore[union-attr]
    if not 0.0 < height < 10.0:
        scale = float(np.percentile(np.linalg.norm(points, axis=1), 50))
        units = (
            f"; the scan's median range is {scale:.0f}: is it in millimetres (scale it by 0.001)?"
            if scale > 100
            else ""
        )
        raise PerceptionError(
            f"sensor height {height:.3f} m: give the sensor's height above the floor in metres{units}"
        )
    if isinstance(segmenter, CloudSegmenter):
        labels, descriptor = segmenter.segment_points(level, height)
        in_view = 1.0
    else:
        labels, descriptor, in_view = _through_grid(level, height, segmenter)
    structural = np.isin(labels, (int(SemanticClass.WALL), int(SemanticClass.CEILING)))
    features = detect_corners(level[structural], labels[structural], config=corners, seed=seed)
    return CloudSegmentation(
        hanging_ratio=hanging_ratio(level, height),
        labels=labels,
        descriptor=descriptor,
        level_points=level,
        sensor_height=height,
        height_measured=sensor_height is None,
        tilt_deg=float(np.degrees(np.arccos(np.clip(leveling[2, 2], -1.0, 1.0)))),
        corners=features,
        in_view=in_view,
        leveling=leveling,
    )


def _frame_hint(points: np.ndarray) -> str:
    """What may be wrong with a scan whose floor cannot be found: its scale, or its frame."""
    ranges = np.linalg.norm(points, axis=1)
    median = float(np.median(ranges))
    if median < 0.05:
        return f" (the scan's median range is {median:.4f} m: is it in kilometres, or scaled?)"
    centre = np.median(points, axis=0)
    spread = float(np.median(np.linalg.norm(points - centre, axis=1)))
    if np.linalg.norm(centre) > 2.0 * spread:
        return (
            f" (the returns lie around {np.round(centre, 1).tolist()}, {np.linalg.norm(centre):.1f} m from the origin:"
            " a scan's returns are in the sensor's frame, the sensor at the origin)"
        )
    return ""


def _through_grid(level: np.ndarray, height: float, segmenter: Segmenter) -> tuple[np.ndarray, np.ndarray, float]:
    layout = replace(Lidar3DConfig(), layers=segmenter.layers, points_per_layer=segmenter.points_per_layer)
    cell, inside = network_layout_cells(level, layout)
    order = np.argsort(-np.linalg.norm(level, axis=1), kind="stable")  # far first: the nearest return wins
    chosen = np.full(layout.num_points, -1, dtype=np.int64)
    chosen[cell[order]] = order
    mask = chosen >= 0
    cloud = np.zeros((layout.num_points, 3), dtype=np.float32)
    cloud[mask] = level[chosen[mask]]
    cloud[mask, 2] += height - layout.height  # the network's trained mount height
    result = segmenter.segment(cloud, mask)
    return result.labels[cell].astype(np.int8), result.descriptor, float(np.mean(inside))
