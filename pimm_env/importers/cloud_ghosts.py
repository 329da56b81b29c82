"""The ghosts in a point-cloud map (cloud_map.py): people who walked by while the map was made, left in it as
person-high streaks over floor the map saw after they passed. A thing standing there hides the floor under it."""

from __future__ import annotations

from typing import Any

import numpy as np

#: voxels the ghost of a person reaches out sideways from the columns that rose from the floor to their height:
#: arms and shoulders, a head leaning, the edge of a stride (the columns their few points fall in do not rise
#: from the floor themselves); at least 1 (scipy's dilation takes 0 as "until nothing changes")
REACH_VOXELS = 2


def ghost_voxels(voxels: np.ndarray, clutter: np.ndarray, levelled: np.ndarray, config: Any) -> np.ndarray:
    """Which ``voxels`` (V, 3 indices) are ghosts: the ``clutter`` (a mask) of a column that rises from the floor
    (below 0.5 m) to above 1 m but no higher than ``person_m``, over floor the map saw under it (its points at
    the floor, ``levelled``, over ``ghost_floor`` of the column's half-voxel cells); and the clutter up to a
    person's height, over such floor, joined to those within ``REACH_VOXELS``. ``config``: cloud_map.CloudMapConfig."""
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
    if not person.any():
        return out
    out[index[person[inverse]]] = True
    return out | _joined(voxels, index[over_floor[inverse] & (z + v <= config.person_m + 1e-9)], out)


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
