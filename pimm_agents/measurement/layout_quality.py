"""Segmentation of scans of any LiDAR layout and mount: IoU on every return, as a user's scan is segmented.

For each of ``scans`` random free poses of a world (drawn with ``seed``), each layout casts its rays from a
mount ``height`` m up (``cast_sensor_rays``; 0.01 m range noise, as the simulator's), and the scan's returns
go through ``segment_cloud`` as a file's would: the floor fit measures the height, nothing else is told
(``given_height``: the height is given, as from a sensors file).
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from pimm_agents.measurement.perception_quality import confusion_matrix, segmentation_scores
from pimm_env.sim.sensors import LIDAR_3D, NON_REPETITIVE, scan_directions, scan_layout

#: the layouts measured: presets by name, and "mid-360" for a non-repetitive pattern
LAYOUT_NAMES = ("thesis", "os0-64", "vlp-16", "os1-128", NON_REPETITIVE)


def layout_scan(env: Any, name: str, height: float, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Returns (sensor frame) and true classes of one scan of layout ``name`` from the env's current pose."""
    mount = replace(scan_layout(name), height=height)  # level: its frame is the sensor's
    directions = scan_directions(name, mount, rng)
    ranges, labels = env.cast_sensor_rays(directions, mount)
    hit = np.isfinite(ranges) & (ranges >= mount.min_range)
    ranges = ranges[hit] + rng.normal(0.0, 0.01, int(hit.sum()))
    return directions[hit] * ranges[:, None], labels[hit]


def measure_layouts(
    world: str,
    weights: Path,
    scans: int,
    seed: int,
    heights: tuple[float, ...] = (0.5,),
    layouts: tuple[str, ...] = LAYOUT_NAMES,
    given_height: bool = False,
) -> dict[str, Any]:
    """Per layout and mount height: IoU over all returns, and the measured height's median error."""
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
                errors = []
                for pose_seed in poses:
                    env.reset(seed=pose_seed)
                    points, truth = layout_scan(env, name, height, rng)
                    result = segment_cloud(points, segmenter, height if given_height else None)
                    confusion += confusion_matrix(result.labels, truth)
                    errors.append(abs(result.sensor_height - height))
                scores = segmentation_scores(confusion, scans)
                report[f"{name}@{height:g}m"] = {**scores, "height_error_m": float(np.median(errors))}
    finally:
        env.close()
    return report
