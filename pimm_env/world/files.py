"""The world model: named solid elements with a semantic class, plus named area polygons.

A world is read from a declarative YAML file (``maps/<name>/world.yaml``, format below) or from a
triangle mesh (see :mod:`pimm_env.world.mesh`). Everything downstream (the pybullet scene, the
occupancy grid, the corner map) is derived from this one object.

World file, version 1::

    format: pimm-world/1
    name: my-room
    floor_z: 0.0                 # height of the walkable floor surface (m)
    areas:                       # named polygons of walkable space, [x, y] vertices
      room: [[0, 0], [6, 0], [6, 4], [0, 4]]
    elements:
      - name: west_wall
        class: wall              # wall | ceiling | floor | clutter
        occupancy: true          # drawn into the occupancy map? default: true for wall/clutter
        box: {min: [-0.2, 0, 0], max: [0, 4, 3]}             # axis-aligned box, or
      - {name: post, class: clutter, cylinder: {center: [3, 2], radius: 0.2, z: [0, 3]}}
      - {name: crate, class: clutter, box: {center: [1, 1, 0.5], size: [1, 0.5, 1], yaw: 0.3}}
      - name: north_wall         # a wall along a polyline: one box per segment
        class: wall
        wall: {path: [[0, 4], [6, 4]], thickness: 0.2, z: [0, 3]}
      - name: walls              # a vertical prism over a polygon with holes (what map import writes)
        class: wall
        prism: {outline: [[-1, -1], [7, -1], [7, 5], [-1, 5]], holes: [[[0, 0], [6, 0], [6, 4], [0, 4]]], z: [0, 3]}

An element takes exactly one shape key and only the keys name, class and occupancy besides.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from pimm_env.errors import MissingFileError, WorldFileError
from pimm_env.world.model import World
from pimm_env.world.reader import FieldReader
from pimm_env.yaml_file import yaml_problem

FORMAT = "pimm-world/1"
MAPS_DIR = Path(__file__).resolve().parents[2] / "maps"


def resolve_world_path(world: str | Path) -> Path:
    """Map a world name (``iilab``) or a path to the world file it denotes."""
    candidate = Path(world)
    if candidate.suffix in {".yaml", ".yml"} or candidate.is_file():
        return candidate
    if candidate.is_dir():
        return candidate / "world.yaml"
    named = MAPS_DIR / str(world) / "world.yaml"
    if named.is_file():
        return named
    known = sorted(p.parent.name for p in MAPS_DIR.glob("*/world.yaml"))
    raise MissingFileError(f"unknown world {str(world)!r}: no file {named}; known worlds: {', '.join(known)}")


def world_dir(world: World) -> Path:
    """The folder of a world's files: its world file's folder, or ``maps/<name>`` for a world built in code."""
    if world.source is not None:
        return Path(world.source).resolve().parent
    return MAPS_DIR / world.name


def load_world(world: str | Path) -> World:
    """Load a world by name or path; dispatches to the mesh loader for ``format: pimm-mesh-world/1``."""
    import yaml

    path = resolve_world_path(world)
    try:
        data = yaml.safe_load(path.read_text())
    except yaml.YAMLError as exc:
        raise WorldFileError(path, "(file)", f"not valid YAML: {yaml_problem(exc)}") from None
    if not isinstance(data, Mapping):
        raise WorldFileError(path, "(file)", f"expected a mapping at the top level, got {type(data).__name__}")
    fmt = data.get("format")
    if fmt == "pimm-mesh-world/1":
        from pimm_env.world.mesh import world_from_mesh_spec

        return world_from_mesh_spec(data, path)
    if fmt != FORMAT:
        raise WorldFileError(path, "format", f"expected {FORMAT!r} or 'pimm-mesh-world/1', got {fmt!r}")
    return world_from_spec(data, path)


def world_from_spec(data: Mapping[str, Any], path: Path | str = "<dict>") -> World:
    """Build a :class:`World` from the parsed contents of a world file, validating every field."""
    reader = FieldReader(path)
    name = reader.string(data, "name")
    floor_z = reader.number(data.get("floor_z", 0.0), "floor_z")
    areas_raw = data.get("areas")
    if not isinstance(areas_raw, Mapping) or not areas_raw:
        raise WorldFileError(path, "areas", f"expected a non-empty mapping of name -> polygon, got {areas_raw!r}")
    areas = {str(k): reader.polygon(v, f"areas.{k}") for k, v in areas_raw.items()}
    elements_raw = data.get("elements")
    if not isinstance(elements_raw, list) or not elements_raw:
        raise WorldFileError(path, "elements", f"expected a non-empty list, got {elements_raw!r}")
    elements = reader.elements(elements_raw)
    return World(name=name, elements=elements, areas=areas, floor_z=floor_z, source=Path(path))
