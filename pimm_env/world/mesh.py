"""Worlds made of triangle meshes: a mesh file plus rules that map object names to semantic classes.

OBJ files are read by our own reader, which keeps every ``o``/``g`` name exactly as written (trimesh renames
the iilab's objects, ``Cealing_004`` to ``Cealing_4``, and splits 99 objects into 101); PLY, STL, glTF/GLB
and the other formats trimesh knows are read with trimesh, one object per node of the scene.

Mesh world file::

    format: pimm-mesh-world/1
    name: iilab-mesh
    mesh: ../../../shared/data/iilab/iilab.obj   # relative to this file: .obj, .ply, .stl, .glb, .gltf, ...
    up_axis: y                 # y: a vertex (x, y, z) of the file is the map point (x, -z, y); or z
    floor_z: 0.30
    rules:                     # see "Name rules" below
      - {match: "Cealing*", class: ceiling}
      - {match: "Floor", class: floor}
      - {match: "Wall*", class: wall}
      - {match: "*", class: clutter}
    occupancy: [wall, clutter] # classes drawn into the occupancy map
    left_out: [name, ...]      # optional: objects not taken into the world (set by the import, see mesh_checks)
    wall_line: [name, ...]     # optional: objects classed wall whatever the rules say (set by the import: those
                               # standing in a wall's line, windows and closed doors; see importers/wall_line.py)
    ceiling_height: 2.5        # optional: add a flat ceiling this high above floor_z over the floor's extent
    elements: [...]            # optional: solid elements beside the mesh's objects, as in a world file (the
                               # point-cloud import writes its walls so: importers/cloud_walls.py)
    areas: {...}               # optional named polygons, as in a world file; default: the floor's outline
    seen_walls: seen_walls.npy # optional: where a scan saw the walls, (S, 2) x, y points (the point-cloud
                               # import writes it): the corner map leaves out corners neither of whose faces
                               # was seen (pimm_env/mapping/corner_map.py)

Name rules: a ``match`` with a wildcard (``*?[``) is an fnmatch pattern on the whole object name
(case-sensitive); a plain word matches names holding that word, whole and in any case, alone or plural
(``wall`` matches ``HouseWallB_01`` and ``floor_01_walls_1``, not ``Wallpaper``; words split at ``_``, ``-``,
``.``, ``:``, digits and camelCase). Of the rules that match a name, the last specific one wins; a
match-everything pattern (``*``) applies only when no other rule matches.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from fnmatch import fnmatchcase
from pathlib import Path
from typing import Any

import numpy as np

from pimm_env.errors import MissingFileError, WorldError, WorldFileError
from pimm_env.world.model import Element, World
from pimm_env.world.reader import FieldReader
from pimm_env.world.semantics import SemanticClass, parse_class
from pimm_env.world.shapes import Box, Mesh

_WILDCARDS = re.compile(r"[*?\[]")
_WORDS = re.compile(r"[A-Z]+(?![a-z])|[A-Z]?[a-z]+|[0-9]+")


def read_obj(path: Path, up_axis: str = "z") -> dict[str, Mesh]:
    """Objects of a Wavefront OBJ file as triangle meshes in the map frame (polygons are fanned)."""
    path = Path(path)
    if not path.is_file():
        raise MissingFileError(f"mesh file {path} does not exist")
    vertices: list[tuple[float, float, float]] = []
    faces: dict[str, list[list[int]]] = {}
    current = "default"
    for number, line in enumerate(path.read_text().splitlines(), start=1):
        parts = line.split()
        if not parts:
            continue
        try:
            if parts[0] == "o" or parts[0] == "g":
                current = " ".join(parts[1:]) or "default"
            elif parts[0] == "v":
                x, y, z = (float(v) for v in parts[1:4])
                vertices.append((x, -z, y) if up_axis == "y" else (x, y, z))
            elif parts[0] == "f":
                idx = [int(token.split("/")[0]) for token in parts[1:]]
                idx = [i - 1 if i > 0 else len(vertices) + i for i in idx]
                faces.setdefault(current, []).extend([idx[0], idx[k], idx[k + 1]] for k in range(1, len(idx) - 1))
        except (ValueError, IndexError):
            raise WorldError(f"{path}:{number}: cannot parse {line.strip()!r}") from None
    all_vertices = np.array(vertices, dtype=float).reshape(-1, 3)
    meshes: dict[str, Mesh] = {}
    for name, tris in faces.items():
        tri = np.array(tris, dtype=np.int64)
        if tri.size and (tri.min() < 0 or tri.max() >= len(all_vertices)):
            raise WorldError(f"{path}: object {name!r} refers to a vertex that does not exist")
        used, local = np.unique(tri, return_inverse=True)
        meshes[name] = Mesh(all_vertices[used], local.reshape(-1, 3))
    return meshes


def read_mesh(path: Path, up_axis: str = "z") -> dict[str, Mesh]:
    """Named triangle meshes of a mesh file in the map frame (see the module docstring for the formats)."""
    path = Path(path)
    if path.suffix.lower() == ".obj":
        return read_obj(path, up_axis)
    if not path.is_file():
        raise MissingFileError(f"mesh file {path} does not exist")
    import trimesh

    try:
        scene = trimesh.load(path, force="scene")
    except Exception as error:  # trimesh raises many kinds for unreadable files
        raise WorldError(f"{path}: cannot read the mesh: {error}") from None
    if not isinstance(scene, trimesh.Scene):
        raise WorldError(f"{path}: expected a mesh scene, got {type(scene).__name__}")
    meshes: dict[str, Mesh] = {}
    for node in scene.graph.nodes_geometry:
        transform, geometry_name = scene.graph[node]
        geometry = scene.geometry[geometry_name]
        if not hasattr(geometry, "faces") or len(geometry.faces) == 0:
            continue
        vertices = trimesh.transform_points(np.asarray(geometry.vertices, dtype=float), transform)
        if up_axis == "y":
            vertices = np.column_stack([vertices[:, 0], -vertices[:, 2], vertices[:, 1]])
        meshes[str(node)] = Mesh(vertices, np.asarray(geometry.faces, dtype=np.int64))
    if not meshes:
        raise WorldError(f"{path}: the file holds no triangles")
    return meshes


def name_words(name: str) -> list[str]:
    """The words of an object name, lower case: ``HouseWallB_01`` -> ``house wall b 01``."""
    return [w.lower() for w in _WORDS.findall(name)]


def rule_matches(pattern: str, name: str) -> bool:
    """Whether one rule's ``match`` matches a name (see "Name rules" in the module docstring)."""
    if _WILDCARDS.search(pattern):
        return fnmatchcase(name, pattern)
    word = pattern.lower()
    return any(w in (word, f"{word}s", f"{word}es") for w in name_words(name))


def classify(name: str, rules: list[tuple[str, SemanticClass]]) -> SemanticClass | None:
    """The class of the last specific rule that matches ``name``; else of a generic (``*``) rule; else None."""
    specific = [semantic for pattern, semantic in rules if pattern.strip("*") and rule_matches(pattern, name)]
    if specific:
        return specific[-1]
    generic = [semantic for pattern, semantic in rules if not pattern.strip("*")]
    return generic[-1] if generic else None


def world_from_mesh_spec(data: Mapping[str, Any], path: Path) -> World:
    """Build a world from a parsed mesh world file (see the module docstring)."""
    mesh_ref = data.get("mesh")
    if not isinstance(mesh_ref, str):
        raise WorldFileError(path, "mesh", f"expected the path of a mesh file, got {mesh_ref!r}")
    mesh_path = (Path(path).parent / mesh_ref).resolve()
    if not mesh_path.is_file():
        raise WorldFileError(path, "mesh", f"file {mesh_path} does not exist")
    up_axis = data.get("up_axis", "z")
    if up_axis not in ("y", "z"):
        raise WorldFileError(path, "up_axis", f"expected 'y' or 'z', got {up_axis!r}")
    raw_rules = data.get("rules")
    if not isinstance(raw_rules, list) or not raw_rules:
        raise WorldFileError(path, "rules", f"expected a list of {{match, class}}, got {raw_rules!r}")
    rules = []
    for i, rule in enumerate(raw_rules):
        if not isinstance(rule, Mapping) or not isinstance(rule.get("match"), str):
            raise WorldFileError(path, f"rules[{i}]", f"expected {{match: PATTERN, class: CLASS}}, got {rule!r}")
        try:
            rules.append((rule["match"], parse_class(str(rule.get("class")))))
        except ValueError as exc:
            raise WorldFileError(path, f"rules[{i}].class", str(exc)) from None
    try:
        occupancy_classes = {parse_class(c) for c in data.get("occupancy", ["wall", "clutter"])}
    except ValueError as exc:
        raise WorldFileError(path, "occupancy", str(exc)) from None
    try:
        meshes = read_mesh(mesh_path, up_axis)
    except ValueError as exc:
        raise WorldFileError(path, "mesh", str(exc)) from None
    left_out = set(data.get("left_out") or [])
    wall_line = data.get("wall_line") or []
    if not isinstance(wall_line, list) or not all(isinstance(n, str) for n in wall_line):
        raise WorldFileError(path, "wall_line", f"expected a list of object names, got {wall_line!r}")
    unknown = sorted(set(wall_line) - set(meshes))
    if unknown:
        raise WorldFileError(path, "wall_line", f"no object {unknown[0]!r} in {mesh_path.name}")
    elements = []
    for name, mesh in meshes.items():
        if name in left_out:
            continue
        semantic = SemanticClass.WALL if name in wall_line else classify(name, rules)
        if semantic is None:
            raise WorldFileError(path, "rules", f"no rule matches object {name!r} of {mesh_path.name}")
        elements.append(Element(name, semantic, mesh, semantic in occupancy_classes))
    extra = data.get("elements")
    if extra is not None:
        if not isinstance(extra, list):
            raise WorldFileError(path, "elements", f"expected a list of world elements, got {extra!r}")
        elements += FieldReader(path).elements(extra, frozenset(meshes))
    floor_z = float(data.get("floor_z", 0.0))
    if data.get("ceiling_height") is not None:
        elements.append(_added_ceiling(elements, floor_z, data["ceiling_height"], path))
    areas_raw = data.get("areas")
    if areas_raw:
        reader = FieldReader(path)
        areas = {str(k): reader.polygon(v, f"areas.{k}") for k, v in areas_raw.items()}
    else:
        extent = _floor_extent(elements)
        if extent is None:
            raise WorldFileError(path, "areas", "no areas given and no floor object to take them from")
        lo, hi = extent
        areas = {"all": np.array([[lo[0], lo[1]], [hi[0], lo[1]], [hi[0], hi[1]], [lo[0], hi[1]]])}
    name = data.get("name") or Path(path).parent.name
    seen = _seen_walls(data.get("seen_walls"), path)
    return World(str(name), elements, areas, floor_z=floor_z, source=Path(path), seen_walls=seen)


def _seen_walls(ref: Any, path: Path) -> np.ndarray | None:
    """The ``seen_walls`` points of a mesh world file (an ``.npy`` of (S, 2) finite numbers), or None."""
    if ref is None:
        return None
    if not isinstance(ref, str):
        raise WorldFileError(path, "seen_walls", f"expected the path of an .npy file, got {ref!r}")
    file = Path(path).parent / ref
    try:
        points = np.load(file, allow_pickle=False)
    except (OSError, ValueError) as error:
        raise WorldFileError(path, "seen_walls", f"cannot read {file}: {error}") from None
    if points.ndim != 2 or points.shape[1] != 2 or not np.issubdtype(points.dtype, np.number):
        raise WorldFileError(path, "seen_walls", f"{file}: expected (S, 2) numbers, got {points.dtype} {points.shape}")
    if not np.all(np.isfinite(points)):
        raise WorldFileError(path, "seen_walls", f"{file}: {int(np.sum(~np.isfinite(points)))} values not finite")
    return points.astype(float)


def _added_ceiling(elements: list[Element], floor_z: float, height: Any, path: Path) -> Element:
    """A flat 10 cm ceiling slab ``height`` above the floor over the floor objects' extent."""
    try:
        height = float(height)
    except (TypeError, ValueError):
        raise WorldFileError(path, "ceiling_height", f"expected a height in metres, got {height!r}") from None
    if not 0.5 <= height <= 50.0:
        raise WorldFileError(path, "ceiling_height", f"expected a height between 0.5 and 50 m, got {height}")
    extent = _floor_extent(elements)
    if extent is None:
        raise WorldFileError(path, "ceiling_height", "the world has no floor object to lay the ceiling over")
    lo, hi = extent
    center = ((lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, floor_z + height + 0.05)
    half = ((hi[0] - lo[0]) / 2, (hi[1] - lo[1]) / 2, 0.05)
    return Element("added_ceiling", SemanticClass.CEILING, Box(center, half), False)


def _floor_extent(elements: list[Element]) -> tuple[np.ndarray, np.ndarray] | None:
    """The lower and upper (x, y) corners of the floor meshes' extent; None without a floor mesh."""
    floors = [
        e.shape.vertices[:, :2] for e in elements if e.semantic == SemanticClass.FLOOR and isinstance(e.shape, Mesh)
    ]
    if not floors:
        return None
    pts = np.concatenate(floors)
    return pts.min(axis=0), pts.max(axis=0)
