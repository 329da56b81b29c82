"""``evaluate.py segment FILE``: one scan from a file, segmented, its corners found, written and drawn; with
``reference=True`` also scored against the plane-fit reference (``plane_reference.py``).

Written to a new ``out/<time>_segment_<name>/`` (none when the file cannot be read or segmented):
``labels.npy`` (int8, one class per point of the file, -1 where it held no return),
``labelled.ply`` (the returns coloured by class, in the file's frame), ``corners.json`` (level sensor frame),
``views.png`` (from above and from the side); with the reference also ``reference_labels.npy`` and
``reference.png``. Returns the record ``--json`` prints.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from pimm_env.world.semantics import CLASS_NAMES


def segment_file(
    path: Path,
    weights: Path,
    out: Path,
    sensor_height: float | None = None,
    roll_pitch_deg: tuple[float, float] | None = None,
    drop_invalid: bool = False,
    reference: bool = False,
    seed: int = 0,
) -> dict[str, Any]:
    from pimm_agents.experiments.experiment import new_folder
    from pimm_agents.perception.segmenter import load_segmenter
    from pimm_agents.results.cloud_figures import draw_labelled_cloud
    from pimm_agents.scans.segment import segment_cloud
    from pimm_agents.scans.upright import standing_off_faces
    from pimm_env.clouds.read import read_cloud
    from pimm_env.errors import PerceptionError

    cloud = read_cloud(path, drop_invalid)
    try:
        result = segment_cloud(cloud.points, load_segmenter(weights), sensor_height, roll_pitch_deg, seed=seed)
    except PerceptionError as error:  # said of the user's file
        raise PerceptionError(f"{path}: {error}") from None
    standing = standing_off_faces(result.level_points)
    out = new_folder(out, f"segment_{Path(path).stem}")  # only once the scan was read and segmented
    labels = np.full(cloud.total, -1, dtype=np.int8)
    labels[cloud.rows] = result.labels
    np.save(out / "labels.npy", labels)
    _write_ply(out / "labelled.ply", cloud.points, result.labels)
    corners = [
        {"x": round(f.x, 3), "y": round(f.y, 3), "theta": round(f.theta, 4), "confidence": round(f.confidence, 3)}
        for f in result.corners.features
    ]
    (out / "corners.json").write_text(json.dumps({"frame": "level sensor frame", "corners": corners}, indent=1))
    found = np.array([[c["x"], c["y"]] for c in corners]).reshape(-1, 2)
    record: dict[str, Any] = {
        "file": str(path),
        "points": cloud.total,
        "returns": len(cloud.points),
        "left_out": cloud.left_out,
        "far_outliers": result.far_outliers,  # stray returns set aside, labelled clutter (scans/segment.py)
        "offset": [float(v) for v in cloud.offset],  # taken off a georeferenced file's coordinates
        "organized": list(cloud.organized) if cloud.organized else None,
        "sensor_height_m": round(result.sensor_height, 3),
        "height_measured": result.height_measured,
        "tilt_deg": round(result.tilt_deg, 2),
        "hanging_ratio": round(result.hanging_ratio, 2),
        "standing_off": standing,  # returns just off each face (scans/upright.py)
        "warnings": _warnings(result, cloud.points, standing, roll_pitch_deg is not None),
        "in_network_view": round(result.in_view, 3),
        "shares": {name: round(float(np.mean(result.labels == k)), 4) for k, name in enumerate(CLASS_NAMES)},
        "corners": corners,
        "weights": str(weights),
        "out": str(out),
    }
    reference_corners = None
    if reference:
        from pimm_agents.measurement.plane_reference import scored_against_reference

        ref, record["reference"] = scored_against_reference(cloud.points, result.labels, found, seed)
        reference_labels = np.full(cloud.total, -1, dtype=np.int8)
        reference_labels[cloud.rows] = ref.labels
        np.save(out / "reference_labels.npy", reference_labels)
        reference_corners = ref.corners
        draw_labelled_cloud(
            result.level_points,
            ref.labels,
            ref.corners,
            out / "reference.png",
            f"{Path(path).name}: plane-fit reference",
        )
    draw_labelled_cloud(
        result.level_points, result.labels, found, out / "views.png", f"{Path(path).name}: classes", reference_corners
    )
    (out / "segment.json").write_text(json.dumps(record, indent=1))
    return record


def _warnings(result: Any, points: np.ndarray, standing: dict[str, int], mount_given: bool) -> list[str]:
    """What a user should look at: a scan that did not stand z-up in its file (on its side, upside down), or was
    turned far to level it."""
    from pimm_agents.scans.upright import upright_warnings

    found = upright_warnings(points, standing, mount_given)
    if not found and result.hanging_ratio > 1.0:
        found.append(
            f"the scan looks upside down: {result.hanging_ratio:.1f} times as many returns within a metre under its"
            " top as within a metre over its floor (furniture stands on a floor); if it is, give its mount as"
            " turned over (--sensors with lidar3d mount_roll_deg: 180)"
        )
    if result.tilt_deg > 30.0:
        found.append(f"the scan was turned {result.tilt_deg:.0f} deg to level it: is its file z-up?")
    return found


def _write_ply(path: Path, points: np.ndarray, labels: np.ndarray) -> None:
    """The returns coloured by class (ASCII-free binary PLY that any viewer opens)."""
    import open3d as o3d

    from pimm_env.envs.render import CLASS_COLORS

    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.asarray(points, dtype=np.float64)))
    cloud.colors = o3d.utility.Vector3dVector(CLASS_COLORS[np.clip(labels, 0, 3)] / 255.0)
    o3d.io.write_point_cloud(path, cloud, write_ascii=False)
