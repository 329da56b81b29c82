"""The world model: named solid elements with a semantic class, plus named area polygons.

A world is read from a declarative YAML file (``maps/<name>/world.yaml``, format below) or from a
triangle mesh (see :mod:`pimm_env.mesh_world`). Everything downstream (the pybullet scene, the
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
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from pimm_env.grid import GridSpec
from pimm_env.semantics import SemanticClass, parse_class
from pimm_env.shapes import Box, Cylinder, Shape

FORMAT = "pimm-world/1"
MAPS_DIR = Path(__file__).resolve().parents[1] / "maps"


class WorldFileError(ValueError):
    """A world file is malformed; the message names the file, the field and the bad value."""

    def __init__(self, path: Path | str, field_name: str, message: str) -> None:
        super().__init__(f"{path}: {field_name}: {message}")
        self.path = str(path)
        self.field = field_name


@dataclass(frozen=True)
class Element:
    """One solid piece of the world."""

    name: str
    semantic: SemanticClass
    shape: Shape
    occupancy: bool


@dataclass
class World:
    """A building: its elements, its named areas and the height of its floor."""

    name: str
    elements: list[Element]
    areas: dict[str, np.ndarray]
    floor_z: float = 0.0
    source: Path | None = None
    _footprints: dict[tuple[Any, ...], np.ndarray] = field(default_factory=dict, repr=False)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper (x, y) corners of everything in the world."""
        points = [poly for poly in self.areas.values()]
        for element in self.elements:
            shape = element.shape
            if isinstance(shape, Box):
                points.append(shape.corners_xy())
            elif isinstance(shape, Cylinder):
                c = np.asarray(shape.center)
                points.append(np.stack([c - shape.radius, c + shape.radius]))
            else:
                points.append(shape.vertices[:, :2])
        stacked = np.concatenate(points, axis=0)
        return stacked.min(axis=0), stacked.max(axis=0)

    def grid(self, resolution: float) -> GridSpec:
        lower, upper = self.bounds()
        return GridSpec.covering(lower, upper, resolution)

    def footprint(
        self,
        grid: GridSpec,
        z: float,
        classes: Sequence[SemanticClass] | None = None,
        occupancy_only: bool = False,
    ) -> np.ndarray:
        """Cells covered at height ``z`` by elements of ``classes`` (all if None)."""
        key = (grid, round(z, 4), tuple(classes) if classes else None, occupancy_only)
        if key not in self._footprints:
            mask = grid.empty_mask()
            for element in self.elements:
                if classes is not None and element.semantic not in classes:
                    continue
                if occupancy_only and not element.occupancy:
                    continue
                mask |= element.shape.footprint(grid, z)
            self._footprints[key] = mask
        return self._footprints[key]

    def area_mask(self, grid: GridSpec) -> np.ndarray:
        """Cells inside any named area."""
        mask = grid.empty_mask()
        for polygon in self.areas.values():
            mask |= grid.points_in_polygon(polygon)
        return mask

    def area_of(self, x: float, y: float) -> str | None:
        """Name of the area holding the point, or None."""
        for name, polygon in self.areas.items():
            if _point_in_polygon(x, y, polygon):
                return name
        return None

    def ceiling_heights(self) -> list[float]:
        """Distinct heights of the undersides of ceiling elements, lowest first."""
        heights = {round(e.shape.z_range[0], 3) for e in self.elements if e.semantic == SemanticClass.CEILING}
        return sorted(heights)


def _point_in_polygon(x: float, y: float, polygon: np.ndarray) -> bool:
    inside = False
    n = len(polygon)
    for i in range(n):
        ax, ay = polygon[i]
        bx, by = polygon[(i + 1) % n]
        if (ay > y) != (by > y) and x < ax + (y - ay) * (bx - ax) / (by - ay):
            inside = not inside
    return inside


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
    raise FileNotFoundError(f"unknown world {str(world)!r}: no file {named}; known worlds: {', '.join(known)}")


def load_world(world: str | Path) -> World:
    """Load a world by name or path; dispatches to the mesh loader for ``format: pimm-mesh-world/1``."""
    import yaml

    path = resolve_world_path(world)
    try:
        data = yaml.safe_load(path.read_text())
    except yaml.YAMLError as exc:
        raise WorldFileError(path, "(file)", f"not valid YAML: {exc}") from None
    if not isinstance(data, Mapping):
        raise WorldFileError(path, "(file)", f"expected a mapping at the top level, got {type(data).__name__}")
    fmt = data.get("format")
    if fmt == "pimm-mesh-world/1":
        from pimm_env.mesh_world import world_from_mesh_spec

        return world_from_mesh_spec(data, path)
    if fmt != FORMAT:
        raise WorldFileError(path, "format", f"expected {FORMAT!r} or 'pimm-mesh-world/1', got {fmt!r}")
    return world_from_spec(data, path)


def world_from_spec(data: Mapping[str, Any], path: Path | str = "<dict>") -> World:
    """Build a :class:`World` from the parsed contents of a world file, validating every field."""
    reader = _Reader(path)
    name = reader.string(data, "name")
    floor_z = reader.number(data.get("floor_z", 0.0), "floor_z")
    areas_raw = data.get("areas")
    if not isinstance(areas_raw, Mapping) or not areas_raw:
        raise WorldFileError(path, "areas", f"expected a non-empty mapping of name -> polygon, got {areas_raw!r}")
    areas = {str(k): reader.polygon(v, f"areas.{k}") for k, v in areas_raw.items()}
    elements_raw = data.get("elements")
    if not isinstance(elements_raw, list) or not elements_raw:
        raise WorldFileError(path, "elements", f"expected a non-empty list, got {elements_raw!r}")
    elements: list[Element] = []
    seen: set[str] = set()
    for i, raw in enumerate(elements_raw):
        where = f"elements[{i}]"
        if not isinstance(raw, Mapping):
            raise WorldFileError(path, where, f"expected a mapping, got {raw!r}")
        el_name = reader.string(raw, "name", where)
        where = f"elements[{i}] ({el_name})"
        if el_name in seen:
            raise WorldFileError(path, f"{where}.name", f"duplicate element name {el_name!r}")
        seen.add(el_name)
        try:
            semantic = parse_class(str(raw.get("class")))
        except ValueError as exc:
            raise WorldFileError(path, f"{where}.class", str(exc)) from None
        occupancy = raw.get("occupancy", semantic in (SemanticClass.WALL, SemanticClass.CLUTTER))
        if not isinstance(occupancy, bool):
            raise WorldFileError(path, f"{where}.occupancy", f"expected true or false, got {occupancy!r}")
        shapes = [key for key in ("box", "cylinder", "wall") if key in raw]
        if len(shapes) != 1:
            raise WorldFileError(path, where, f"expected exactly one of box, cylinder, wall; got {shapes or 'none'}")
        kind = shapes[0]
        for j, shape in enumerate(reader.shapes(kind, raw[kind], f"{where}.{kind}")):
            suffix = f"#{j}" if kind == "wall" and j else ""
            elements.append(Element(el_name + suffix, semantic, shape, occupancy))
    return World(name=name, elements=elements, areas=areas, floor_z=floor_z, source=Path(path))


class _Reader:
    """Typed field access that reports the file and field of any bad value."""

    def __init__(self, path: Path | str) -> None:
        self.path = path

    def fail(self, field_name: str, message: str) -> WorldFileError:
        return WorldFileError(self.path, field_name, message)

    def string(self, data: Mapping[str, Any], key: str, where: str = "") -> str:
        value = data.get(key)
        if not isinstance(value, str) or not value:
            raise self.fail(f"{where}.{key}" if where else key, f"expected a non-empty string, got {value!r}")
        return value

    def number(self, value: Any, field_name: str) -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value):
            raise self.fail(field_name, f"expected a finite number, got {value!r}")
        return float(value)

    def vector(self, value: Any, n: int, field_name: str) -> tuple[float, ...]:
        if not isinstance(value, Sequence) or isinstance(value, str) or len(value) != n:
            raise self.fail(field_name, f"expected a list of {n} numbers, got {value!r}")
        return tuple(self.number(v, f"{field_name}[{k}]") for k, v in enumerate(value))

    def positive(self, value: Any, field_name: str) -> float:
        number = self.number(value, field_name)
        if number <= 0:
            raise self.fail(field_name, f"expected a positive number, got {value!r}")
        return number

    def z_range(self, value: Any, field_name: str) -> tuple[float, float]:
        z0, z1 = self.vector(value, 2, field_name)
        if z1 <= z0:
            raise self.fail(field_name, f"expected [bottom, top] with top > bottom, got {list(value)}")
        return z0, z1

    def polygon(self, value: Any, field_name: str) -> np.ndarray:
        if not isinstance(value, Sequence) or len(value) < 3:
            raise self.fail(field_name, f"expected a polygon of at least 3 [x, y] points, got {value!r}")
        return np.array([self.vector(p, 2, f"{field_name}[{k}]") for k, p in enumerate(value)])

    def shapes(self, kind: str, spec: Any, where: str) -> list[Shape]:
        if not isinstance(spec, Mapping):
            raise self.fail(where, f"expected a mapping, got {spec!r}")
        if kind == "box":
            return [self.box(spec, where)]
        if kind == "cylinder":
            center = self.vector(spec.get("center"), 2, f"{where}.center")
            radius = self.positive(spec.get("radius"), f"{where}.radius")
            return [Cylinder(center, radius, self.z_range(spec.get("z"), f"{where}.z"))]
        return self.wall(spec, where)

    def box(self, spec: Mapping[str, Any], where: str) -> Box:
        if "min" in spec or "max" in spec:
            lo = np.array(self.vector(spec.get("min"), 3, f"{where}.min"))
            hi = np.array(self.vector(spec.get("max"), 3, f"{where}.max"))
            if np.any(hi <= lo):
                raise self.fail(f"{where}.max", f"must exceed min on every axis: min {lo.tolist()}, max {hi.tolist()}")
            return Box(tuple((lo + hi) / 2), tuple((hi - lo) / 2))
        center = self.vector(spec.get("center"), 3, f"{where}.center")
        size = self.vector(spec.get("size"), 3, f"{where}.size")
        if min(size) <= 0:
            raise self.fail(f"{where}.size", f"expected positive sizes, got {list(size)}")
        yaw = self.number(spec.get("yaw", 0.0), f"{where}.yaw")
        return Box(center, tuple(s / 2 for s in size), yaw)

    def wall(self, spec: Mapping[str, Any], where: str) -> list[Shape]:
        path = spec.get("path")
        if not isinstance(path, Sequence) or len(path) < 2:
            raise self.fail(f"{where}.path", f"expected at least 2 [x, y] points, got {path!r}")
        points = np.array([self.vector(p, 2, f"{where}.path[{k}]") for k, p in enumerate(path)])
        thickness = self.positive(spec.get("thickness"), f"{where}.thickness")
        z0, z1 = self.z_range(spec.get("z"), f"{where}.z")
        boxes: list[Shape] = []
        for k, (a, b) in enumerate(itertools.pairwise(points)):
            length = float(np.linalg.norm(b - a))
            if length == 0:
                raise self.fail(f"{where}.path[{k + 1}]", f"repeats the previous point {a.tolist()}")
            # Extend each segment by half the thickness so that consecutive segments close their corner.
            mid = (a + b) / 2
            yaw = float(np.arctan2(b[1] - a[1], b[0] - a[0]))
            half = ((length + thickness) / 2, thickness / 2, (z1 - z0) / 2)
            boxes.append(Box((float(mid[0]), float(mid[1]), (z0 + z1) / 2), half, yaw))
        return boxes
