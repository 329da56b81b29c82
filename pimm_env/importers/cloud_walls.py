"""The walls of a point-cloud map (cloud_map.py): upright planes fitted across the plan to the wall voxels'
points that reach the ceiling (a cabinet as high as a wall's judged part stops short of it), cut at doorways, each
stood as a box behind the surface the LiDAR saw, and their ends mended (cloud_wall_ends.py)."""

from __future__ import annotations

from typing import Any

import numpy as np

from pimm_env.importers.cloud_wall_ends import bridged, meet


def wall_planes(
    centres: np.ndarray, tops: np.ndarray, floors: tuple[set, set], config: Any, upper: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Upright planes fitted one after another (RANSAC of lines across the floor plan, seeded) to the wall
    voxels' points (``centres``: each voxel's mean point, K x 3), each cut into pieces at gaps wider than
    ``door_gap_m`` (two pieces in line across a narrower gap are closed, :func:`bridged`): the walls, (W, 7) as
    ``CloudMap.walls``, each up to the ceiling over it (its columns' ``tops``) and standing behind its surface:
    between its two faces where the plane holds both (a thin wall seen from both rooms, :func:`_two_faces`),
    towards its other face (a thicker one), else away from the floor in front of it (``floors``: the voxel
    columns of the floor seen and of the open floor, :func:`_behind`); and which centres lie on one. Planes
    within ``SQUARE_DEG`` of the first (the longest wall) are fitted square to it where that holds as many
    points, overall or along the wall (:func:`_squared`). ``upper`` marks centres of a wall seen only near the
    ceiling (over a tall cabinet): a piece needs ``min_wall_m`` of the others, and where only these stand its box
    starts at their foot (:func:`_runs`). ``config``: cloud_map.CloudMapConfig."""
    rng = np.random.default_rng(0)
    walls: list[list[float]] = []
    on_plane = np.zeros(len(centres), dtype=bool)
    remaining = np.arange(len(centres))
    tops = np.asarray(tops, dtype=float)
    square = None  # the building's square: the direction of its longest wall, the first plane found
    reaches = _up_to_ceiling(centres, tops, config)
    upper = np.zeros(len(centres), dtype=bool) if upper is None else np.asarray(upper, dtype=bool)
    while len(remaining) >= 20:
        inliers, normal = _ransac_line(centres[remaining, :2], config.wall_plane_m, rng)
        if square is None:
            square = float(np.arctan2(normal[1], normal[0]))
        inliers, normal = _squared(centres[remaining, :2], inliers, normal, square, config)
        inliers = remaining[inliers]
        if len(inliers) < 20:
            break
        normal = np.array([normal[0], normal[1], 0.0])
        along = np.array([-normal[1], normal[0]]) / np.hypot(normal[0], normal[1])
        points = centres[inliers]
        s = points[:, :2] @ along
        for piece in _pieces(s, config.door_gap_m):
            lo, hi = float(s[piece].min()), float(s[piece].max())
            if _filled(s[piece][~upper[inliers[piece]]], config.voxel_m) < config.min_wall_m - 1e-9:
                continue  # a pillar's side (or a plane through its two sides), a shelf's end
            if reaches[inliers[piece]].mean() < 0.5:
                continue  # furniture as high as a wall but short of the ceiling
            n2 = normal[:2] / np.hypot(normal[0], normal[1])
            depths = points[piece, :2] @ n2
            offset = float(np.median(depths))
            # the body is between the two faces the plane holds (a thin wall seen from both rooms), else towards
            # its other face beyond the plane's band, else away from the floor seen in front of it
            faces = _two_faces(depths, s[piece], config.voxel_m)
            if faces:
                offset, side, depth = faces[0], 1, faces[1] - faces[0]
            else:
                others = np.ones(len(centres), dtype=bool)
                others[inliers[piece]] = False
                others &= reaches & ~upper  # a cabinet standing behind a wall is not its other face, nor a wall's top
                side, depth = _other_face(offset, n2, along, lo, hi, centres[others, :2], config.voxel_m)
            thickness = max(config.voxel_m, depth)
            if side == 0:
                side = _behind((offset * n2 + lo * along, offset * n2 + hi * along), n2, floors, config.voxel_m)
                thickness = ONE_FACED_M if side else config.voxel_m
            offset += side * thickness / 2
            top = float(tops[inliers[piece]].max())
            for start, end, bottom in _runs(s[piece], points[piece, 2], upper[inliers[piece]], config.voxel_m):
                a, b = offset * n2 + start * along, offset * n2 + end * along
                walls.append([a[0], a[1], b[0], b[1], thickness, bottom, top])
            on_plane[inliers[piece]] = True
        remaining = np.setdiff1d(remaining, inliers)
    walls_in_line = bridged(np.array(walls).reshape(-1, 7), config.door_gap_m, config.wall_plane_m)
    return meet(walls_in_line, config.corner_reach_m, floors[0], config.voxel_m), on_plane


def near_the_ceiling(voxels: np.ndarray, clutter: np.ndarray, floor: set, tops: np.ndarray, config: Any) -> np.ndarray:
    """Which ``clutter`` voxels (``tops``: their columns' highest voxel's height) stand in an unbroken stack of two
    or more from right under the ceiling band down to no lower than ``wall_from_m``, over no ``floor`` the map saw
    (its voxel columns) within a voxel: where they lie on a wall's plane, the wall's top seen over a cabinet that
    hides its foot (a beam, a lintel or a ceiling's step stands over floor the LiDAR saw under it)."""
    v = config.voxel_m
    z = (voxels[:, 2] + 0.5) * v
    idx = np.flatnonzero(clutter & (z >= config.wall_from_m) & (tops >= config.ceiling_min_m))
    order = idx[np.lexsort((-voxels[idx, 2], voxels[idx, 1], voxels[idx, 0]))]  # column by column, top first
    column, height = voxels[order, :2], voxels[order, 2]
    new = np.r_[True, np.any(column[1:] != column[:-1], axis=1)]
    first = np.maximum.accumulate(np.where(new, np.arange(len(order)), 0))
    stacked = height == height[first] - (np.arange(len(order)) - first)  # unbroken from the column's top one
    band = np.round(tops[order] / v - 0.5) - round(config.ceiling_band_m / v)  # the band's lowest voxel
    group = np.cumsum(new) - 1
    size = np.bincount(group, weights=stacked)[group]
    out = np.zeros(len(voxels), dtype=bool)
    out[order[stacked & (height[first] >= band - 1) & (size >= 2)]] = True
    near = [(dx, dy) for dx in (-1, 0, 1) for dy in (-1, 0, 1)]
    over = np.array([any((int(x) + dx, int(y) + dy) in floor for dx, dy in near) for x, y in voxels[out, :2]], bool)
    out[np.flatnonzero(out)[over]] = False
    return out


def _runs(s: np.ndarray, z: np.ndarray, upper: np.ndarray, v: float) -> list[tuple[float, float, float]]:
    """A wall piece's stretches (from and to along it, foot): a voxel ``v`` along it stands from the floor where
    any of its points (places ``s`` along it, heights ``z``) is not ``upper``, else from the lowest of them; a
    voxel without points goes with the one before."""
    lo, hi = float(s.min()), float(s.max())
    cell = np.floor((s - lo) / v).astype(int)
    foot = np.full(cell.max() + 1, np.inf)
    np.minimum.at(foot, cell, np.where(upper, np.floor(z / v) * v, 0.0))
    runs: list[list[float]] = []
    for k, bottom in enumerate(foot):
        if runs and (np.isinf(bottom) or (bottom > 0) == (runs[-1][2] > 0)):
            runs[-1][1] = lo + (k + 1) * v
            runs[-1][2] = min(runs[-1][2], bottom)
        else:
            runs.append([lo + k * v, lo + (k + 1) * v, float(bottom)])
    runs[0][0], runs[-1][1] = lo - v / 2, hi + v / 2
    return [(start, end, bottom) for start, end, bottom in runs]


def _filled(s: np.ndarray, v: float) -> float:
    """How far a plane's points (at ``s`` along it) fill it, in voxels of ``v`` from the first: a wall's length
    where it was seen, not the span between a round pillar's two sides."""
    return len(np.unique((s - s.min()) // v)) * v if len(s) else 0.0


def _up_to_ceiling(centres: np.ndarray, tops: np.ndarray, config: Any) -> np.ndarray:
    """Which wall voxels (their mean points ``centres``, their columns' ``tops``) stand in a column whose wall
    voxels come within half ``wall_gap_m`` of the ceiling band over it: a wall holds its ceiling up (the LiDAR's
    rings on a far wall end half a gap below it on average), a tall cabinet stops short."""
    v = config.voxel_m
    column, inverse = np.unique(np.floor(centres[:, :2] / v).astype(np.int64), axis=0, return_inverse=True)
    inverse = inverse.reshape(-1)
    highest = np.full(len(column), -np.inf)
    np.maximum.at(highest, inverse, (np.floor(centres[:, 2] / v) + 0.5) * v)
    below = tops - v / 2 - config.ceiling_band_m - highest[inverse] - v  # 0: the wall's top voxel meets the band
    return below <= config.wall_gap_m / 2 + 1e-9


def _ransac_line(xy: np.ndarray, within: float, rng: np.random.Generator, draws: int = 300) -> tuple:
    """The line through two of ``xy`` (K, 2) that the most points lie within ``within`` of (scored on at most
    3000 of them, drawn from ``rng``), refitted to its inliers by least squares: (inlier indices, unit normal)."""
    sample = xy if len(xy) <= 3000 else xy[rng.choice(len(xy), 3000, replace=False)]
    pairs = rng.integers(len(sample), size=(draws, 2))
    direction = sample[pairs[:, 1]] - sample[pairs[:, 0]]
    length = np.hypot(direction[:, 0], direction[:, 1])
    ok = length > 1e-6
    normals = np.column_stack([-direction[ok, 1], direction[ok, 0]]) / length[ok, None]
    if not len(normals):
        return np.zeros(0, dtype=int), np.array([1.0, 0.0])
    offsets = np.einsum("ij,ij->i", normals, sample[pairs[ok, 0]])
    counts = (np.abs(sample @ normals.T - offsets) < within).sum(axis=0)
    best = int(np.argmax(counts))
    normal, offset = normals[best], offsets[best]
    for _ in range(2):  # refit: the inliers' principal direction
        inliers = np.flatnonzero(np.abs(xy @ normal - offset) < within)
        if len(inliers) < 2:
            break
        centre = xy[inliers].mean(axis=0)
        normal = np.linalg.svd(xy[inliers] - centre, full_matrices=False)[2][1]
        offset = float(centre @ normal)
    return np.flatnonzero(np.abs(xy @ normal - offset) < within), normal


#: a wall plane this near (deg) to the building's own square is tried square to it
SQUARE_DEG = 10.0


def _squared(xy: np.ndarray, inliers: np.ndarray, normal: np.ndarray, square: float, config: Any) -> tuple:
    """The plane (``inliers`` of ``xy``, unit ``normal``) turned square to the building (``square``: a wall's
    normal, rad) where it lies within ``SQUARE_DEG`` of it and holds at least as many points so (a thin wall's
    two faces, fitted on a slant across both, are one plane square to the building), or as many along its
    longest piece, a wall's length at least (a line slanted by a few degrees gathers two walls in line across
    the building, a room's partition and the one across the corridor), else as it is. ``config``:
    cloud_map.CloudMapConfig."""
    angle = np.arctan2(normal[1], normal[0])
    turn = (angle - square + np.pi / 4) % (np.pi / 2) - np.pi / 4
    if abs(turn) > np.radians(SQUARE_DEG) or not len(inliers):
        return inliers, normal
    within = config.wall_plane_m
    snapped = np.array([np.cos(angle - turn), np.sin(angle - turn)])
    depth = xy @ snapped
    # the band (``within`` either side) near the inliers' median that holds the most points: a thin wall's two
    # faces both, where a median would slide to the face seen more
    near = np.sort(depth[np.abs(depth - np.median(depth[inliers])) < 2 * within])
    if not len(near):  # an even count's median between two faces further apart than the band: none to centre on
        return inliers, normal
    ends = np.searchsorted(near, near + 2 * within, side="right")
    best = int(np.argmax(ends - np.arange(len(near))))
    kept = np.flatnonzero(np.abs(depth - (near[best] + near[ends[best] - 1]) / 2) < within)
    if len(kept) >= len(inliers):
        return kept, snapped
    along = xy @ np.array([-snapped[1], snapped[0]])
    on_it = along[kept]
    longest = on_it[max(_pieces(on_it, config.door_gap_m), key=lambda piece: np.ptp(on_it[piece]))]
    lo, hi = float(longest.min()), float(longest.max())
    local = [np.count_nonzero((along[ids] >= lo) & (along[ids] <= hi)) for ids in (kept, inliers)]
    return (kept, snapped) if hi - lo >= config.min_wall_m and local[0] >= local[1] else (inliers, normal)


def _pieces(s: np.ndarray, gap: float) -> list[np.ndarray]:
    """The points of a plane (at ``s`` along it) in pieces cut at gaps wider than ``gap`` (a doorway): each an
    index array into ``s``, in order along it."""
    order = np.argsort(s)
    return np.split(order, np.flatnonzero(np.diff(s[order]) > gap) + 1)


def _behind(face: tuple[np.ndarray, np.ndarray], normal: np.ndarray, floors: tuple[set, set], voxel_m: float) -> int:
    """+1 or -1: the side of a wall face (from ``face[0]`` to ``face[1]``, facing along ``normal``) where its body
    stands: away from the floor seen right at its foot (``floors[0]``, voxel columns: the LiDAR saw that side),
    else away from the open floor a little further out (``floors[1]``); 0 when neither tells."""
    for floor, reach in zip(floors, (0.15, 0.25), strict=True):
        counts = []
        for side in (1, -1):
            probes = [face[0] + t * (face[1] - face[0]) + side * reach * normal for t in np.linspace(0.1, 0.9, 5)]
            counts.append(sum((int(x), int(y)) in floor for x, y in np.floor(np.array(probes) / voxel_m)))
        if counts[0] != counts[1]:
            return 1 if counts[1] > counts[0] else -1
    return 0


#: the body of a wall seen from one side only (m): a common interior wall (its back is not in the map), and
#: thick enough that the corners of its back lie beyond the ceiling, which stops at the walls' faces
ONE_FACED_M = 0.15
#: how far behind a wall's face its other face is looked for (m): a thinner wall's two faces lie in one plane's
#: band (``wall_plane_m`` either side); the thickest interior wall
OTHER_FACE_M = (0.15, 0.4)


#: the least gap between the two faces of a thin wall in one plane's band (m): well under the 0.1 m of the
#: thinnest wall, while one face's own scatter (a few centimetres of pose and range error) splits into halves
#: nearer than this
TWO_FACES_M = 0.06


def _two_faces(depth: np.ndarray, s: np.ndarray, v: float) -> tuple[float, float] | None:
    """The two faces (their depths, the lesser first) where the points of one plane (``depth`` across it, ``s``
    along it) are a thin wall's two faces: split where each side is tightest (Otsu's threshold), the halves'
    medians at least ``TWO_FACES_M`` apart and both seen along the same third of the wall (in voxels of ``v``),
    so that neither a jog in a wall nor a pillar standing out of it is taken for its thickness. None when the
    plane holds one face."""
    if len(depth) < 6:
        return None
    order = np.argsort(depth)
    d, n = depth[order], len(depth)
    k = np.arange(1, n)
    split = int(np.argmax(k * (n - k) * (np.cumsum(d)[:-1] / k - (d.sum() - np.cumsum(d)[:-1]) / (n - k)) ** 2)) + 1
    halves = order[:split], order[split:]
    near, far = (float(np.median(depth[half])) for half in halves)
    bins = [set(np.floor(s[half] / v).astype(int).tolist()) for half in halves]
    if far - near < TWO_FACES_M or not _along_a_third(len(bins[0] & bins[1]), float(s.max() - s.min()), v):
        return None
    return near, far


def _along_a_third(voxels: int, length_m: float, v: float) -> bool:
    """Whether ``voxels`` (of ``v``) along a wall ``length_m`` long are a third of it, and 3 at least: a face seen
    along the wall, not a wall across it or a pillar beside it."""
    return voxels >= max(3, length_m / v / 3)


def _other_face(offset: float, normal: np.ndarray, along: np.ndarray, lo: float, hi: float, xy: np.ndarray, v: float):
    """+1 or -1: the side of a wall face (its line at ``offset`` along ``normal``, from ``lo`` to ``hi`` along
    ``along``) where other wall voxels' points (``xy``) lie parallel to it, within ``OTHER_FACE_M`` and a voxel
    (``v``) of one depth, along a third of the face's length and 0.3 m at least: its other face, seen from the
    other room, with fewer points between the two (the wall's body) than on it; and how far it is (m, their
    median). 0, 0.0 when neither side; the nearer when both."""
    depth = xy @ normal - offset
    s = xy @ along
    inside = (s > lo + v) & (s < hi - v)  # not at its ends, where the walls it meets stand
    for probe in np.arange(OTHER_FACE_M[0], OTHER_FACE_M[1] + 1e-9, v / 4):
        for side in (1, -1):
            band = inside & (np.abs(side * depth - probe) < v / 2)
            count = np.count_nonzero(band)
            # the wall's body between its faces is empty: a face's own scatter thins out, it does not come back
            body = np.count_nonzero(inside & (side * depth > v / 2) & (side * depth < probe - v / 2))
            along_it = len(np.unique(np.floor(s[band] / v)))  # walls across it fill a voxel or two each
            if body < count / 2 and _along_a_third(along_it, hi - lo, v):
                return side, float(np.median(side * depth[band]))
    return 0, 0.0


def in_walls(xy: np.ndarray, walls: np.ndarray) -> np.ndarray:
    """Which points ``xy`` (K, 2) lie in the plan of one of ``walls`` (as ``CloudMap.walls``)."""
    inside = np.zeros(len(xy), dtype=bool)
    for x0, y0, x1, y1, thickness, _, _ in walls:
        line = np.array([x1 - x0, y1 - y0])
        length = float(np.hypot(*line))
        if length < 1e-9:
            continue
        along = (xy - [x0, y0]) @ line / length
        across = (xy - [x0, y0]) @ np.array([-line[1], line[0]]) / length
        inside |= (along >= 0.0) & (along <= length) & (np.abs(across) < thickness / 2)
    return inside


def wall_elements(walls: np.ndarray) -> list[dict[str, Any]]:
    """The walls (W, 7: line, thickness, bottom, top) as world elements ``wall_1``, ...: boxes along their lines,
    so that the corner map reads their outlines (corner_map.py), not a raster of their slant."""
    elements = []
    for k, (x0, y0, x1, y1, thickness, bottom, top) in enumerate(walls):
        centre = [round((x0 + x1) / 2, 4), round((y0 + y1) / 2, 4), round((bottom + top) / 2, 4)]
        size = [round(float(np.hypot(x1 - x0, y1 - y0)), 4), round(thickness, 4), round(top - bottom, 4)]
        box = {"center": centre, "size": size, "yaw": round(float(np.arctan2(y1 - y0, x1 - x0)), 6)}
        elements.append({"name": f"wall_{k + 1}", "class": "wall", "box": box})
    return elements
