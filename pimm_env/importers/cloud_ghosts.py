"""The ghosts in a point-cloud map (cloud_map.py): people who walked by while the map was made, left in it as
person-high streaks over floor the map saw after they passed, or, seen from afar by a few of the LiDAR's rings, as
small pieces floating free over that floor. A thing standing there hides the floor under it."""

from __future__ import annotations

from typing import Any

import numpy as np

#: voxels the ghost of a person reaches out sideways from the columns that rose from the floor to their height:
#: arms and shoulders, a head leaning, the edge of a stride (the columns their few points fall in do not rise
#: from the floor themselves); at least 1 (scipy's dilation takes 0 as "until nothing changes")
REACH_VOXELS = 2
#: a piece of clutter standing free of every other surface, over seen floor, no wider than this (m) is a passer-by
#: seen by a few of the LiDAR's rings (ours: a person is 0.4 x 0.3 m, 0.5 m across; a desk or a chair's seat is more)
FRAGMENT_M = 0.5
#: voxels of height between a piece's voxels in one column that still join them (the gap between two rings' hits)
RING_GAP_VOXELS = 2


def ghost_voxels(voxels: np.ndarray, clutter: np.ndarray, levelled: np.ndarray, config: Any) -> np.ndarray:
    """Which ``voxels`` (V, 3 indices) are ghosts: the ``clutter`` (a mask) of a column that rises from the floor
    (below 0.5 m) to above 1 m but no higher than ``person_m``, over floor the map saw under it (its points at
    the floor, ``levelled``, over ``ghost_floor`` of the column's half-voxel cells); the clutter up to a
    person's height, over such floor, joined to those within ``REACH_VOXELS``; and the pieces of clutter over
    such floor that touch nothing else (:func:`_fragments`). ``config``: cloud_map.CloudMapConfig."""
    v = config.voxel_m
    out = np.zeros(len(voxels), dtype=bool)
    index = np.flatnonzero(clutter)
    if not len(index):
        return out
    column, inverse = np.unique(voxels[index, :2], axis=0, return_inverse=True)
    inverse = inverse.reshape(-1)
    z = voxels[index, 2] * v
    low, high = np.full(len(column), np.inf), np.full(len(column), -np.inf)
    np.minimum.at(low, inverse, z)
    np.maximum.at(high, inverse, z + v)
    on_floor = levelled[np.abs(levelled[:, 2]) < v / 2, :2]
    cells = np.unique(np.floor(on_floor / (v / 2)).astype(np.int64), axis=0)  # the half-voxel cells seen
    under, seen = np.unique(np.floor(cells / 2).astype(np.int64), axis=0, return_counts=True)
    seen_in = dict(zip(map(tuple, under.tolist()), seen.tolist(), strict=True))
    share = np.array([seen_in.get(tuple(c), 0) / 4 for c in column.tolist()])
    over_floor = share >= config.ghost_floor
    person = (low < 0.5) & (high > 1.0) & (high <= config.person_m + 1e-9) & over_floor
    if person.any():
        out[index[person[inverse]]] = True
        out |= _joined(voxels, index[over_floor[inverse] & (z + v <= config.person_m + 1e-9)], out)
    over = np.zeros(len(voxels), dtype=bool)
    over[index] = over_floor[inverse]
    return out | _fragments(voxels, clutter & ~out, over, config)


def _fragments(voxels: np.ndarray, clutter: np.ndarray, over_floor: np.ndarray, config: Any) -> np.ndarray:
    """The ``clutter`` voxels (a mask) of pieces that are a passer-by seen from afar: a piece (clutter voxels
    joined to a neighbour, 26-connected, or in one column across ``RING_GAP_VOXELS``) no wider than ``FRAGMENT_M``
    in x and y, no higher than ``person_m``, every voxel ``over_floor`` (a mask: its column's floor was seen), and
    no voxel of another class (floor, wall, ceiling) beside any of it: it stands on nothing and hangs from nothing."""
    from scipy import ndimage

    index = np.flatnonzero(clutter)
    out = np.zeros(len(voxels), dtype=bool)
    if not len(index):
        return out
    lo = voxels[index].min(axis=0) - 1
    shape = tuple(voxels[index].max(axis=0) - lo + 2)
    at = tuple((voxels[index] - lo).T)
    piece = np.zeros(shape, dtype=bool)
    piece[at] = True
    tall = np.ones((1, 1, 2 * (RING_GAP_VOXELS // 2) + 1), dtype=bool)  # each hit grown by half the gap up and down
    labels, count = ndimage.label(ndimage.binary_dilation(piece, tall), np.ones((3, 3, 3), dtype=bool))
    label = labels[at] - 1
    others = np.flatnonzero(~clutter & np.all((voxels >= lo) & (voxels < lo + shape), axis=1))
    other = np.zeros(shape, dtype=bool)
    other[tuple((voxels[others] - lo).T)] = True
    beside = ndimage.binary_dilation(other, np.ones((3, 3, 3), dtype=bool))[at]
    fits = np.ones(count, dtype=bool)
    np.logical_and.at(fits, label, over_floor[index] & ~beside)
    v = config.voxel_m
    for axis in (0, 1):
        low, high = np.full(count, np.iinfo(np.int64).max), np.full(count, np.iinfo(np.int64).min)
        np.minimum.at(low, label, voxels[index, axis])
        np.maximum.at(high, label, voxels[index, axis])
        fits &= (high - low + 1) * v <= FRAGMENT_M + 1e-9
    top = np.full(count, -np.inf)
    np.maximum.at(top, label, (voxels[index, 2] + 1) * v)
    fits &= top <= config.person_m + 1e-9
    out[index] = fits[label]
    return out


def _joined(voxels: np.ndarray, reachable: np.ndarray, ghosts: np.ndarray) -> np.ndarray:
    """The voxels of ``reachable`` (indices) joined to ``ghosts`` (a mask), each to the next, by up to
    ``REACH_VOXELS`` steps to a neighbour (26-connected)."""
    from scipy import ndimage

    lo = voxels[reachable].min(axis=0) - 1
    shape = tuple(voxels[reachable].max(axis=0) - lo + 2)
    allowed = np.zeros(shape, dtype=bool)
    allowed[tuple((voxels[reachable] - lo).T)] = True
    inside = np.all((voxels >= lo) & (voxels < lo + shape), axis=1)
    seed = np.zeros(shape, dtype=bool)
    seed[tuple((voxels[ghosts & inside] - lo).T)] = True
    grown = ndimage.binary_dilation(seed, np.ones((3, 3, 3), bool), REACH_VOXELS, mask=allowed | seed)
    out = np.zeros(len(voxels), dtype=bool)
    out[reachable] = grown[tuple((voxels[reachable] - lo).T)]
    return out
