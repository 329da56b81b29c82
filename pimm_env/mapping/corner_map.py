"""The corner map: every place where two walls meet under a ceiling (thesis 3.1.2, "Feature Map").

The thesis drew its ten corners by hand; here they are derived from the world. For each ceiling height (see
:mod:`pimm_env.mapping.ceilings`: any ceiling's shape), the walls are cut just below the ceiling on a fine grid
(a mesh wall's hollow inside filled), and every grid vertex where the four cells around
it hold one odd cell out (three wall cells and a free one: an inside corner; one wall cell and three free:
an outside corner) is a candidate. A candidate is kept when both wall faces run straight for at least
``min_face`` metres (so wall ends at doorways do not count), the ceiling covers it, and it faces a named
area. Its orientation is the thesis's: the bisector of the two wall directions seen from the corner.

A world made from a scan knows where the scan saw its walls (``World.seen_walls``: the point-cloud import);
there a corner is kept only where the scan saw at least one of its two faces. The rest stand where the import
guessed a wall's hidden back (the far side of a wall seen from one room, the outside of an outer wall).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy import ndimage

from pimm_env.errors import WorldError
from pimm_env.mapping.ceilings import ceiling_cover, ceiling_levels
from pimm_env.world.files import World
from pimm_env.world.grid import GridSpec
from pimm_env.world.semantics import SemanticClass
from pimm_env.world.shapes import Box, Cylinder, Mesh, Prism
from pimm_env.yaml_file import yaml_problem

FORMAT = "pimm-corners/1"


@dataclass(frozen=True)
class CornerMapConfig:
    resolution: float = 0.05
    shell_fill: float = 0.25  # a mesh wall's hollow inside, up to this half-width (m), counts as wall
    below_ceiling: float = 0.10  # height below the ceiling's underside at which walls are cut
    min_face: float = 0.30  # both faces must run straight this far from the corner
    area_margin: float = 0.30  # how far outside a named area a corner may lie
    min_turn_deg: float = 30.0  # outlines (not rasters): the walls turn by at least this much at a corner


@dataclass(frozen=True)
class CornerMap:
    """Corners as arrays: ``xy`` (N, 2), ceiling height ``z`` (N,), orientation ``theta`` (N,) in radians."""

    xy: np.ndarray
    z: np.ndarray
    theta: np.ndarray

    def __len__(self) -> int:
        return len(self.z)


def derive_corner_map(world: World, config: CornerMapConfig | None = None) -> CornerMap:
    """Corners from a fine raster of the walls where every wall lies along the grid (axis-aligned boxes,
    cylinders) or is a mesh; from the walls' outlines where some wall is a prism or a box at another angle,
    whose raster would be a staircase of false corners."""
    config = config or CornerMapConfig()
    walls = [e.shape for e in world.elements if e.semantic == SemanticClass.WALL]
    slanted = any(isinstance(s, Prism) or (isinstance(s, Box) and not _on_grid(s.yaw)) for s in walls)
    if slanted and not any(isinstance(s, Mesh) for s in walls):
        corners = _vector_corner_map(world, config)
    else:
        corners = _raster_corner_map(world, config)
    return corners if world.seen_walls is None else _seen_corners(corners, world.seen_walls, config)


#: a face was seen where a scan's wall point lies this near it (m): 3/4 of the point-cloud import's voxel, so a
#: guessed back face, 0.15 m behind the seen one, is not
SEEN_REACH_M = 0.075
#: ... from this many of the points ``resolution`` apart along the face's first ``SEEN_ALONG_M`` from the corner
SEEN_SAMPLES = 2
#: how far along a face from its corner it may first have been seen (m): furniture standing in the corner (a
#: cabinet's depth) hides the stretch nearest it from a LiDAR below its top
SEEN_ALONG_M = 1.0


def _seen_corners(corners: CornerMap, seen_walls: np.ndarray, config: CornerMapConfig) -> CornerMap:
    """The corners at least one of whose faces has seen wall points along it (a right angle's faces leave the
    corner 45 degrees either side of its orientation)."""
    from scipy.spatial import cKDTree

    if not len(corners) or not len(seen_walls):
        return CornerMap(corners.xy[:0], corners.z[:0], corners.theta[:0])
    tree = cKDTree(seen_walls)
    steps = np.arange(1, round(SEEN_ALONG_M / config.resolution) + 1) * config.resolution
    keep = np.zeros(len(corners), dtype=bool)
    for side in (-1.0, 1.0):
        heading = corners.theta + side * np.pi / 4
        along = np.stack([np.cos(heading), np.sin(heading)], axis=1)
        samples = corners.xy[:, None, :] + steps[None, :, None] * along[:, None, :]
        distance, _ = tree.query(samples.reshape(-1, 2))
        keep |= np.sum(distance.reshape(len(corners), -1) <= SEEN_REACH_M, axis=1) >= SEEN_SAMPLES
    return CornerMap(corners.xy[keep], corners.z[keep], corners.theta[keep])


def _on_grid(yaw: float) -> bool:
    return abs((yaw + np.pi / 4) % (np.pi / 2) - np.pi / 4) < 1e-6


#: corners found under several ceiling heights this close (m) and this alike in orientation (deg) are one corner
SAME_CORNER_M = 0.15
SAME_CORNER_DEG = 10.0


def _as_map(found: list[tuple[float, float, float, float]]) -> CornerMap:
    """The corners (x, y, ceiling height, orientation), each place once: where the same corner was found under
    several ceiling heights (a sloped ceiling spans many), at the lowest."""
    if not found:
        return CornerMap(np.zeros((0, 2)), np.zeros(0), np.zeros(0))
    arr = np.array(found)
    kept: list[int] = []
    for i in np.argsort(arr[:, 2], kind="stable"):
        turn = np.abs((arr[kept, 3] - arr[i, 3] + np.pi) % (2 * np.pi) - np.pi)
        near = np.hypot(*(arr[kept, :2] - arr[i, :2]).T) < SAME_CORNER_M
        if not np.any(near & (turn < np.radians(SAME_CORNER_DEG))):
            kept.append(int(i))
    arr = arr[np.sort(kept)]
    return CornerMap(arr[:, :2], arr[:, 2], arr[:, 3])


#: cells (of ``CornerMapConfig.resolution``) a corner's free side may lie off a mesh ceiling's cover
MESH_CEILING_REACH = 2


def _vector_corner_map(world: World, config: CornerMapConfig) -> CornerMap:
    """Vertices of the walls' cross-section just under each ceiling where the outline turns by at least
    ``min_turn_deg``, both edges run ``min_face``, and the free side is under that ceiling and in an area (a
    mesh ceiling's heights and cover as the raster map reads them: :mod:`pimm_env.mapping.ceilings`)."""
    import shapely
    from shapely.geometry import Point, Polygon

    areas = shapely.unary_union([Polygon(p) for p in world.areas.values()]).buffer(config.area_margin)
    found: list[tuple[float, float, float, float]] = []
    straight = np.cos(np.radians(180.0 - config.min_turn_deg))
    meshes = any(isinstance(e.shape, Mesh) for e in world.elements if e.semantic == SemanticClass.CEILING)
    grid = world.grid(config.resolution) if meshes else None
    for height in ceiling_levels(world) if meshes else world.ceiling_heights():
        walls = shapely.simplify(_section(world, SemanticClass.WALL, height - config.below_ceiling), 1e-3)
        if grid is None:
            covered = _section(world, SemanticClass.CEILING, height + 0.01).covers
        else:
            # a mesh ceiling's cover is a raster of its faces, at the heights its columns were drawn at: beside a
            # wall that rises to a higher ceiling its edge can stand a cell or two off the wall's face
            near = ndimage.binary_dilation(ceiling_cover(world, grid, height), iterations=MESH_CEILING_REACH)
            covered = _under(near, grid)
        for ring in _rings(walls):
            coords = np.asarray(ring.coords)[:-1]
            for i, vertex in enumerate(coords):
                e1, e2 = coords[i - 1] - vertex, coords[(i + 1) % len(coords)] - vertex
                l1, l2 = float(np.hypot(*e1)), float(np.hypot(*e2))
                if min(l1, l2) < config.min_face or np.dot(e1, e2) / (l1 * l2) < straight:
                    continue
                bisector = e1 / l1 + e2 / l2
                bisector /= np.hypot(*bisector)
                probes = [Point(vertex + s * config.resolution * bisector) for s in (1.0, -1.0)]
                free = [p for p in probes if not walls.covers(p)]
                if free and covered(free[0]) and areas.covers(free[0]):
                    found.append((float(vertex[0]), float(vertex[1]), height, float(np.arctan2(*bisector[::-1]))))
    return _as_map(found)


def _under(cover: np.ndarray, grid: GridSpec):
    """Whether a shapely point lies in a cell of ``cover``."""

    def covered(point) -> bool:
        rows, cols, valid = grid.cells_of(np.array([[point.x, point.y]]))
        return bool(valid[0] and cover[rows[0], cols[0]])

    return covered


def _section(world: World, semantic: SemanticClass, z: float):
    """The union of the horizontal cross-sections at height ``z`` of the elements of one class."""
    import shapely
    from shapely.geometry import Point, Polygon

    pieces = []
    for element in world.elements:
        shape = element.shape
        if element.semantic != semantic or not shape.z_range[0] <= z <= shape.z_range[1]:
            continue
        if isinstance(shape, Box):
            pieces.append(Polygon(shape.corners_xy()))
        elif isinstance(shape, Cylinder):
            pieces.append(Point(shape.center).buffer(shape.radius, quad_segs=16))
        elif isinstance(shape, Prism):
            pieces.append(Polygon(shape.outline, list(shape.holes)))
    return shapely.unary_union(pieces)


def _rings(geometry) -> list:
    polygons = getattr(geometry, "geoms", [geometry])
    return [ring for p in polygons if not p.is_empty for ring in (p.exterior, *p.interiors)]


def _raster_corner_map(world: World, config: CornerMapConfig) -> CornerMap:
    grid = world.grid(config.resolution)
    in_area = ndimage.distance_transform_edt(~world.area_mask(grid)) * grid.resolution <= config.area_margin
    found: list[tuple[float, float, float, float]] = []
    for height in ceiling_levels(world):
        walls = fill_shells(
            world.footprint(grid, height - config.below_ceiling, classes=[SemanticClass.WALL]), grid, config
        )
        ceiling = ceiling_cover(world, grid, height)
        for x, y, theta in _corners_of_mask(walls, ceiling & in_area, grid, config):
            found.append((x, y, height, theta))
    return _as_map(found)


def fill_shells(walls: np.ndarray, grid: GridSpec, config: CornerMapConfig) -> np.ndarray:
    """A mesh wall's cross-section is its outline (the solid is a hollow shell); fill the thin enclosed
    regions (no cell farther than ``shell_fill`` from the outline), so a wall's inside gives no corners. Rooms,
    wider than that, stay free."""
    holes = ndimage.binary_fill_holes(walls) & ~walls
    if not holes.any():
        return walls
    labels, count = ndimage.label(holes)
    depth = ndimage.distance_transform_edt(holes) * grid.resolution
    deepest = ndimage.maximum(depth, labels, index=np.arange(1, count + 1))
    thin = np.flatnonzero(np.asarray(deepest) <= config.shell_fill) + 1
    return walls | np.isin(labels, thin)


def _corners_of_mask(
    walls: np.ndarray, allowed: np.ndarray, grid: GridSpec, config: CornerMapConfig
) -> list[tuple[float, float, float]]:
    """Corner vertices of the wall mask: (x, y, theta) for each vertex with one odd cell out of four."""
    n_face = max(1, round(config.min_face / grid.resolution))
    quad = {  # quadrant (sx, sy) of each cell of the 2x2 block around vertex (r, c)
        (-1, -1): walls[:-1, :-1],
        (1, -1): walls[:-1, 1:],
        (-1, 1): walls[1:, :-1],
        (1, 1): walls[1:, 1:],
    }
    count = sum(q.astype(int) for q in quad.values())
    corners = []
    for (sx, sy), cell in quad.items():
        # The odd cell is a wall among three free cells, or a free cell among three walls.
        odd = np.argwhere(((count == 1) & cell) | ((count == 3) & ~cell))
        for r0, c0 in odd:
            r, c = r0 + 1, c0 + 1  # vertex index: cells r-1, r and c-1, c surround it
            value = walls[r + (sy - 1) // 2, c + (sx - 1) // 2]
            if not _faces_straight(walls, r, c, sx, sy, value, n_face):
                continue
            block = [(r + (qy - 1) // 2, c + (qx - 1) // 2) for qx, qy in quad]
            if not any(allowed[i, j] and not walls[i, j] for i, j in block):
                continue
            x = grid.origin[0] + c * grid.resolution
            y = grid.origin[1] + r * grid.resolution
            corners.append((x, y, float(np.arctan2(sy, sx))))
    return corners


def _faces_straight(walls: np.ndarray, r: int, c: int, sx: int, sy: int, value: bool, n: int) -> bool:
    """Both faces leave the vertex straight: along x, the odd cell's row keeps ``value`` and the other row
    keeps its opposite for ``n`` cells; likewise along y."""
    rows, cols = walls.shape
    row_odd, row_other = r + (sy - 1) // 2, r + (-sy - 1) // 2
    col_odd, col_other = c + (sx - 1) // 2, c + (-sx - 1) // 2
    for k in range(n):
        cx = col_odd + sx * k
        ry = row_odd + sy * k
        if not (0 <= cx < cols and 0 <= ry < rows and 0 <= row_other < rows and 0 <= col_other < cols):
            return False
        if walls[row_odd, cx] != value or walls[row_other, cx] == value:
            return False
        if walls[ry, col_odd] != value or walls[ry, col_other] == value:
            return False
    return True


def save_corner_map(corners: CornerMap, path: Path, world_name: str, stamp: str) -> None:
    lines = [
        f"format: {FORMAT}",
        f"world: {world_name}",
        f"source: {stamp}",
        "# x, y: the corner (m, map frame); z: the ceiling's underside (m); theta: orientation (deg),",
        "# the bisector of the two wall directions as seen from the corner (thesis 3.3.3).",
        "corners:",
    ]
    for (x, y), z, theta in zip(corners.xy, corners.z, corners.theta, strict=True):
        lines.append(f"  - {{x: {x:.3f}, y: {y:.3f}, z: {z:.3f}, theta: {np.degrees(theta):.1f}}}")
    if len(corners) == 0:
        lines[-1] = "corners: []"
    Path(path).write_text("\n".join(lines) + "\n")


def load_corner_map(path: Path) -> CornerMap:
    """Read a corner map; accepts this project's format and the thesis's ``features:`` list. Every problem
    names the file, the entry and the field."""
    import yaml

    path = Path(path)
    try:
        data = yaml.safe_load(path.read_text())
    except yaml.YAMLError as error:
        raise WorldError(f"{path}: not valid YAML: {yaml_problem(error)}") from None
    fields: tuple[tuple[str, ...], ...]
    if isinstance(data, dict) and "corners" in data:
        entries, fields = data["corners"] or [], (("x",), ("y",), ("z",), ("theta",))
        where = "corners"
    elif isinstance(data, dict) and "features" in data:
        entries = data["features"] or []
        fields = (("position", "x"), ("position", "y"), ("position", "z"), ("orientation", "theta"))
        where = "features"
    else:
        raise WorldError(f"{path}: expected a 'corners' (or thesis 'features') list")
    if not isinstance(entries, list):
        raise WorldError(f"{path}: {where}: expected a list, got {type(entries).__name__}")
    rows = [[_corner_number(path, where, i, entry, keys) for keys in fields] for i, entry in enumerate(entries)]
    arr = np.array(rows, dtype=float).reshape(-1, 4)
    return CornerMap(arr[:, :2], arr[:, 2], np.radians(arr[:, 3]))


def _corner_number(path: Path, where: str, index: int, entry: object, keys: tuple[str, ...]) -> float:
    value: object = entry
    for key in keys:
        if not isinstance(value, dict) or key not in value:
            if keys[-1] == "z" and isinstance(value, dict):  # a corner's ceiling height may be left out
                return 0.0
            raise WorldError(f"{path}: {where}[{index}]: missing field {'.'.join(keys)!r}")
        value = value[key]
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value):
        raise WorldError(f"{path}: {where}[{index}].{'.'.join(keys)}: expected a finite number, got {value!r}")
    return float(value)
