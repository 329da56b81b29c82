"""From an occupancy raster to straight walls: free space as polygons whose edges lie at the walls' true angle.

1. Free space is the free cells in components wide and large enough for a robot; everything else is structure
   (a hollow wall drawn as two lines, an unknown patch, a stray free speck are filled).
2. Its outline is traced between cell centres (marching squares), so a wall face lies on the cell edges.
3. Each ring is cut into straight runs (Douglas-Peucker at ``tolerance``), a line is fitted to the traced points
   of each run away from its ends, and each vertex is moved to where the lines of its two runs meet: a 30 deg
   staircase becomes one edge at 30 deg, and a corner lands on the walls' junction, not on a raster step.
4. The structure is the map's rectangle minus the free space, kept only within ``structure_reach_m`` of an
   occupied cell: unknown space (a SLAM map's unseen exterior) stays unknown, as map_server and nav2 read it,
   while a wall drawn hollow (unknown or a free sliver between two lines) is solid. The piece of structure
   around the outside is the walls, the pieces standing inside a room are walls when large and clutter
   (pillars, fixed furniture) when small.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from pimm_env.errors import MapFileError
from pimm_env.mapping.map_server import RasterMap
from pimm_env.world.polyline import douglas_peucker


@dataclass(frozen=True)
class VectorizeConfig:
    min_space_area_m2: float = 1.0  # free components smaller than this are filled
    min_space_width_m: float = 0.6  # free components a robot cannot stand in (widest point) are filled
    tolerance_cells: float = 1.0  # Douglas-Peucker tolerance, in cells (0.8 missed corners at 3-17 and 75-87 deg)
    end_margin_cells: float = 1.5  # traced points this close to a run's ends are left out of its line fit
    min_turn_deg: float = 8.0  # vertices that turn less than this are dropped after the fit
    island_clutter_m2: float = 4.0  # structure standing inside a room is clutter when smaller than this
    island_wall_length_m: float = 1.5  # ... unless it runs this long (a free-standing partition)
    margin_m: float = 0.5  # the structure's outer rectangle extends this far beyond the map
    structure_reach_m: float = 0.3  # non-free cells farther than this from an occupied cell are unknown, not wall


@dataclass(frozen=True)
class FloorPlan:
    """Shapely polygons in the map frame: free space (one per connected region), walls and clutter."""

    spaces: list
    walls: list
    clutter: list


def free_space(raster: RasterMap, config: VectorizeConfig) -> np.ndarray:
    """Free cells in components that a robot can stand in."""
    labels, count = ndimage.label(raster.free)
    if count == 0:
        return np.zeros_like(raster.free)
    cells = np.bincount(labels.ravel(), minlength=count + 1)
    width = ndimage.maximum(ndimage.distance_transform_edt(raster.free), labels, np.arange(count + 1))
    res = raster.resolution
    keep = (cells * res**2 >= config.min_space_area_m2) & (2 * np.asarray(width) * res >= config.min_space_width_m)
    keep[0] = False
    return keep[labels]


def _fit_line(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    centre = points.mean(axis=0)
    _, _, vt = np.linalg.svd(points - centre)
    return centre, vt[0]


def straighten(ring: np.ndarray, tolerance: float, end_margin: float, min_turn_deg: float) -> np.ndarray:
    """A closed traced ring (N, 2), not repeated at the end, as a polygon of straight runs (K, 2)."""
    ring = np.asarray(ring, dtype=float)
    start = int(np.argmax(np.hypot(*(ring - ring.mean(axis=0)).T)))
    ring = np.roll(ring, -start, axis=0)
    closed = np.vstack([ring, ring[:1]])
    kept = douglas_peucker(closed, tolerance)[:-1]  # the last index is the first point again
    if len(kept) < 3:
        return ring[kept]
    lines, lengths = [], []
    for a, b in zip(kept, [*kept[1:], len(ring)], strict=True):
        run = closed[a : b + 1]
        along = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(run, axis=0).T))])
        inner = run[(along >= end_margin) & (along <= along[-1] - end_margin)]
        lines.append(_fit_line(inner) if len(inner) >= 2 else _fit_line(run[[0, -1]]))
        lengths.append(along[-1])
    min_sin = np.sin(np.radians(min_turn_deg))
    # A short run between two runs that meet at an angle is the tracer's cut across a corner: drop it, so the
    # corner is where its neighbours' lines meet. A short run between parallel runs (a door jamb) stays.
    n, short = len(lines), 2 * (tolerance + end_margin)
    keep = [
        not (
            lengths[k] < short <= min(lengths[k - 1], lengths[(k + 1) % n])
            and abs(_cross(lines[k - 1][1], lines[(k + 1) % n][1])) > min_sin
        )
        for k in range(n)
    ]
    order = [k for k in range(n) if keep[k]]
    vertices = []
    for i, k in enumerate(order):
        (p, u), (q, v) = lines[order[i - 1]], lines[k]
        cross = _cross(u, v)
        if abs(cross) < min_sin:
            continue  # the runs are nearly parallel: no corner here
        t = ((q[0] - p[0]) * v[1] - (q[1] - p[1]) * v[0]) / cross
        meet = p + t * u
        if np.hypot(*(meet - closed[kept[k]])) > 4 * (tolerance + end_margin):
            meet = closed[kept[k]]  # the lines meet far away: keep the traced vertex
        vertices.append(meet)
    return np.array(vertices).reshape(-1, 2)


def _cross(u: np.ndarray, v: np.ndarray) -> float:
    return float(u[0] * v[1] - u[1] * v[0])


def traced_polygons(space: np.ndarray, resolution: float) -> list[tuple[np.ndarray, list[np.ndarray]]]:
    """Outer ring and holes of each free region, in image metres (cell centres at (i + 0.5) res)."""
    import contourpy

    padded = np.pad(space, 1).astype(float)
    rows, cols = padded.shape
    x = (np.arange(cols) - 0.5) * resolution
    y = (np.arange(rows) - 0.5) * resolution
    generator = contourpy.contour_generator(x, y, padded, fill_type=contourpy.FillType.OuterOffset)
    points, offsets = generator.filled(0.5, 1.5)[:2]  # OuterOffset: point arrays and ring offsets
    polygons = []
    for pts, offs in zip(points, offsets, strict=True):
        assert pts is not None and offs is not None  # OuterOffset fills both
        rings = [pts[offs[i] : offs[i + 1] - 1] for i in range(len(offs) - 1)]  # drop the repeated point
        polygons.append((rings[0], rings[1:]))
    return polygons


def vectorize(raster: RasterMap, config: VectorizeConfig | None = None) -> FloorPlan:
    """The floor plan of ``raster``: free space, walls and clutter as straight-edged polygons (map frame)."""
    import shapely
    from shapely.geometry import Polygon, box

    config = config or VectorizeConfig()
    res = raster.resolution
    space = free_space(raster, config)
    if not space.any():
        raise MapFileError(
            f"{raster.source}: no free space: no component of free cells is {config.min_space_width_m} m wide "
            f"and {config.min_space_area_m2} m^2 large (check negate and the thresholds)"
        )

    def straight(ring: np.ndarray) -> np.ndarray:
        return straighten(ring, config.tolerance_cells * res, config.end_margin_cells * res, config.min_turn_deg)

    pieces = []
    for outer, holes in traced_polygons(space, res):
        polygon = Polygon(straight(outer), [h for h in map(straight, holes) if len(h) >= 3])
        pieces.append(shapely.make_valid(polygon))
    spaces = shapely.unary_union(pieces)
    rows, cols = space.shape
    m = config.margin_m
    solid = box(-m, -m, cols * res + m, rows * res + m).difference(spaces)
    near = ndimage.distance_transform_edt(~raster.occupied) * res <= config.structure_reach_m
    if not near.all():
        reach = shapely.unary_union([Polygon(o, h) for o, h in traced_polygons(near, res)]).buffer(res)
        solid = solid.intersection(reach)
    to_map = _map_transform(raster)
    walls, clutter = [], []
    rooms = [Polygon(space.exterior) for space in _polygons(spaces)]
    for polygon in _polygons(solid):
        touches_edge = not any(room.contains(polygon) for room in rooms)  # not an island inside one room
        long_side = max(_sides(polygon.minimum_rotated_rectangle))
        if touches_edge or polygon.area >= config.island_clutter_m2 or long_side >= config.island_wall_length_m:
            walls.append(to_map(polygon))
        else:
            clutter.append(to_map(polygon))
    return FloorPlan([to_map(p) for p in _polygons(spaces)], walls, clutter)


def _sides(rectangle) -> list[float]:
    corners = np.asarray(rectangle.exterior.coords)
    return [float(np.hypot(*(b - a))) for a, b in itertools.pairwise(corners)]


def _polygons(geometry) -> list:
    return [g for g in getattr(geometry, "geoms", [geometry]) if g.geom_type == "Polygon" and not g.is_empty]


def _map_transform(raster: RasterMap):
    import shapely

    def apply(polygon):
        return shapely.transform(polygon, raster.to_map)

    return apply
