"""The ends of a point-cloud map's walls (cloud_walls.py fits them): one wall fitted as two planes closed across
the stretch a cabinet hid, and two walls met where furniture hides the corner or the T where they join. Walls are
rows of ``CloudMap.walls``: x0, y0, x1, y1 of the wall's line, its thickness, bottom, top."""

from __future__ import annotations

import numpy as np

from pimm_env.mapping.corner_map import SEEN_ALONG_M


def bridged(walls: np.ndarray, gap: float, within: float) -> np.ndarray:
    """``walls`` with each two in line (each one's end within ``within`` of the other's line) whose ends face each
    other across less than ``gap`` (not a doorway) carried to the middle of it: one wall fitted as two planes a
    centimetre or two apart (a SLAM map's drift), its stretch behind a cabinet not seen."""
    walls = walls.copy()
    for i in range(len(walls)):
        for j in range(len(walls)):
            a0, a1 = walls[i, 0:2], walls[i, 2:4]  # read again for each j: an earlier j may have moved a1
            length = float(np.hypot(*(a1 - a0)))
            if i == j or length < 1e-9:
                continue
            along = (a1 - a0) / length
            near = int(np.argmin([(walls[j, 0:2] - a1) @ along, (walls[j, 2:4] - a1) @ along]))  # j's end facing a1
            b0, b1 = walls[j, 2 * near : 2 * near + 2], walls[j, 2 - 2 * near : 4 - 2 * near]
            ahead = float((b0 - a1) @ along)  # the gap, i running on towards j, j on away from i
            if not 0.0 < ahead < gap or (b1 - b0) @ along <= 0.0:
                continue
            line = (b1 - b0) / np.hypot(*(b1 - b0))
            if abs(_across(along, b0 - a0)) < within and abs(_across(line, a1 - b0)) < within:
                middle = (a1 + b0) / 2
                walls[i, 2:4] = a0 + ((middle - a0) @ along) * along
                walls[j, 2 * near : 2 * near + 2] = b1 + ((middle - b1) @ line) * line
    return walls


def _across(direction: np.ndarray, offset: np.ndarray) -> float:
    """The plane's cross product of ``direction`` and ``offset`` (2,): with a unit ``direction``, how far ``offset``
    lies to its left."""
    return float(direction[0] * offset[1] - direction[1] * offset[0])


#: the least turn between two walls that meet at a corner or a T: sin 45 degrees
TURN = float(np.sin(np.radians(45.0)))


def meet(walls: np.ndarray, reach: float, floor: set | frozenset = frozenset(), voxel_m: float = 0.1) -> np.ndarray:
    """``walls`` with the ends of each two that turn by 45 degrees or more moved onto their meeting point where
    both stop within ``reach`` of it (short of it: of the other's face, the stretch left unseen; past it: of the
    other's middle line), or both short of it by no more than ``SEEN_ALONG_M`` with no ``floor`` seen between
    (its voxel columns of ``voxel_m``): furniture standing in a room's corner hides where its walls meet, while a
    doorway beside a corner shows the floor through it; and the end of one that stops within ``reach`` of another
    running past it (a T: a partition's last metre is seen at a grazing angle, in voxels too sparse to keep). A
    moved end runs on past the meeting point by half the other wall's thickness, to its far face, so that the two
    boxes' outline turns once on each side."""
    walls = walls.copy()
    for i in range(len(walls)):
        for j in range(i + 1, len(walls)):
            a0, a1, b0, b1 = walls[i, 0:2], walls[i, 2:4], walls[j, 0:2], walls[j, 2:4]
            da, db = a1 - a0, b1 - b0
            cross = _across(da, db)
            if abs(cross) < TURN * np.hypot(*da) * np.hypot(*db):
                continue
            t = _across(b0 - a0, db) / cross
            point = a0 + t * da
            ends = []  # each wall's end nearer the meeting point and its gap: short of the other's face, or past
            for k, (p0, p1) in ((i, (a0, a1)), (j, (b0, b1))):
                gaps = [np.hypot(*(point - p0)), np.hypot(*(point - p1))]
                end = int(np.argmin(gaps))
                tip, far = (p0, p1) if end == 0 else (p1, p0)
                short = _short_of(tip, far, point)
                ends.append((k, end, gaps[end] - (walls[j if k == i else i, 4] / 2 if short else 0.0)))
            near = [(k, end) for k, end, gap in ends if gap <= reach]
            if len(near) < 2 and all(
                gap <= reach or _hidden(walls[k], end, point, floor, voxel_m) for k, end, gap in ends
            ):
                near = [(k, end) for k, end, _ in ends]  # a corner furniture hides: both stop short of it
            if len(near) == 1:  # a T: the other wall runs past the meeting point, only this one ends there
                other = j if near[0][0] == i else i
                p0, p1 = walls[other, 0:2], walls[other, 2:4]
                along = float(np.dot(point - p0, p1 - p0) / np.dot(p1 - p0, p1 - p0))
                near = near if 0.0 <= along <= 1.0 else []
            for k, end in near:  # onto the meeting point and on by half the other's thickness: its far face
                other = j if k == i else i
                start = walls[k, 2 - 2 * end : 4 - 2 * end]
                walls[k, 2 * end : 2 * end + 2] = point + (point - start) / np.hypot(*(point - start)) * (
                    walls[other, 4] / 2
                )
    return walls


def _hidden(wall: np.ndarray, end: int, point: np.ndarray, floor: set | frozenset, voxel_m: float) -> bool:
    """Whether ``point`` lies on the line of ``wall`` (a row of ``CloudMap.walls``) past its ``end`` (0: its
    start, 1: its end) by no more than ``SEEN_ALONG_M``, with the ``floor`` (voxel columns of ``voxel_m``) seen
    under less than half of the way there: a doorway's floor is seen through it; behind a cabinet it is not."""
    far, tip = wall[2 - 2 * end : 4 - 2 * end], wall[2 * end : 2 * end + 2]  # the wall's other end, this one
    if not _short_of(tip, far, point) or np.hypot(*(point - tip)) > SEEN_ALONG_M:
        return False
    steps = max(1, int(np.ceil(np.hypot(*(point - tip)) / (voxel_m / 2))))
    probes = np.floor((tip + np.linspace(0.0, 1.0, steps + 1)[1:, None] * (point - tip)) / voxel_m).astype(int)
    return 2 * sum((int(x), int(y)) in floor for x, y in probes) < len(probes)


def _short_of(tip: np.ndarray, far: np.ndarray, point: np.ndarray) -> bool:
    """Whether a wall from ``far`` to ``tip`` stops short of ``point`` on its line (``point`` lies past ``tip``)."""
    return bool(np.dot(point - far, tip - far) > np.dot(tip - far, tip - far))
