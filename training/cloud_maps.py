"""Point-cloud maps of generated buildings made the way SLAM makes them, imported back with ``world import``, and
scored against the building's own maps; then PIMM localizing in the building with the maps the import derived.

The maps and the trajectories they come with are made in slam_maps.py. The figures
(:func:`score_import`):

- what the map saw: rays of the LiDAR's range cast from the mapping poses across the building's walls at
  ``WALL_HEIGHT`` (above its furniture, below its ceilings); the wall cells they first hit were seen;
- corners: the building's own corner map against the imported one, matched within ``MATCH_M`` in the plane:
  the share found of the building's corners the map saw (in sight of a mapping pose, and both faces: seen wall
  cells near it in two directions) and of all; and
  the share of imported corners that are none of the building's: no two of the building's walls meet under a
  ceiling within ``MATCH_M``, the length of their faces judged with the same slack (the corner map asks 0.3 m of
  each face, so that a doorway's jamb is no corner; a 0.25 m stub beside a door is walls meeting all the same);
- walls: both worlds cut at ``WALL_HEIGHT`` (people walking through and most furniture are lower), each within
  two cells of a seen wall cell (the face the map saw and the wall's body behind it): IoU cell for cell and within
  one cell (5 cm, the grids' own step);
- the import's time per 1 000 m² of the floor it found.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np

#: a corner of the import within this of one of the building's (in the plane) is that corner (m)
MATCH_M = 0.1
#: the height the walls are compared and seen at (m): above desks, cabinets and people, below any ceiling
WALL_HEIGHT = 2.0
#: mapping poses this far apart cast the rays that tell what the map saw (m)
POSE_SPACING_M = 0.5


def corner_figures(truth: Any, found: Any, seen: np.ndarray, there: Any = None) -> dict[str, float]:
    """Corner maps ``truth`` (the building's) and ``found`` (the import's) matched within ``MATCH_M``; ``seen``
    marks the building's corners in the part the map saw; a found corner is none of the building's where it lies
    farther than ``MATCH_M`` from every corner of ``there`` (the building's corners with their faces' slack;
    None: ``truth``)."""
    from scipy.spatial import cKDTree

    there = truth if there is None else there
    if not len(truth) or not len(found):
        nothing = {"recall_seen": 0.0, "recall_all": 0.0, "false": 1.0 if len(found) else 0.0}
        return {"corners": len(truth), "seen": int(seen.sum()), "found": len(found), **nothing}
    to_found, _ = cKDTree(found.xy).query(truth.xy)
    to_truth, _ = cKDTree(there.xy).query(found.xy)
    hit = to_found <= MATCH_M
    return {
        "corners": len(truth),
        "seen": int(seen.sum()),
        "found": len(found),
        "recall_seen": float(hit[seen].mean()) if seen.any() else 0.0,
        "recall_all": float(hit.mean()),
        "false": float(np.mean(to_truth > MATCH_M)),
    }


def seen_cells(occupied: np.ndarray, grid: Any, poses: np.ndarray, reach_m: float, beams: int = 720) -> np.ndarray:
    """The occupied cells that rays from ``poses`` (every ``POSE_SPACING_M`` of them) first hit within
    ``reach_m``: the walls a LiDAR driven there saw."""
    from pimm_agents.active.views import cast_ranges

    origins = _spaced(poses)
    bearings = np.linspace(-np.pi, np.pi, beams, endpoint=False)
    x0, y0 = grid.origin
    ranges = cast_ranges(origins, np.zeros(len(origins)), bearings, occupied, x0, y0, grid.resolution, reach_m)
    hit = ranges < reach_m
    # where each ray stopped, a hair short (the march adds its steps up; this multiplies them, a few ulps apart)
    reach = np.maximum(ranges - 1e-6, 0.0)
    ends = origins[:, None, :] + reach[:, :, None] * np.stack([np.cos(bearings), np.sin(bearings)], axis=1)[None]
    rows, cols, valid = grid.cells_of(ends[hit])
    seen = np.zeros(occupied.shape, dtype=bool)
    seen[rows[valid], cols[valid]] = occupied[rows[valid], cols[valid]]
    return seen


def faces_seen(corners: np.ndarray, seen: np.ndarray, grid: Any, reach_m: float = 0.2) -> np.ndarray:
    """Which ``corners`` (K, 2) the map saw: seen wall cells within ``reach_m`` of each lie in two directions at
    least 60 degrees apart from it (both its faces, not one face running past it)."""
    from scipy.spatial import cKDTree

    gx, gy = grid.cell_centers()
    cells = np.column_stack([gx[seen], gy[seen]])
    out = np.zeros(len(corners), dtype=bool)
    if not len(cells):
        return out
    tree = cKDTree(cells)
    for k, corner in enumerate(np.asarray(corners, dtype=float)):
        near = cells[tree.query_ball_point(corner, reach_m)] - corner
        near = near[np.hypot(near[:, 0], near[:, 1]) > grid.resolution]
        if len(near) < 2:
            continue
        angle = np.arctan2(near[:, 1], near[:, 0])
        apart = np.abs((angle[:, None] - angle[None, :] + np.pi) % (2 * np.pi) - np.pi)
        out[k] = bool(apart.max() >= np.radians(60.0))
    return out


def in_sight(corners: np.ndarray, occupied: np.ndarray, grid: Any, poses: np.ndarray, reach_m: float) -> np.ndarray:
    """Which ``corners`` (K, 2) a ray from one of ``poses`` (every ``POSE_SPACING_M``) reaches within ``reach_m``
    unblocked by ``occupied``: at a point 7 cm off the corner on each diagonal that is free (the room's side),
    not only the wall cells beside it (the far side of a thin wall lies as near)."""
    from pimm_agents.active.views import cast_ranges

    origins = _spaced(poses)
    x0, y0 = grid.origin
    out = np.zeros(len(corners), dtype=bool)
    for k, corner in enumerate(np.asarray(corners, dtype=float)):
        for dx, dy in ((1, 1), (1, -1), (-1, 1), (-1, -1)):
            probe = corner + 0.07 * np.array([dx, dy])
            rows, cols, valid = grid.cells_of(probe[None])
            if not valid[0] or occupied[rows[0], cols[0]]:
                continue
            gap = probe - origins
            far = np.hypot(gap[:, 0], gap[:, 1])
            near = far < reach_m
            if not near.any():
                continue
            heading = np.arctan2(gap[near, 1], gap[near, 0])
            ranges = cast_ranges(origins[near], heading, np.zeros(1), occupied, x0, y0, grid.resolution, reach_m)
            if np.any(ranges[:, 0] >= far[near] - grid.resolution):
                out[k] = True
                break
    return out


def _spaced(poses: np.ndarray) -> np.ndarray:
    """The (x, y) of ``poses`` at least ``POSE_SPACING_M`` apart, in order."""
    keep = [0]
    for k in range(1, len(poses)):
        if np.hypot(*(poses[k, :2] - poses[keep[-1], :2])) >= POSE_SPACING_M:
            keep.append(k)
    return np.ascontiguousarray(poses[keep, :2], dtype=float)


def score_import(building: Path, imported: Path, poses: np.ndarray, reach_m: float = 10.0) -> dict[str, Any]:
    """The imported world ``imported`` (its derived maps built) against the building ``building`` (world files)
    that was mapped from ``poses`` with a LiDAR of ``reach_m``."""
    from scipy import ndimage

    from pimm_env.mapping.corner_map import CornerMapConfig, derive_corner_map
    from pimm_env.mapping.derived_maps import load_derived_maps
    from pimm_env.mapping.occupancy import occupancy_from_world, resample_occupied, tolerant_iou
    from pimm_env.world.files import load_world

    own_world, made_world = load_world(building), load_world(imported)
    own, made = load_derived_maps(own_world), load_derived_maps(made_world)
    walls = occupancy_from_world(own_world, own.occupancy.grid.resolution, WALL_HEIGHT)
    grid = walls.grid
    seen = seen_cells(walls.occupied, grid, poses, reach_m)
    made_walls = resample_occupied(occupancy_from_world(made_world, grid.resolution, WALL_HEIGHT), grid)
    near_seen = ndimage.binary_dilation(seen, iterations=2)  # the import's cells are judged where the map saw
    corner_seen = faces_seen(own.corners.xy, seen, grid) & in_sight(
        own.corners.xy, walls.occupied, grid, poses, reach_m
    )
    there = derive_corner_map(own_world, CornerMapConfig(min_face=CornerMapConfig().min_face - MATCH_M))
    return {
        **corner_figures(own.corners, made.corners, corner_seen, there),
        "wall_iou": tolerant_iou(walls.occupied & near_seen, made_walls & near_seen, 0),
        "wall_iou_5cm": tolerant_iou(walls.occupied & near_seen, made_walls & near_seen, 1),
        "floor_m2": float(made.occupancy.free.sum() * made.occupancy.grid.resolution**2),
    }


def cloud_map_figure(points: np.ndarray, building: Path, imported: Path, path: Path) -> Path:
    """The SLAM-like map (seen from above, coloured by height) beside what the import made of it: its walls cut at
    ``WALL_HEIGHT`` over the building's own (grey), the building's corners and the imported corner map's."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from shapely.geometry import Polygon

    from pimm_env.mapping.corner_map import _rings, _section
    from pimm_env.mapping.derived_maps import load_derived_maps
    from pimm_env.mapping.occupancy import occupancy_from_world
    from pimm_env.world.files import load_world
    from pimm_env.world.semantics import SemanticClass

    own_world, made_world = load_world(building), load_world(imported)
    own, made = load_derived_maps(own_world), load_derived_maps(made_world)
    walls = occupancy_from_world(own_world, 0.05, WALL_HEIGHT)
    x0, y0 = walls.grid.origin
    rows, cols = walls.occupied.shape
    extent = (x0, x0 + cols * 0.05, y0, y0 + rows * 0.05)
    fig, (left, right) = plt.subplots(1, 2, figsize=(14, 6), sharex=True, sharey=True)
    shown = points[(points[:, 2] > 0.2) & (points[:, 2] < 3.0)]
    shown = shown[np.random.default_rng(0).permutation(len(shown))[:60_000]]
    left.scatter(shown[:, 0], shown[:, 1], c=shown[:, 2], s=0.3, cmap="viridis")
    left.set_title(f"the point-cloud map ({building.parent.name}, coloured by height, people's ghosts included)")
    right.imshow(walls.occupied, origin="lower", extent=extent, cmap="Greys", vmax=2.5, interpolation="nearest")
    for k, ring in enumerate(_rings(_section(made_world, SemanticClass.WALL, WALL_HEIGHT))):
        right.fill(*np.asarray(Polygon(ring).exterior.coords).T, fc="none", ec="tab:red", lw=1,
                   label="imported walls" if k == 0 else None)  # fmt: skip
    right.scatter(*own.corners.xy.T, s=60, facecolors="none", edgecolors="tab:green", label="the building's corners")
    right.scatter(*made.corners.xy.T, s=30, c="tab:blue", marker="x", label="corners of the imported map")
    right.set_title("imported: walls and corners over the building's own walls (grey)")
    right.legend(loc="upper right", fontsize=8)
    for axis in (left, right):
        axis.set_aspect("equal")
        axis.set_xlabel("x (m)")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def import_cloud(cloud_file: Path, name: str, worlds: Path, trajectory: Path | None = None) -> tuple[Path, float]:
    """``world import`` of ``cloud_file`` (with its SLAM ``trajectory``, a TUM file) as ``worlds/name`` (replacing
    one there), prepared; the import's own seconds (without the preparation's fingerprints and routes)."""
    import shutil

    from pimm_agents.preparation.prepare import prepare_world
    from pimm_env.importers.world_import import import_world

    shutil.rmtree(worlds / name, ignore_errors=True)
    start = time.perf_counter()
    path = import_world(cloud_file, name, worlds, trajectory=trajectory)
    seconds = time.perf_counter() - start
    prepare_world(path, progress=False)
    return path, seconds


def localize_with(building: Path, maps: Path | None, trials: int, workers: int, out: Path) -> dict[str, Any]:
    """PIMM on the building's routes (its kidnap route aside: the map was made on the others), with the maps of
    ``maps`` (a world) or the building's own: convergence rate, median time to a right ``localized`` and the
    seconds ``localized`` while wrong, over all trials, and each trial's time to a right ``localized`` (of those
    that got there) for :func:`pooled_times`."""
    from pimm_agents.experiments.experiment import Execution, Experiment
    from pimm_agents.experiments.run_plan import RunPlan, resolve_localizers
    from pimm_agents.scoring.honesty import honesty_metrics
    from pimm_env.driving.scenarios import load_scenarios
    from pimm_env.world.files import load_world

    routes = tuple(n for n, s in load_scenarios(load_world(building)).items() if s.kidnap_to is None)
    plan = RunPlan(str(building), resolve_localizers(["pimm"]), routes, trials, maps=str(maps) if maps else "")
    outcome = Experiment.of_plan(plan, Execution(workers, progress=False)).run(out, resume=True)
    rows = [by["pimm"] for by in outcome.summary["scenarios"].values()]
    times = [r["time_to_localized_s"] for r in rows if r.get("time_to_localized_s") is not None]
    each = [honesty_metrics(t.log.after_kidnap(), None).time_to_localized_s for t in outcome.results]
    return {
        "times_s": [t for t in each if t is not None],
        "convergence_rate": float(
            np.average([r["convergence_rate"] for r in rows], weights=[r["trials"] for r in rows])
        ),
        "time_to_localized_s": float(np.median(times)) if times else None,
        "false_localized_s": float(sum(r.get("false_localized_s") or 0.0 for r in rows)),
    }


def measure_cloud_map(
    seed: int, worlds: Path, out: Path, trials: int, workers: int, trajectory: bool = True
) -> dict[str, Any]:
    """One generated building: its SLAM-like map and trajectory written (``out/gen-SEED.pcd``, ``.tum``),
    imported (with the trajectory, unless not ``trajectory``) as ``gen-SEED-cloud`` under ``worlds``, scored (a
    figure, ``out/gen-SEED.png``), and (``trials`` > 0) PIMM localizing in the building with those maps and its
    own."""
    from pimm_agents.results.tum import write_tum
    from pimm_env.clouds.pcd import write_pcd
    from pimm_env.world.files import load_world
    from training.heldout import ready_building
    from training.slam_maps import slam_like_cloud

    building = ready_building(seed, worlds)
    out.mkdir(parents=True, exist_ok=True)
    slam = slam_like_cloud(load_world(building), seed)
    cloud_file = write_pcd(out / f"gen-{seed}.pcd", slam.points)
    path = write_tum(out / f"gen-{seed}.tum", slam.times, slam.poses)
    imported, seconds = import_cloud(cloud_file, f"gen-{seed}-cloud", worlds, path if trajectory else None)
    figures = score_import(building, imported, slam.true_poses)
    cloud_map_figure(slam.points, building, imported, out / f"gen-{seed}.png")
    figures.update(
        points=len(slam.points), import_s=seconds, import_s_per_1000m2=1000.0 * seconds / figures["floor_m2"]
    )
    if trials:
        figures["own_maps"] = localize_with(building, None, trials, workers, out / f"gen-{seed}" / "own")
        figures["cloud_maps"] = localize_with(building, imported, trials, workers, out / f"gen-{seed}" / "cloud")
    return figures


def cloud_map_table(rows: dict[str, dict[str, Any]]) -> str:
    """The figures of :func:`measure_cloud_map`, a row per building."""

    def pct(value: float | None) -> str:
        return "-" if value is None else f"{100 * value:.0f} %"

    def sec(value: float | None) -> str:
        return "-" if value is None else f"{value:.1f}"

    head = ("| building | points | floor m² | corners (seen) | found of seen | found of all | not the building's "
            "| wall IoU | within 5 cm | import s / 1 000 m² | PIMM conv. own / cloud | time to localized s own / "
            "cloud | localized while wrong s own / cloud |")  # fmt: skip
    lines = [head, "|---|" + "---:|" * 12]
    for name, r in rows.items():
        own, cloud = r.get("own_maps", {}), r.get("cloud_maps", {})
        lines.append(
            f"| {name} | {r['points']} | {r['floor_m2']:.0f} | {r['corners']} ({r['seen']}) "
            f"| {pct(r['recall_seen'])} "
            f"| {pct(r['recall_all'])} | {pct(r['false'])} | {r['wall_iou']:.2f} | {r['wall_iou_5cm']:.2f} "
            f"| {r['import_s_per_1000m2']:.0f} "
            f"| {pct(own.get('convergence_rate'))} / {pct(cloud.get('convergence_rate'))} "
            f"| {sec(own.get('time_to_localized_s'))} / {sec(cloud.get('time_to_localized_s'))} "
            f"| {sec(own.get('false_localized_s'))} / {sec(cloud.get('false_localized_s'))} |"
        )
    return "\n".join(lines)


#: resamples of the bootstrap interval of the pooled time ratio (seeded: the same trials give the same interval)
RESAMPLES = 2000


def pooled_times(rows: dict[str, dict[str, Any]], seed: int = 0) -> str:
    """One line under the table: every building's trials pooled, the median time to a right ``localized`` with
    the building's own maps and with the imported ones, their ratio and its 90 % bootstrap interval (each set of
    trials resampled with replacement; trials that never got there are in neither, as in the table's medians).
    A building's median over twelve trials swings by half either way from one set of trials to the next; the
    pooled ratio says whether the imported maps are slower at all. Empty when no building has trials with both."""
    own = [t for r in rows.values() for t in r.get("own_maps", {}).get("times_s", [])]
    cloud = [t for r in rows.values() for t in r.get("cloud_maps", {}).get("times_s", [])]
    if not own or not cloud:
        return ""
    a, b = np.asarray(own), np.asarray(cloud)
    rng = np.random.default_rng(seed)
    ratios = [np.median(rng.choice(b, len(b))) / np.median(rng.choice(a, len(a))) for _ in range(RESAMPLES)]
    low, high = np.percentile(ratios, [5, 95])
    own_s, cloud_s = float(np.median(a)), float(np.median(b))
    return (
        f"All buildings' trials pooled: median time to a right `localized` {own_s:.1f} s with their own "
        f"maps ({len(a)} trials), {cloud_s:.1f} s with the imported ones ({len(b)}): "
        f"{cloud_s / own_s:.2f} times as long (90 % bootstrap interval {low:.2f}-{high:.2f})."
    )


def run_cloud_maps(
    seeds: list[int], trials: int, workers: int, worlds: Path, out: Path, made: str, echo: Any, trajectory: bool = True
) -> None:
    """:func:`measure_cloud_map` for each building, writing ``out/cloud_maps.json`` and ``out/cloud_maps.md``
    (headed by the command ``made``, the commit and the machine) after each."""
    import json

    from tqdm import tqdm

    from pimm_agents.results.markdown import provenance_here

    out.mkdir(parents=True, exist_ok=True)
    rows: dict[str, dict[str, Any]] = {}
    report = f"{cloud_map_table(rows)}\n\n"
    for seed in tqdm(seeds, desc="buildings", unit="building"):
        rows[f"gen-{seed}"] = measure_cloud_map(seed, worlds, out, trials, workers, trajectory)
        report = f"{cloud_map_table(rows)}\n\n{pooled_times(rows)}"  # the table and its pooled line, once
        (out / "cloud_maps.json").write_text(json.dumps(rows, indent=1))
        (out / "cloud_maps.md").write_text(f"{provenance_here(made)}\n\n{report}\n")
    echo(report)
