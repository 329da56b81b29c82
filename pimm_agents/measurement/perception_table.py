"""``evaluate.py perception-table``: one network's segmentation on every kind of data, in one table.

- real scans (``scans``): against their plane-fit reference (``plane_reference.py``), with the room corners
  found within 0.2 m;
- simulated worlds (``worlds``: the iiLab, imported furnished buildings, generated held-out buildings):
  ``count`` fresh scans of the thesis's LiDAR at 0.5 m, IoU over every return (``layout_quality.py``), and
  where asked, the objects whose returns were labelled wrong most often;
- every LiDAR layout and two mount heights in one world (``layouts_world``), the height measured from the
  floor and given.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any


def real_scan_scores(path: Path, weights: Path, seed: int = 0) -> dict[str, Any]:
    """One real scan against its plane-fit reference: IoU per class, corners matched within 0.2 m."""
    import numpy as np

    from pimm_agents.measurement.plane_reference import scored_against_reference
    from pimm_agents.perception.segmenter import load_segmenter
    from pimm_agents.scans.segment import segment_cloud
    from pimm_env.clouds.read import read_cloud

    cloud = read_cloud(path)
    result = segment_cloud(cloud.points, load_segmenter(weights), seed=seed)
    found = np.array([[f.x, f.y] for f in result.corners.features]).reshape(-1, 2)
    _, scores = scored_against_reference(cloud.points, result.labels, found, seed)
    return {**scores, "sensor_height_m": result.sensor_height}


def perception_table(
    weights: Path,
    scans: list[Path],
    worlds: list[str],
    layouts_world: str | None,
    count: int,
    seed: int,
    by_object: bool = False,
) -> dict[str, Any]:
    """The table's figures (``by_object``: each world's objects whose returns were labelled wrong most often)."""
    from pimm_agents.measurement.layout_quality import measure_layouts

    table: dict[str, Any] = {"weights": str(weights), "scans_per_world": count, "seed": seed}
    table["real_scans"] = {str(path): real_scan_scores(path, weights, seed) for path in scans}
    table["worlds"] = {
        world: measure_layouts(world, weights, count, seed, layouts=("thesis",), by_object=by_object)["thesis@0.5m"]
        for world in worlds
    }
    if layouts_world is not None:
        table["layouts"] = {
            "world": layouts_world,
            "measured": measure_layouts(layouts_world, weights, count, seed, heights=(0.5, 1.2)),
            "given": measure_layouts(layouts_world, weights, count, seed, heights=(0.5, 1.2), given_height=True),
        }
    return table
