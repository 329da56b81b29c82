"""Typed access to the fields of a parsed world file, with errors that name the file and the field."""

from __future__ import annotations

import itertools
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from pimm_env.errors import WorldFileError
from pimm_env.world.model import Element
from pimm_env.world.semantics import SemanticClass, parse_class
from pimm_env.world.shapes import Box, Cylinder, Prism, Shape

#: An element's shape keys (exactly one) and its other keys (world file format: pimm_env/world/files.py).
SHAPE_KEYS = ("box", "cylinder", "wall", "prism")
ELEMENT_KEYS = frozenset({"name", "class", "occupancy"})


class FieldReader:
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

    def elements(self, raw_list: list[Any], taken: frozenset[str] = frozenset()) -> list[Element]:
        """The ``elements`` list of a world file; names must be unique (and not among ``taken``)."""
        elements: list[Element] = []
        seen: set[str] = set(taken)
        for i, raw in enumerate(raw_list):
            where = f"elements[{i}]"
            if not isinstance(raw, Mapping):
                raise self.fail(where, f"expected a mapping, got {raw!r}")
            el_name = self.string(raw, "name", where)
            where = f"elements[{i}] ({el_name})"
            if el_name in seen:
                raise self.fail(f"{where}.name", f"duplicate element name {el_name!r}")
            seen.add(el_name)
            try:
                semantic = parse_class(str(raw.get("class")))
            except ValueError as exc:
                raise self.fail(f"{where}.class", str(exc)) from None
            occupancy = raw.get("occupancy", semantic in (SemanticClass.WALL, SemanticClass.CLUTTER))
            if not isinstance(occupancy, bool):
                raise self.fail(f"{where}.occupancy", f"expected true or false, got {occupancy!r}")
            shapes = [key for key in SHAPE_KEYS if key in raw]
            if len(shapes) != 1:
                raise self.fail(where, f"expected exactly one of {', '.join(SHAPE_KEYS)}; got {shapes or 'none'}")
            unknown = sorted(set(raw) - set(SHAPE_KEYS) - ELEMENT_KEYS)
            if unknown:
                valid = ", ".join(sorted(ELEMENT_KEYS | set(SHAPE_KEYS)))
                raise self.fail(f"{where}.{unknown[0]}", f"unknown key; valid keys: {valid}")
            kind = shapes[0]
            for j, shape in enumerate(self.shapes(kind, raw[kind], f"{where}.{kind}")):
                suffix = f"#{j}" if kind == "wall" and j else ""
                elements.append(Element(el_name + suffix, semantic, shape, occupancy))
        return elements

    def shapes(self, kind: str, spec: Any, where: str) -> list[Shape]:
        if not isinstance(spec, Mapping):
            raise self.fail(where, f"expected a mapping, got {spec!r}")
        if kind == "box":
            return [self.box(spec, where)]
        if kind == "cylinder":
            center = self.vector(spec.get("center"), 2, f"{where}.center")
            radius = self.positive(spec.get("radius"), f"{where}.radius")
            return [Cylinder((center[0], center[1]), radius, self.z_range(spec.get("z"), f"{where}.z"))]
        if kind == "prism":
            return [self.prism(spec, where)]
        return self.wall(spec, where)

    def prism(self, spec: Mapping[str, Any], where: str) -> Prism:
        outline = self.polygon(spec.get("outline"), f"{where}.outline")
        holes_raw = spec.get("holes", [])
        if not isinstance(holes_raw, Sequence) or isinstance(holes_raw, str):
            raise self.fail(f"{where}.holes", f"expected a list of polygons, got {holes_raw!r}")
        holes = tuple(self.polygon(h, f"{where}.holes[{k}]") for k, h in enumerate(holes_raw))
        return Prism(outline, holes, self.z_range(spec.get("z"), f"{where}.z"))

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
        return Box((center[0], center[1], center[2]), (size[0] / 2, size[1] / 2, size[2] / 2), yaw)

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
