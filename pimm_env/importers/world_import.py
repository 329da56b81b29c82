"""``world import``: a ROS map or a building mesh written as ``maps/NAME/world.yaml`` (and what it needs)."""

from __future__ import annotations

import shutil
from pathlib import Path
from typing import Any

from pimm_env.errors import MapFileError
from pimm_env.importers.floor_plan import CeilingArea, read_ceilings, world_spec, write_world
from pimm_env.importers.furnish import furnish
from pimm_env.importers.vectorize import vectorize
from pimm_env.mapping.map_server import read_ros_map

MESH_SUFFIXES = (".obj", ".ply", ".stl", ".glb", ".gltf", ".off", ".dae")
#: Default name-to-class rules for meshes, first match wins (fnmatch, case-sensitive: both spellings listed).
DEFAULT_MESH_RULES = [
    {"match": pattern, "class": semantic}
    for semantic, words in (
        ("ceiling", ("ceil", "Ceil", "CEIL", "Cealing")),
        ("floor", ("floor", "Floor", "FLOOR")),
        ("wall", ("wall", "Wall", "WALL")),
    )
    for pattern in (f"*{word}*" for word in words)
] + [{"match": "*", "class": "clutter"}]


def import_world(
    source: Path,
    name: str,
    maps_dir: Path,
    ceiling_height: float = 3.0,
    ceilings: Path | None = None,
    furnish_count: int = 0,
    seed: int = 0,
    rules: list[dict[str, str]] | None = None,
    up_axis: str = "z",
) -> Path:
    """Write ``maps_dir/name/world.yaml`` from a map_server ``.yaml`` or a mesh file; returns its path."""
    source = Path(source)
    if not source.is_file():
        raise MapFileError(f"{source}: no such file")
    if ceiling_height <= 0:
        raise MapFileError(f"--ceiling-height: expected a positive height (m), got {ceiling_height}")
    folder = Path(maps_dir) / name
    if source.suffix.lower() in (".yaml", ".yml"):
        spec = _from_ros_map(source, name, ceiling_height, ceilings, furnish_count, seed)
    elif source.suffix.lower() in MESH_SUFFIXES:
        spec = _from_mesh(source, name, folder, rules or DEFAULT_MESH_RULES, up_axis)
    else:
        raise MapFileError(f"{source}: expected a map_server .yaml or a mesh ({', '.join(MESH_SUFFIXES)})")
    return write_world(spec, folder / "world.yaml")


def _from_ros_map(
    source: Path, name: str, ceiling: float, ceilings: Path | None, furnish_count: int, seed: int
) -> dict[str, Any]:
    plan = vectorize(read_ros_map(source))
    areas: list[CeilingArea] = []
    if ceilings is not None:
        ceiling, areas = read_ceilings(ceilings, ceiling)
    spec = world_spec(name, plan, ceiling, areas)
    if furnish_count > 0:
        spec["elements"] += furnish(plan, furnish_count, seed, ceiling)
    return spec


def _from_mesh(source: Path, name: str, folder: Path, rules: list[dict[str, str]], up_axis: str) -> dict[str, Any]:
    from pimm_env.world.mesh import world_from_mesh_spec

    folder.mkdir(parents=True, exist_ok=True)
    target = folder / source.name
    if source.resolve() != target.resolve():
        shutil.copyfile(source, target)
    spec: dict[str, Any] = {
        "format": "pimm-mesh-world/1",
        "name": name,
        "mesh": source.name,
        "up_axis": up_axis,
        "rules": rules,
        "occupancy": ["wall", "clutter"],
    }
    world = world_from_mesh_spec(spec, folder / "world.yaml")  # refuses a mesh with no floor, naming the file
    spec["floor_z"] = round(_floor_top(world), 4)
    return spec


def _floor_top(world: Any) -> float:
    """The walkable height: the top of the floor geometry."""
    from pimm_env.world.semantics import SemanticClass

    return max(e.shape.z_range[1] for e in world.elements if e.semantic == SemanticClass.FLOOR)
