"""Segmentation of scans of any LiDAR layout and mount: IoU on every return, as a user's scan is segmented.

For each of ``scans`` random free poses of a world (drawn with ``seed``), each layout casts its rays from a
mount ``height`` m up (``cast_sensor_rays``; 0.01 m range noise, as the simulator's), and the scan's returns
go through ``segment_cloud`` as a file's would: the floor fit measures the height, nothing else is told
(``given_height``: the height is given, as from a sensors file).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from pimm_agents.measurement.perception_quality import confusion_matrix, segmentation_scores
from pimm_env.sim.sensors import LIDAR_3D, NON_REPETITIVE, Lidar3DConfig, scan_directions, scan_layout
from pimm_env.world.model import Element
from pimm_env.world.semantics import CLASS_NAMES

#: the layouts measured: presets by name, and "mid-360" for a non-repetitive pattern
LAYOUT_NAMES = ("thesis", "os0-64", "vlp-16", "os1-128", NON_REPETITIVE)
#: objects listed by ``by_object``: those with the most mislabelled returns
OBJECTS_LISTED = 10


@dataclass(frozen=True)
class LayoutScan:
    """One simulated scan of a layout: its returns (sensor frame), their true classes, and the rays (sensor-frame
    unit directions) and mount that gave them."""

    points: np.ndarray
    labels: np.ndarray
    directions: np.ndarray
    mount: Lidar3DConfig


def layout_scan(env: Any, name: str, height: float, rng: np.random.Generator) -> LayoutScan:
    """One scan of layout ``name`` from the env's current pose, ``height`` m up."""
    mount = replace(scan_layout(name), height=height)  # level: its frame is the sensor's
    directions = scan_directions(name, mount, rng)
    ranges, labels = env.cast_sensor_rays(directions, mount)
    hit = np.isfinite(ranges) & (ranges >= mount.min_range)
    ranges = ranges[hit] + rng.normal(0.0, 0.01, int(hit.sum()))
    return LayoutScan(directions[hit] * ranges[:, None], labels[hit], directions[hit], mount)


def object_errors(
    elements: list[Element], labelled: dict[int, np.ndarray], top: int = OBJECTS_LISTED
) -> list[dict[str, Any]]:
    """The ``top`` objects whose returns were labelled other than their class most often: per object its name,
    its class, its returns, how many were wrong and how many got each class (``labelled``: element index ->
    counts per class)."""
    rows: list[dict[str, Any]] = []
    for index, counts in labelled.items():
        own = int(elements[index].semantic)
        rows.append(
            {
                "name": elements[index].name,
                "class": CLASS_NAMES[own],
                "returns": int(counts.sum()),
                "wrong": int(counts.sum() - counts[own]),
                "labelled": {name: int(counts[c]) for c, name in enumerate(CLASS_NAMES)},
            }
        )
    rows.sort(key=lambda row: (-int(row["wrong"]), str(row["name"])))
    return rows[:top]


def measure_layouts(
    world: str,
    weights: Path,
    scans: int,
    seed: int,
    heights: tuple[float, ...] = (0.5,),
    layouts: tuple[str, ...] = LAYOUT_NAMES,
    given_height: bool = False,
    by_object: bool = False,
) -> dict[str, Any]:
    """Per layout and mount height: IoU over all returns, and the measured height's median error; with
    ``by_object``, also the world's objects whose returns were labelled wrong most often (``objects``)."""
    from pimm_agents.perception.segmenter import load_segmenter
    from pimm_agents.scans.segment import segment_cloud
    from pimm_env.envs.iilab_env import IILabEnv
    from pimm_env.envs.sim_config import SimConfig
    from pimm_env.mapping.derived_maps import ensure_derived_maps
    from pimm_env.world.files import load_world

    segmenter = load_segmenter(weights)
    ensure_derived_maps(load_world(world))
    env = IILabEnv(world=world, config=SimConfig(lidar3d=replace(LIDAR_3D["thesis"], enabled=False)))
    rng = np.random.default_rng(seed)
    poses = [int(rng.integers(0, 1 << 31)) for _ in range(scans)]
    report: dict[str, Any] = {}
    try:
        for name in layouts:
            for height in heights:
                confusion = np.zeros((4, 4), dtype=np.int64)
                per_object: dict[int, np.ndarray] = {}
                errors = []
                for pose_seed in poses:
                    env.reset(seed=pose_seed)
                    scan = layout_scan(env, name, height, rng)
                    result = segment_cloud(scan.points, segmenter, height if given_height else None)
                    confusion += confusion_matrix(result.labels, scan.labels)
                    errors.append(abs(result.sensor_height - height))
                    if by_object:
                        hit = env.sensor_ray_elements(scan.directions, scan.mount)
                        _count_by_object(per_object, hit, result.labels)
                scores = segmentation_scores(confusion, scans)
                report[f"{name}@{height:g}m"] = {
                    **scores,
                    "returns": int(confusion.sum()),
                    "height_error_m": float(np.median(errors)),
                }
                if by_object:
                    report[f"{name}@{height:g}m"]["objects"] = object_errors(env.world.elements, per_object)
    finally:
        env.close()
    return report


def _count_by_object(labelled: dict[int, np.ndarray], elements: np.ndarray, predicted: np.ndarray) -> None:
    """Add one scan's labels to ``labelled`` (element index -> counts per class) by the element each return lay
    on (``elements``; -1, a walker or nothing, is left out)."""
    on = elements >= 0
    if not on.any():
        return
    classes = len(CLASS_NAMES)
    pairs = elements[on] * classes + predicted[on].astype(np.int64)
    counts = np.bincount(pairs, minlength=(int(elements.max()) + 1) * classes).reshape(-1, classes)
    for index in np.flatnonzero(counts.sum(axis=1)):
        labelled.setdefault(int(index), np.zeros(classes, dtype=np.int64))[:] += counts[index]
