"""Voxel columns as floor, ceiling, wall or clutter (pimm_env/importers/cloud_columns.py)."""

import numpy as np

from pimm_env.importers.cloud_columns import CEILING, CLUTTER, FLOOR, WALL, column_classes
from pimm_env.importers.cloud_map import CloudMapConfig


def column(x: int, y: int, heights_m) -> np.ndarray:
    """The voxels (0.1 m) of column (x, y) at the given heights (their bottoms, metres)."""
    z = np.round(np.asarray(heights_m, float) / 0.1).astype(int)
    return np.column_stack([np.full(len(z), x), np.full(len(z), y), z])


def corridor(beside: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """A corridor (y 0-4, x 0-9) with its floor seen and a 2.7 m ceiling, and the columns ``beside`` it at y 5:
    the voxels and their classes."""
    open_floor = [column(x, y, [0.0, 2.6, 2.7]) for x in range(10) for y in range(5)]
    voxels = np.vstack(open_floor + beside)
    classes, _ = column_classes(voxels, CloudMapConfig())
    return voxels, classes


def classes_at(voxels: np.ndarray, classes: np.ndarray, x: int, y: int, lo_m: float, hi_m: float) -> set[int]:
    z = voxels[:, 2] * 0.1
    at = (voxels[:, 0] == x) & (voxels[:, 1] == y) & (z >= lo_m) & (z < hi_m)
    return set(classes[at].tolist())


def test_a_wall_going_on_over_the_corridors_ceiling_holds_it_up_and_a_cabinet_does_not():
    """Columns at y 5: a wall seen from the corridor up to its 2.7 m ceiling and, over it, from afar from 3.6 m
    to 5 m (a gap of 0.9 m between), and a 1.9 m cabinet under a ceiling seen at 5 m."""
    seen_twice = np.r_[np.arange(0.0, 2.75, 0.1), np.arange(3.6, 5.05, 0.1)]
    wall = [column(x, 5, seen_twice) for x in range(0, 5)]
    cabinet = [column(x, 5, np.r_[np.arange(0.0, 1.95, 0.1), 4.9, 5.0]) for x in range(5, 10)]
    voxels, classes = corridor(wall + cabinet)
    assert classes_at(voxels, classes, 2, 5, 1.2, 2.5) == {WALL}
    assert classes_at(voxels, classes, 7, 5, 1.2, 1.9) == {CLUTTER}
    assert classes_at(voxels, classes, 2, 2, 2.6, 2.8) == {CEILING} and classes_at(voxels, classes, 2, 2, 0, 0.1) == {
        FLOOR
    }


def test_a_sparsely_seen_column_is_not_a_ceiling_the_wall_beside_it_holds_up():
    """The same wall's columns and, two columns off (y 7), columns over seen floor holding a few voxels up to
    2.1-2.3 m (the inside of a wall seen through its rings: not level with three neighbours). No lower ceiling
    stands beside the wall, so it is judged up to its own 5 m top, over the 0.9 m it was not seen: clutter."""
    seen_twice = np.r_[np.arange(0.0, 2.75, 0.1), np.arange(3.6, 5.05, 0.1)]
    wall = [column(x, 5, seen_twice) for x in range(0, 10)]
    inside = [column(x, 7, [0.0, 0.5, 1.4, 2.3 - 0.1 * (x % 3)]) for x in range(0, 10)]
    voxels = np.vstack(wall + inside)
    classes, _ = column_classes(voxels, CloudMapConfig())
    assert classes_at(voxels, classes, 4, 5, 1.2, 2.5) == {CLUTTER}
