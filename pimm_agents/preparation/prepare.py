"""Preparing a world for localization: derived maps, the table of the map's twins, the fingerprint map made with
the world's weights (the shipped ones unless it has its own), and generated routes in ``scenarios.yaml`` when it
has none."""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

from pimm_env.driving.routes import RouteConfig
from pimm_env.mapping.occupancy import OccupancyGrid
from pimm_env.world.model import World
from pimm_env.world.semantics import SemanticClass


@dataclass
class Preparation:
    world: str
    folder: Path
    corners: int
    free_m2: float
    fingerprints: int
    scenarios: list[str]
    routes_written: bool
    seconds: dict[str, float] = field(default_factory=dict)
    has_ceiling: bool = True  # whether any element of the world is a ceiling


def prepare_world(
    world: str | Path | World,
    routes: RouteConfig | None = None,
    seed: int = 0,
    spacing: float = 0.5,
    new_routes: bool = False,
    progress: bool = True,
) -> Preparation:
    """Rebuild everything a world needs to be localized in (see the module docstring)."""
    from pimm_agents.perception.files import checkpoint_path, fingerprint_path
    from pimm_agents.perception.segmenter import load_segmenter
    from pimm_agents.preparation.fingerprints import build_fingerprint_map
    from pimm_env.driving.routes import plan_routes, scenarios_document
    from pimm_env.driving.scenarios import load_scenarios, scenarios_path
    from pimm_env.mapping.derived_maps import build_derived_maps, load_derived_maps
    from pimm_env.mapping.twins import TWINS_FILE, MapTwins, TwinConfig
    from pimm_env.world.files import load_world, world_dir

    loaded = world if isinstance(world, World) else load_world(world)
    routes = routes or RouteConfig()
    seconds: dict[str, float] = {}
    start = time.perf_counter()
    maps = build_derived_maps(loaded)
    seconds["maps"] = time.perf_counter() - start
    start = time.perf_counter()
    # PIMM's ambiguity check's, worked out once per cell, on the map as the localizers read it back (a grid whose
    # origin is not a round number comes back from occupancy.yaml a few ulps away, and the table would not be taken)
    twins = MapTwins(load_derived_maps(loaded).occupancy, TwinConfig())
    twins.precompute(progress)
    twins.save(world_dir(loaded) / TWINS_FILE)
    seconds["twins"] = time.perf_counter() - start
    start = time.perf_counter()
    written = new_routes or not scenarios_path(loaded).is_file()
    if written:
        planned = plan_routes(drivable(loaded, maps.occupancy), routes, seed)
        scenarios_path(loaded).write_text(scenarios_document(loaded.name, planned, routes, seed))
    seconds["routes"] = time.perf_counter() - start
    start = time.perf_counter()
    weights = checkpoint_path(loaded)
    segmenter = load_segmenter(weights)  # the simulated thesis LiDAR: 0.5 m up
    fmap = build_fingerprint_map(loaded, segmenter, spacing, seed, progress=progress)
    provenance = {"spacing_m": str(spacing), "seed": str(seed), "weights": str(weights)}
    fmap.save(fingerprint_path(loaded), segmenter.weights_sha256, provenance)
    seconds["fingerprints"] = time.perf_counter() - start
    occupancy = maps.occupancy
    return Preparation(
        world=loaded.name,
        folder=world_dir(loaded),
        corners=len(maps.corners),
        free_m2=float(occupancy.free.sum() * occupancy.grid.resolution**2),
        fingerprints=len(fmap),
        scenarios=list(load_scenarios(loaded)),
        routes_written=written,
        seconds=seconds,
        has_ceiling=any(e.semantic == SemanticClass.CEILING for e in loaded.elements),
    )


def drivable(world: World, occupancy: OccupancyGrid) -> OccupancyGrid:
    """``occupancy`` with everything the robot's body can touch made occupied: routes are planned on it, so that
    they keep their clearance from furniture lower than the map's cut (a chair seat, a low table)."""
    from pimm_env.mapping.occupancy import body_obstacles

    body = body_obstacles(world, occupancy.grid)
    return OccupancyGrid(occupancy.grid, occupancy.occupied | body, occupancy.free & ~body)


#: fewer corners than this per 100 m^2 of free space and the corner cue says little (the iiLab has 32 over
#: 422 m^2 of free space: 7.6; the generated held-out buildings 8-42; the AWS small house with a 3 m ceiling 4.4)
MIN_CORNERS_PER_100_M2 = 2.0


def describe(done: Preparation) -> str:
    """What ``evaluate.py world prepare`` prints: the world's maps, its scenarios and where the time went."""
    steps = ", ".join(f"{k} {v:.1f} s" for k, v in done.seconds.items())
    per_100 = 100.0 * done.corners / max(done.free_m2, 1e-9)
    warning = ""
    if per_100 < MIN_CORNERS_PER_100_M2:
        why = (
            "the ceiling meets few of its walls (a ceiling only over some rooms, or walls that stop short of it)"
            if done.has_ceiling
            else "the world has no ceiling: give --ceiling-height on import"
        )
        warning = (
            f"warning: {done.corners} corners over {done.free_m2:.0f} m^2 ({per_100:.1f} per 100 m^2, fewer than "
            f"{MIN_CORNERS_PER_100_M2:g}): PIMM leans on its other cues here; {why}\n"
        )
    return warning + (
        f"{done.world}: {done.free_m2:.0f} m^2 free, {done.corners} corners, {done.fingerprints} fingerprints, "
        f"scenarios {', '.join(done.scenarios)}{' (generated)' if done.routes_written else ''}; "
        f"prepared in {sum(done.seconds.values()):.1f} s ({steps}) -> {done.folder}\n"
        f"next: python evaluate.py run --world {done.folder / 'world.yaml'}"
    )
