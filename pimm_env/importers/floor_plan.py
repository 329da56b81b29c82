"""A floor plan (free space, walls, clutter as polygons) extruded into a ``pimm-world/1`` world file.

Walls and clutter become prisms from the floor to the highest ceiling; a floor slab and a ceiling slab cover
the plan, and areas of another ceiling height (a small YAML, below) get their own ceiling piece. The free
space becomes the world's areas, so nothing has to be drawn by hand. ``furnish`` adds seeded mapped furniture.

Ceiling heights file::

    default: 3.0                  # optional; else --ceiling-height
    areas:
      hall: {polygon: [[0, 0], [12, 0], [12, 8], [0, 8]], height: 6.0}
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from pimm_env.errors import MapFileError
from pimm_env.importers.vectorize import FloorPlan

SLAB = 0.1  # thickness of the floor and ceiling slabs (m)


@dataclass(frozen=True)
class CeilingArea:
    name: str
    polygon: np.ndarray
    height: float


def read_ceilings(path: Path, default: float) -> tuple[float, list[CeilingArea]]:
    """The default height and the areas of other heights from a ceilings file (format above)."""
    import yaml

    try:
        data = yaml.safe_load(Path(path).read_text())
    except (OSError, yaml.YAMLError) as error:
        raise MapFileError(f"{path}: cannot read the ceilings file: {error}") from None
    if not isinstance(data, Mapping):
        raise MapFileError(f"{path}: expected a mapping with 'default' and 'areas'")
    height = data.get("default", default)
    if not isinstance(height, (int, float)) or height <= 0:
        raise MapFileError(f"{path}: default: expected a positive height (m), got {height!r}")
    areas = []
    for name, spec in (data.get("areas") or {}).items():
        where = f"{path}: areas.{name}"
        if not isinstance(spec, Mapping):
            raise MapFileError(f"{where}: expected {{polygon: [[x, y], ...], height: H}}, got {spec!r}")
        try:
            polygon = np.asarray(spec.get("polygon"), dtype=float)
        except (TypeError, ValueError):
            raise MapFileError(f"{where}.polygon: expected [[x, y], ...], got {spec.get('polygon')!r}") from None
        if polygon.ndim != 2 or polygon.shape[1] != 2 or len(polygon) < 3 or not np.isfinite(polygon).all():
            raise MapFileError(f"{where}.polygon: expected at least 3 finite [x, y] points")
        area_height = spec.get("height")
        if not isinstance(area_height, (int, float)) or area_height <= 0:
            raise MapFileError(f"{where}.height: expected a positive height (m), got {area_height!r}")
        areas.append(CeilingArea(str(name), polygon, float(area_height)))
    return float(height), areas


def _ring(coords: Any) -> list[list[float]]:
    points = np.asarray(coords)[:-1]  # shapely repeats the first point
    return [[round(float(x), 4), round(float(y), 4)] for x, y in points]


def _prism(polygon: Any, z0: float, z1: float) -> dict[str, Any]:
    spec: dict[str, Any] = {"outline": _ring(polygon.exterior.coords), "z": [z0, z1]}
    holes = [_ring(h.coords) for h in polygon.interiors]
    if holes:
        spec["holes"] = holes
    return spec


def world_spec(name: str, plan: FloorPlan, ceiling: float, ceilings: list[CeilingArea] | None = None) -> dict[str, Any]:
    """The ``pimm-world/1`` mapping of an extruded floor plan."""
    import shapely
    from shapely.geometry import Polygon, box

    ceilings = ceilings or []
    top = max([ceiling, *(c.height for c in ceilings)])
    structure = shapely.unary_union([*plan.walls, *plan.clutter, *plan.spaces])
    x0, y0, x1, y1 = structure.bounds
    cover = box(x0, y0, x1, y1)
    elements: list[dict[str, Any]] = [
        {"name": "floor", "class": "floor", "box": {"min": [x0, y0, -SLAB], "max": [x1, y1, 0.0]}},
    ]
    rest = cover
    for area in ceilings:
        piece = Polygon(area.polygon).intersection(cover)
        rest = rest.difference(piece)
        for k, part in enumerate(getattr(piece, "geoms", [piece])):
            if part.geom_type == "Polygon" and not part.is_empty:
                spec = {"name": f"ceiling_{area.name}_{k}", "class": "ceiling"}
                elements.append({**spec, "prism": _prism(part, area.height, area.height + SLAB)})
    for k, part in enumerate(getattr(rest, "geoms", [rest])):
        if part.geom_type == "Polygon" and not part.is_empty:
            elements.append(
                {"name": f"ceiling_{k}", "class": "ceiling", "prism": _prism(part, ceiling, ceiling + SLAB)}
            )
    for k, wall in enumerate(plan.walls):
        elements.append({"name": f"walls_{k}", "class": "wall", "prism": _prism(wall, 0.0, top)})
    for k, piece in enumerate(plan.clutter):
        elements.append({"name": f"fixture_{k}", "class": "clutter", "prism": _prism(piece, 0.0, top)})
    areas = {f"space_{k + 1}": _ring(space.exterior.coords) for k, space in enumerate(plan.spaces)}
    return {"format": "pimm-world/1", "name": name, "floor_z": 0.0, "areas": areas, "elements": elements}


def write_world(spec: Mapping[str, Any], path: Path) -> Path:
    """Write a world mapping as YAML, coordinate lists on one line each."""
    import yaml

    class _Dumper(yaml.SafeDumper):
        pass

    def short_lists(dumper: yaml.SafeDumper, data: list) -> yaml.Node:
        flat = all(isinstance(v, (int, float)) for v in data)
        return dumper.represent_sequence("tag:yaml.org,2002:seq", data, flow_style=flat)

    _Dumper.add_representer(list, short_lists)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(yaml.dump(_plain(spec), Dumper=_Dumper, sort_keys=False, width=120))
    return path


def _plain(value: Any) -> Any:
    """Nested data with numpy scalars and tuples turned into Python numbers and lists."""
    if isinstance(value, Mapping):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    return value
