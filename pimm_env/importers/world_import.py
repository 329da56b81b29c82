"""``world import``: a ROS map, a building mesh or a Gazebo SDF world written as ``maps/NAME/world.yaml``.

A mesh is copied beside the world file; an SDF world is flattened (:mod:`pimm_env.importers.sdf_world`) into
one GLB file whose objects keep the models' scoped names. Objects get their classes from name rules (the
defaults below, then a user's ``--rules`` file, whose rules win); objects standing in a wall's line (windows,
closed doors) are classed wall (:mod:`pimm_env.importers.wall_line`), and the import checks what it made
(:mod:`pimm_env.importers.mesh_checks`). A failed import leaves no folder behind.
"""

from __future__ import annotations

import math
import re
import shutil
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from pimm_env.errors import MapFileError, WorldFileError
from pimm_env.importers.floor_plan import CeilingArea, read_ceilings, world_spec, write_world
from pimm_env.importers.furnish import furnish
from pimm_env.importers.vectorize import vectorize
from pimm_env.mapping.map_server import read_ros_map

MESH_SUFFIXES = (".obj", ".ply", ".stl", ".glb", ".gltf", ".off", ".dae")
#: point-cloud maps (a ``.ply`` without faces is one too): pimm_env/importers/cloud_map.py
CLOUD_SUFFIXES = (".pcd", ".las", ".laz", ".npy", ".bin")
SDF_SUFFIXES = (".world", ".sdf")
#: Default name-to-class rules for meshes: whole words, the last matching rule wins, ``*`` when none matches
#: (see "Name rules" in :mod:`pimm_env.world.mesh`). Wall comes last: ``floor_01_walls_1`` is a wall.
#: The last matching rule wins, so the more specific class comes last: ``floor_01_ceiling`` is a ceiling, and
#: ``wall_ceiling`` too (a floor's or a wall's name is where a ceiling piece is often filed).
DEFAULT_MESH_RULES = [
    {"match": "*", "class": "clutter"},
    {"match": "floor", "class": "floor"},
    {"match": "wall", "class": "wall"},
    {"match": "ceiling", "class": "ceiling"},
    {"match": "cealing", "class": "ceiling"},
]


#: A floor plan's ceiling height (m) when none is given.
PLAN_CEILING_HEIGHT = 3.0


#: A world's name: a folder under maps/ of its own (letters, digits, _ . -; not starting with . or -).
WORLD_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.-]{0,99}")


def check_world_name(name: str) -> None:
    """A ``MapFileError`` unless ``name`` makes one folder under maps/ (no path, no ``..``, not empty)."""
    if not WORLD_NAME.fullmatch(name or ""):
        raise MapFileError(
            f"--name {name!r}: a world's name is one folder under maps/: letters, digits, _ . - (not starting "
            "with . or -), at most 100 characters"
        )


def import_world(
    source: Path,
    name: str,
    maps_dir: Path,
    ceiling_height: float | None = None,
    ceilings: Path | None = None,
    furnish_count: int = 0,
    seed: int = 0,
    rules: list[dict[str, str]] | None = None,
    up_axis: str = "z",
    model_paths: Sequence[Path] = (),
    geometry: str = "collision",
    wall_line: bool = True,
    strict: bool = False,
    trajectory: Path | None = None,
) -> Path:
    """Write ``maps_dir/name/world.yaml`` from a map_server ``.yaml``, a mesh or an SDF world; returns its path.

    ``ceiling_height``: a floor plan's ceiling (default 3 m); for a mesh or SDF world, a flat ceiling added that
    high above the floor (none is added when not given). ``rules`` are added after the defaults and win. With
    ``wall_line``, a mesh's objects standing in a wall's line are classed wall (:mod:`wall_line`). ``strict``: a
    Gazebo model or mesh that cannot be found stops the import (else it is left out, said and counted).
    ``trajectory``: a point-cloud map's SLAM trajectory (TUM, the map's frame): clutter where it drove is set aside."""
    source = Path(source)
    check_world_name(name)
    if not source.is_file():
        raise MapFileError(f"{source}: no such file")
    if ceiling_height is not None and not (math.isfinite(ceiling_height) and ceiling_height > 0):
        raise MapFileError(f"--ceiling-height: expected a positive height (m), got {ceiling_height}")
    folder = Path(maps_dir) / name
    existed = folder.exists()
    suffix = source.suffix.lower()
    if trajectory is not None and suffix not in (*CLOUD_SUFFIXES, ".ply"):
        raise MapFileError(f"--trajectory {trajectory}: a trajectory goes with a point-cloud map, not {source}")
    all_rules = DEFAULT_MESH_RULES + list(rules or [])
    try:
        if suffix in (".yaml", ".yml"):
            spec = _from_ros_map(source, name, ceiling_height or PLAN_CEILING_HEIGHT, ceilings, furnish_count, seed)
        elif suffix in CLOUD_SUFFIXES:
            spec = _from_cloud(source, name, folder, all_rules, wall_line, trajectory)
        elif suffix in MESH_SUFFIXES:
            spec = _from_mesh(source, name, folder, all_rules, up_axis, ceiling_height, wall_line, trajectory)
        elif suffix in SDF_SUFFIXES:
            spec = _from_sdf(source, name, folder, all_rules, ceiling_height, model_paths, geometry, wall_line, strict)
        else:
            raise MapFileError(
                f"{source}: expected a map_server .yaml, an SDF world ({', '.join(SDF_SUFFIXES)}), "
                f"a mesh ({', '.join(MESH_SUFFIXES)}) or a point-cloud map ({', '.join(CLOUD_SUFFIXES)}, .ply)"
            )
        return write_world(spec, folder / "world.yaml")
    except BaseException as error:
        if not existed:
            shutil.rmtree(folder, ignore_errors=True)
        if isinstance(error, WorldFileError) and Path(error.path).parent == folder:  # said of the user's file
            said = str(error)[len(f"{error.path}: ") :]
            raise MapFileError(f"{source}: imported as a world, {said}") from None
        raise


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


def _from_mesh(
    source: Path,
    name: str,
    folder: Path,
    rules: list[dict[str, str]],
    up_axis: str,
    ceiling: float | None,
    wall_line: bool,
    trajectory: Path | None = None,
) -> dict[str, Any]:
    from pimm_env.importers.sdf_world import read_mesh_file

    if len(read_mesh_file(source).faces) == 0:  # said of the user's file, before anything is written
        if source.suffix.lower() == ".ply":  # points only: a point-cloud map
            return _from_cloud(source, name, folder, rules, wall_line, trajectory)
        raise MapFileError(f"{source}: the mesh has no faces (a point set?): world import needs surfaces")
    if trajectory is not None:
        raise MapFileError(f"--trajectory {trajectory}: a trajectory goes with a point-cloud map; {source} is a mesh")
    folder.mkdir(parents=True, exist_ok=True)
    target = folder / source.name
    if source.resolve() != target.resolve():
        shutil.copyfile(source, target)
    return _mesh_spec(source.name, name, folder, rules, up_axis, ceiling, source, wall_line)


def _from_cloud(
    source: Path, name: str, folder: Path, rules: list[dict[str, str]], wall_line: bool, trajectory: Path | None = None
) -> dict[str, Any]:
    import numpy as np

    from pimm_env.clouds.read import read_cloud
    from pimm_env.importers.cloud_map import CloudMapConfig, classify, floor_areas, write_cloud_world_mesh
    from pimm_env.importers.cloud_path import read_path
    from pimm_env.importers.cloud_walls import wall_elements

    config = CloudMapConfig()
    cloud = read_cloud(source)
    path = None if trajectory is None else read_path(trajectory) - cloud.offset  # the cloud's frame, as read
    cloud_map = classify(cloud.points, config, source, path, trajectory or "")  # refused before anything is written
    areas = floor_areas(cloud_map, config, source)
    folder.mkdir(parents=True, exist_ok=True)
    mesh = write_cloud_world_mesh(cloud_map, folder / f"{source.stem}.glb")
    walls = wall_elements(cloud_map.walls)
    spec = _mesh_spec(mesh.name, name, folder, rules, "z", None, source, wall_line, walls)
    spec["areas"] = areas
    np.save(folder / "seen_walls.npy", np.round(cloud_map.seen_walls, 3))
    spec["seen_walls"] = "seen_walls.npy"
    spec["cloud_map"] = {
        "points": cloud_map.points,
        "voxel_m": config.voxel_m,
        "voxels": cloud_map.counts(),
        "set_aside": cloud_map.set_aside,
        "tilt_deg": round(cloud_map.tilt_deg, 3),
        "floor_z": round(cloud_map.floor_z, 3),
        "offset": [float(v) for v in cloud.offset],
    }
    if path is not None:
        spec["cloud_map"]["trajectory"] = {"file": str(trajectory), "poses": len(path)}
    return spec


def _from_sdf(
    source: Path,
    name: str,
    folder: Path,
    rules: list[dict[str, str]],
    ceiling: float | None,
    model_paths: Sequence[Path],
    geometry: str,
    wall_line: bool,
    strict: bool = False,
) -> dict[str, Any]:
    import trimesh

    from pimm_env.importers.sdf_world import read_sdf_world

    meshes = read_sdf_world(source, model_paths, geometry, strict)
    scene = trimesh.Scene()
    for key, mesh in meshes.items():
        scene.add_geometry(mesh, node_name=key, geom_name=key)
    folder.mkdir(parents=True, exist_ok=True)
    scene.export(folder / f"{source.stem}.glb")
    return _mesh_spec(f"{source.stem}.glb", name, folder, rules, "z", ceiling, source, wall_line)


def _mesh_spec(
    mesh: str,
    name: str,
    folder: Path,
    rules: list[dict[str, str]],
    up_axis: str,
    ceiling: float | None,
    source: Path,
    wall_line: bool,
    elements: list[dict[str, Any]] | None = None,
) -> dict[str, Any]:
    from pimm_env.importers.mesh_checks import check_mesh_world, floor_height
    from pimm_env.importers.wall_line import wall_line_objects
    from pimm_env.world.mesh import world_from_mesh_spec

    spec: dict[str, Any] = {
        "format": "pimm-mesh-world/1",
        "name": name,
        "mesh": mesh,
        "up_axis": up_axis,
        "rules": rules,
        "occupancy": ["wall", "clutter"],
    }
    if elements:
        spec["elements"] = elements
    world = world_from_mesh_spec(spec, folder / "world.yaml")  # refuses a mesh with no floor, naming the file
    spec["floor_z"] = round(floor_height(world), 4)
    left_out = check_mesh_world(world, spec["floor_z"], source, ceiling is not None)
    if left_out:
        spec["left_out"] = left_out
    in_line = wall_line_objects(e for e in world.elements if e.name not in left_out) if wall_line else []
    if in_line:
        spec["wall_line"] = in_line
    if ceiling is not None:
        spec["ceiling_height"] = ceiling
    return spec


def read_rules(path: Path) -> list[dict[str, str]]:
    """A rules file: a YAML list of ``{match: PATTERN_OR_WORD, class: CLASS}`` (or ``{rules: [...]}``)."""
    import yaml

    from pimm_env.world.semantics import parse_class

    try:
        data = yaml.safe_load(Path(path).read_text())
    except (OSError, yaml.YAMLError) as error:
        raise MapFileError(f"{path}: cannot read the rules file: {error}") from None
    if isinstance(data, dict):
        data = data.get("rules")
    if not isinstance(data, list) or not data:
        raise MapFileError(f"{path}: expected a list of {{match: PATTERN, class: CLASS}}, got {data!r}")
    rules = []
    for i, rule in enumerate(data):
        if not isinstance(rule, dict) or not isinstance(rule.get("match"), str) or "class" not in rule:
            raise MapFileError(f"{path}: rules[{i}]: expected {{match: PATTERN, class: CLASS}}, got {rule!r}")
        try:
            parse_class(str(rule["class"]))
        except ValueError as error:
            raise MapFileError(f"{path}: rules[{i}].class: {error}") from None
        rules.append({"match": rule["match"], "class": str(rule["class"])})
    return rules
