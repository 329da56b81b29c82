"""A building from the point-cloud map a robot's SLAM writes (FAST-LIO, LIO-SAM, GLIM, KISS-ICP save a ``.pcd``;
surveys give ``.las``; ``.ply`` and ``.npy`` too): one floor's cloud as a triangle mesh PIMM and the simulator use.

1. **Level** it on its floor: the lowest large level surface (points whose normal stands within 18 degrees of
   z, binned by height) fitted as a plane; the cloud is turned by that plane's tilt and moved so the floor lies
   at z = 0 (x and y stay the map's, so poses in the SLAM map frame stay valid). A second large level surface
   more than ``storey_m`` above the floor with the map going on a metre over it (over the surface itself) is
   another storey's floor: the map is refused, naming the heights. A ceiling has nothing over it, however high,
   and beside a higher one.
2. **Voxels** of ``voxel_m``: a voxel with fewer than ``min_points`` points (people who walked through while
   mapping, stray returns) and a voxel with no occupied neighbour (outliers) are set aside and counted.
3. **Classes per column** of voxels (``cloud_columns.py``): floor near the floor, ceiling at each column's top (a
   real ceiling is not flat), wall where a column's voxels stand stacked from above the furniture up to its
   ceiling or to a lower one beside it that it holds up, clutter the rest. Ceiling gaps
   of up to three columns between seen ceiling (a LiDAR's rings leave stripes) are filled in. Clutter rising
   from the floor to no more than a person's height over floor the map saw under it is the ghost of someone who
   walked by while mapping (a thing standing there hides its floor), and so are their arms beside it
   (``cloud_ghosts.py``): set aside and counted. Given the trajectory the map was made along, clutter up to a
   person's height where the robot drove is set aside too (``cloud_path.py``).
4. **Surfaces**: walls are upright planes fitted to the wall voxels (``cloud_walls.py``), each a box element of
   the world standing behind the surface the LiDAR saw (so the corner map reads the walls' outlines, at the
   slant they were fitted at, not a raster of it), and where the map saw them (``seen_walls``: the mean point of
   each voxel on a wall plane; the corner map keeps only corners with a face seen); the ceiling is a downward face
   at each column's top up to the walls' faces, smoothed over 5 x 5 columns; floor and clutter are the faces of
   their voxels that border empty space. One mesh per other class (``floor``, ``ceiling``, ``clutter``), one GLB
   the mesh import reads.
5. **Where the robot can be**: the outline of the floor seen and of the floor hidden under a seen ceiling with
   nothing standing there (the far corners of a room seen through its doorway), as the world's areas.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from pimm_env.errors import MapFileError
from pimm_env.geometry import rotation_onto_z
from pimm_env.importers.cloud_columns import CEILING, CLASSES, CLUTTER, FLOOR, WALL, column_classes
from pimm_env.importers.cloud_ghosts import ghost_voxels
from pimm_env.importers.cloud_path import on_path
from pimm_env.importers.cloud_walls import in_walls, near_the_ceiling, wall_planes


@dataclass(frozen=True)
class CloudMapConfig:
    """How a point-cloud map becomes a building (ours; docs/worlds.md#your-building-from-a-point-cloud-map)."""

    voxel_m: float = 0.1  # the surface's cell; a map's own noise is a few centimetres
    min_points: int = 2  # points a voxel needs to be a surface (fewer: passers-by, strays)
    floor_band_m: float = 0.15  # above the floor plane: floor
    ceiling_min_m: float = 1.8  # a column rising this high ends in a ceiling
    ceiling_band_m: float = 0.2  # below a column's top: ceiling
    wall_from_m: float = 1.2  # a wall column is judged from this height up (furniture hides its foot)
    wall_min_span_m: float = 0.6  # ... over at least this much (so to 2 m or more: above cabinets and people)
    wall_gap_m: float = 0.4  # ... with gaps no wider than this (a far wall is seen as the LiDAR's rings)
    wall_plane_m: float = 0.08  # a wall voxel within this of a wall plane belongs to it
    door_gap_m: float = 0.6  # a wall plane's voxels further apart along it than this are two walls (a doorway)
    min_wall_m: float = 0.6  # pieces of a wall plane filling less along it are not walls (a pillar, a shelf's end)
    corner_reach_m: float = 0.4  # two walls whose ends come this near their meeting line meet there
    person_m: float = 2.0  # clutter rising from the floor to no more than this, over seen floor, is a ghost ...
    ghost_floor: float = 0.75  # ... when the floor under its column was seen over this share of it
    storey_m: float = 2.0  # a level surface higher above the floor, with the map going on over it, is a storey
    over_storey: float = 0.2  # ... with this many points a metre over it, for each point on it
    min_area_m2: float = 2.0  # smaller patches of seen floor are not places the robot can be


@dataclass
class CloudMap:
    """A levelled, classified cloud map: its voxels, their classes, and what was set aside."""

    voxels: np.ndarray  # (V, 3) int voxel indices, levelled frame (floor at z = 0)
    classes: np.ndarray  # (V,) index into CLASSES
    voxel_m: float
    tilt_deg: float  # the floor plane's tilt the cloud was turned by
    floor_z: float  # the floor's height in the map's frame, before levelling
    points: int  # points read
    set_aside: dict[str, int] = field(default_factory=dict)  # voxels, by why
    #: the walls fitted to the wall voxels: (W, 7) x0, y0, x1, y1 of the wall's line, its thickness, bottom, top
    walls: np.ndarray = field(default_factory=lambda: np.zeros((0, 7)))
    #: (S, 2) where the map saw the walls: the mean point, in the plane, of each voxel on a wall plane
    seen_walls: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))

    def counts(self) -> dict[str, int]:
        return {name: int(np.count_nonzero(self.classes == k)) for k, name in enumerate(CLASSES)}


def level_frame(
    points: np.ndarray, config: CloudMapConfig, source: Path | str
) -> tuple[np.ndarray, float, float, np.ndarray]:
    """``points`` turned and moved so that the floor plane is z = 0 (see the module's text); the tilt (deg), the
    floor's height in the given frame and the turn (3, 3; a point p levels to ``turn @ p - (0, 0, floor)``)."""
    import open3d as o3d

    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points)).voxel_down_sample(config.voxel_m)
    cloud.estimate_normals(o3d.geometry.KDTreeSearchParamKNN(16))
    thin, normals = np.asarray(cloud.points), np.asarray(cloud.normals)
    level = thin[np.abs(normals[:, 2]) > np.cos(np.radians(18.0))]
    if len(level) < 100:
        raise MapFileError(
            f"{source}: no level surface in the map ({len(level)} level points): is it a building's floor with z up?"
        )
    bins = np.arange(level[:, 2].min(), level[:, 2].max() + 0.1, 0.1)
    counts, edges = np.histogram(level[:, 2], bins=bins) if len(bins) > 1 else (np.array([len(level)]), bins)
    strong = np.flatnonzero(counts >= 0.2 * counts.max())
    floor_at = float(edges[strong[0]] + 0.05) if len(bins) > 1 else float(np.median(level[:, 2]))
    storeys = [
        float(edges[k] + 0.05)
        for k in strong
        if edges[k] + 0.05 - floor_at > config.storey_m and _built_over(level, thin, edges[k], config.over_storey)
    ]
    if storeys:
        heights = ", ".join(f"{h:.2f}" for h in [floor_at, *storeys])
        raise MapFileError(
            f"{source}: the map holds more than one storey (large level surfaces at z = {heights} m); crop it to"
            " one floor (its floor to its ceiling) and import that"
        )
    near = level[np.abs(level[:, 2] - floor_at) < 0.2]
    normal = np.array([0.0, 0.0, 1.0])
    if len(near) >= 3:  # the floor plane by least squares, twice, the second time without the points 3 cm off
        for _ in range(2):
            centre = near.mean(axis=0)
            normal = np.linalg.svd(near - centre, full_matrices=False)[2][2]
            normal = normal * np.sign(normal[2] or 1.0)
            kept = np.abs((near - centre) @ normal) < 0.03
            near = near[kept] if kept.sum() >= 3 else near
    turn = rotation_onto_z(normal)
    levelled = np.asarray(points, dtype=float) @ turn.T
    floor_z = float(np.median((near @ turn.T)[:, 2])) if len(near) else floor_at
    levelled[:, 2] -= floor_z
    return levelled, float(np.degrees(np.arccos(np.clip(normal[2], -1.0, 1.0)))), floor_z, turn


def _built_over(level: np.ndarray, thin: np.ndarray, height: float, share: float) -> bool:
    """Whether the map goes on a metre over the level surface at ``height`` (its 10 cm bin of ``level`` points),
    over that surface itself (0.5 m cells, those at its edge left out): more than ``share`` as many points as it
    holds there. A storey's floor has its walls and ceiling over it; a ceiling, seen from below, has nothing (a
    hall's higher ceiling and the wall up to it are beside it, in its edge cells at most)."""
    on = level[(level[:, 2] >= height) & (level[:, 2] < height + 0.1)]
    at = [(int(x), int(y)) for x, y in np.floor(on[:, :2] / 0.5)]
    cells = set(at)
    inner = {(x, y) for x, y in cells if all((x + a, y + b) in cells for a in (-1, 0, 1) for b in (-1, 0, 1))}
    above = thin[thin[:, 2] > height + 1.05]
    over = sum((int(x), int(y)) in inner for x, y in np.floor(above[:, :2] / 0.5))
    return over > share * sum(c in inner for c in at)


def classify(
    points: np.ndarray,
    config: CloudMapConfig = CloudMapConfig(),
    source: Path | str = "cloud",
    path: np.ndarray | None = None,
    path_source: Path | str = "trajectory",
) -> CloudMap:
    """The cloud map of ``points`` (N, 3, any frame with z up): levelled, voxelized, classified. ``path``: the
    positions (M, 3, the points' frame) the map was made along, read from ``path_source`` (cloud_path.py)."""
    levelled, tilt, floor_z, turn = level_frame(points, config, source)
    index = np.floor(levelled / config.voxel_m).astype(np.int64)
    voxels, inverse, hits = np.unique(index, axis=0, return_inverse=True, return_counts=True)
    inverse = inverse.reshape(-1)
    means = np.column_stack([np.bincount(inverse, levelled[:, k]) for k in range(3)]) / hits[:, None]
    set_aside = {"sparse voxels": int(np.count_nonzero(hits < config.min_points))}
    voxels, means = voxels[hits >= config.min_points], means[hits >= config.min_points]
    below = voxels[:, 2] < -round(config.floor_band_m / config.voxel_m) - 1
    set_aside["below the floor"] = int(np.count_nonzero(below))
    voxels, means = voxels[~below], means[~below]
    lonely = ~_has_neighbour(voxels)
    set_aside["outliers"] = int(np.count_nonzero(lonely))
    voxels, means = voxels[~lonely], means[~lonely]
    if not len(voxels):
        raise MapFileError(f"{source}: no surface left in the map after setting aside {set_aside}")
    classes, tops = column_classes(voxels, config)
    ghosts = ghost_voxels(voxels, classes == CLUTTER, levelled, config)
    set_aside["ghosts (clutter over seen floor, as high as a person: people who walked by while mapping)"] = int(
        np.count_nonzero(ghosts)
    )
    voxels, classes, means, tops = voxels[~ghosts], classes[~ghosts], means[~ghosts], tops[~ghosts]
    if path is not None:
        cleared = on_path(voxels, classes == CLUTTER, np.asarray(path) @ turn.T - [0, 0, floor_z], config, path_source)
        set_aside["clutter where the trajectory drove (ghosts the floor rule missed)"] = int(np.count_nonzero(cleared))
        voxels, classes, means, tops = voxels[~cleared], classes[~cleared], means[~cleared], tops[~cleared]
    seen = {(int(x), int(y)) for x, y in voxels[classes == FLOOR, :2]}  # the floor's columns
    upper = near_the_ceiling(voxels, classes == CLUTTER, seen, tops, config)  # walls' tops seen over cabinets
    filled = _closed_ceiling(voxels, classes)
    set_aside["ceiling voxels filled in (gaps between seen ceiling)"] = len(filled)
    voxels, classes = np.vstack([voxels, filled]), np.concatenate([classes, np.full(len(filled), CEILING, np.int8)])
    upper = np.concatenate([upper, np.zeros(len(filled), dtype=bool)])
    wall = np.flatnonzero((classes == WALL) | upper)
    plan, lo = _open_floor(voxels, classes)
    open_floor = {(int(x + lo[0]), int(y + lo[1])) for y, x in zip(*np.nonzero(plan), strict=True)}
    walls, on_plane = wall_planes(means[wall], tops[wall] + config.voxel_m / 2, (seen, open_floor), config, upper[wall])
    loose = wall[~on_plane & ~upper[wall]]
    classes[loose] = CLUTTER  # upright structure on no wall plane: a cabinet's side, a pillar
    classes[wall[on_plane]] = WALL
    set_aside["wall voxels on no wall plane (taken as clutter)"] = len(loose)
    seen_walls = means[wall[on_plane], :2]
    return CloudMap(voxels, classes, config.voxel_m, tilt, floor_z, len(points), set_aside, walls, seen_walls)


def _closed_ceiling(voxels: np.ndarray, classes: np.ndarray, gap: int = 3) -> np.ndarray:
    """Ceiling voxels for the columns in gaps of up to ``gap`` voxels between seen ceiling (a LiDAR's rings leave
    stripes of unseen ceiling), each at the height of the nearest seen one: (K, 3) voxel indices."""
    from scipy import ndimage

    ceiling = voxels[classes == CEILING]
    if not len(ceiling):
        return np.zeros((0, 3), dtype=np.int64)
    lo, height, seen = _column_tops(ceiling, gap)
    closed = ndimage.binary_closing(seen, structure=np.ones((3, 3)), iterations=gap) & ~seen
    _, (ix, iy) = ndimage.distance_transform_edt(~seen, return_indices=True)
    cx, cy = np.nonzero(closed)
    return np.column_stack([cx + lo[0], cy + lo[1], height[ix[cx, cy], iy[cx, cy]]]).astype(np.int64)


def _column_tops(voxels: np.ndarray, pad: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The voxels' columns as a grid with ``pad`` empty columns around: its lowest (x, y) index, each column's top
    voxel index, and which columns hold a voxel."""
    lo = voxels[:, :2].min(axis=0) - pad
    shape = tuple(voxels[:, :2].max(axis=0) - lo + pad + 1)
    top = np.full(shape, np.iinfo(np.int64).min)
    np.maximum.at(top, (voxels[:, 0] - lo[0], voxels[:, 1] - lo[1]), voxels[:, 2])
    return lo, top, top > np.iinfo(np.int64).min


def _keys(voxels: np.ndarray) -> np.ndarray:
    v = voxels + (1 << 20)
    return (v[:, 0] << 42) | (v[:, 1] << 21) | v[:, 2]


def _has_neighbour(voxels: np.ndarray) -> np.ndarray:
    keys = np.sort(_keys(voxels))
    found = np.zeros(len(voxels), dtype=bool)
    for dx in (-1, 0, 1):
        for dy in (-1, 0, 1):
            for dz in (-1, 0, 1):
                if dx or dy or dz:
                    found |= _member(_keys(voxels + np.array([dx, dy, dz])), keys)
    return found


def _member(keys: np.ndarray, sorted_keys: np.ndarray) -> np.ndarray:
    at = np.clip(np.searchsorted(sorted_keys, keys), 0, len(sorted_keys) - 1)
    return sorted_keys[at] == keys


def surface_meshes(cloud_map: CloudMap) -> dict[str, Any]:
    """One trimesh per class: the faces of its voxels that border empty space, each facing out."""

    v = cloud_map.voxel_m
    keys = np.sort(_keys(cloud_map.voxels))
    corners = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]])
    # each face: the direction it faces and its four corners, counter-clockwise seen from outside
    faces = {
        (1, 0, 0): (1, 2, 6, 5), (-1, 0, 0): (0, 4, 7, 3), (0, 1, 0): (2, 3, 7, 6),
        (0, -1, 0): (0, 1, 5, 4), (0, 0, 1): (4, 5, 6, 7), (0, 0, -1): (0, 3, 2, 1),
    }  # fmt: skip
    meshes = {}
    for k, name in enumerate(CLASSES):
        if k == WALL:  # the walls are the world's boxes (cloud_walls.wall_elements)
            continue
        own = cloud_map.voxels[cloud_map.classes == k]
        if k == CEILING:
            own = own[~in_walls((own[:, :2] + 0.5) * v, cloud_map.walls)]  # the ceiling stops at the walls' faces
            if len(own):
                meshes[name] = _ceiling_underside(own, v)
            continue
        quads = []
        for direction, quad in faces.items():
            open_side = own[~_member(_keys(own + direction), keys)]
            quads.append(open_side[:, None, :] + corners[list(quad)][None, :, :])
        if not sum(len(q) for q in quads):
            continue
        meshes[name] = _quads_mesh(np.concatenate(quads).reshape(-1, 4, 3).astype(float) * v)
    return meshes


def _ceiling_underside(ceiling: np.ndarray, v: float):
    """The ceiling as one downward-facing square per voxel column, at the bottom of the column's top voxel (where
    the ceiling's surface is, to a voxel), the heights smoothed over 5 x 5 columns (a median: a voxel's worth of
    noise is not another ceiling height, a step of several is kept)."""
    from scipy import ndimage

    lo, under, seen = _column_tops(ceiling)
    _, (ix, iy) = ndimage.distance_transform_edt(~seen, return_indices=True)
    smooth = ndimage.median_filter(under[ix, iy], size=5)  # unseen columns take their nearest seen neighbour's
    x, y = np.nonzero(seen)
    z = smooth[x, y] * v
    x, y = (x + lo[0]) * v, (y + lo[1]) * v
    # clockwise seen from above: facing down
    return _quads_mesh(np.stack([np.column_stack([x + a, y + b, z]) for a, b in ((0, 0), (0, v), (v, v), (v, 0))], 1))


def _quads_mesh(quad: np.ndarray):
    """Quads (Q, 4, 3), each counter-clockwise seen from the side it faces, as a triangle mesh."""
    import trimesh

    base = np.arange(len(quad))[:, None] * 4
    triangles = np.concatenate([base + np.array([0, 1, 2]), base + np.array([0, 2, 3])])
    return trimesh.Trimesh(quad.reshape(-1, 3), triangles, process=True)


def floor_areas(
    cloud_map: CloudMap, config: CloudMapConfig, source: Path | str = "cloud"
) -> dict[str, list[list[float]]]:
    """The outlines of the floor's patches of at least ``min_area_m2`` (the floor seen, and hidden under a seen
    ceiling with nothing standing there; small gaps under furniture closed), as named areas ``floor_1``,
    ``floor_2``, ... in metres."""
    from scipy import ndimage

    from pimm_env.importers.vectorize import traced_polygons

    if not np.any(cloud_map.classes == FLOOR):
        raise MapFileError(f"{source}: the map shows no floor under its surfaces: a robot has nowhere to stand")
    mask, lo = _open_floor(cloud_map.voxels, cloud_map.classes)
    plans = [_plan(cloud_map.voxels, cloud_map.classes == c, lo, mask.shape) for c in (WALL, CLUTTER)]
    mask |= _up_to_the_walls(mask, *plans)
    mask = _closed(mask, 3)
    mask = ndimage.binary_fill_holes(mask)
    v = cloud_map.voxel_m
    areas: dict[str, list[list[float]]] = {}
    for outer, _ in traced_polygons(mask, v):
        ring = outer + lo * v
        x, y = ring[:, 0], ring[:, 1]
        if 0.5 * abs(np.dot(x, np.roll(y, 1)) - np.dot(y, np.roll(x, 1))) >= config.min_area_m2:
            areas[f"floor_{len(areas) + 1}"] = np.round(ring, 3).tolist()
    if not areas:
        raise MapFileError(f"{source}: the map's seen floor has no patch of {config.min_area_m2} m² or more")
    return areas


#: the widest strip (voxels) of floor hidden between the open floor and a wall that is taken as floor (a far
#: wall's foot, seen over a desk or through a doorway): twice this, as the closing of the gap goes
WALL_FOOT_VOXELS = 3


def _up_to_the_walls(floor: np.ndarray, wall: np.ndarray, clutter: np.ndarray) -> np.ndarray:
    """The cells of a plan (``floor``, ``wall``, ``clutter``: masks, a voxel column a cell) between the open floor
    and the walls it reaches, with nothing standing there (a strip the LiDAR did not see the floor of, up to
    ``2 * WALL_FOOT_VOXELS`` wide), and the walls' columns there: the free space runs up to the faces of the
    walls the map saw, so that the occupancy shows them as faces a sensor sees (``OccupancyGrid.surfaces``)
    rather than obstacles beside unknown space."""
    from scipy import ndimage

    strip = _closed(floor | wall, WALL_FOOT_VOXELS) & ~wall & ~floor & ~clutter
    return strip | (wall & ndimage.binary_dilation(floor | strip, np.ones((3, 3), dtype=bool)))


def _closed(plan: np.ndarray, steps: int) -> np.ndarray:
    """``plan`` closed by ``steps`` steps (gaps up to twice as wide filled), with nothing beyond its edges."""
    from scipy import ndimage

    return ndimage.binary_closing(np.pad(plan, steps), iterations=steps)[steps:-steps, steps:-steps]


def _plan(voxels: np.ndarray, which: np.ndarray, lo: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    """The voxel columns of ``voxels[which]`` as a plan (rows y, columns x) whose cell (0, 0) is column ``lo``."""
    out = np.zeros(shape, dtype=bool)
    out[voxels[which, 1] - lo[1], voxels[which, 0] - lo[0]] = True
    return out


def _open_floor(voxels: np.ndarray, classes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The plan (rows y, columns x, a voxel a cell) of the floor seen and of where the ceiling was seen over
    nothing standing (floor hidden from the LiDAR: the far corners of rooms seen through their doorways), and the
    voxel column of its cell (0, 0)."""
    from scipy import ndimage

    lo, hi = voxels[:, :2].min(axis=0), voxels[:, :2].max(axis=0)
    shape = tuple(hi - lo + 1)[::-1]
    standing = ndimage.binary_dilation(_plan(voxels, (classes == WALL) | (classes == CLUTTER), lo, shape))
    return _plan(voxels, classes == FLOOR, lo, shape) | (_plan(voxels, classes == CEILING, lo, shape) & ~standing), lo


def write_cloud_world_mesh(cloud_map: CloudMap, path: Path) -> Path:
    """The class meshes as one GLB whose objects are named by class (the mesh import's name rules read them)."""
    import trimesh

    scene = trimesh.Scene()
    for name, mesh in surface_meshes(cloud_map).items():
        scene.add_geometry(mesh, node_name=name, geom_name=name)
    scene.export(path)
    return path
