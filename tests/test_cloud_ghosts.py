"""The ghosts in a point-cloud map (pimm_env/importers/cloud_ghosts.py): a person who walked by is set aside,
arms and all; a cabinet beside them is not."""

import numpy as np

from pimm_env.importers.cloud_ghosts import ghost_voxels
from pimm_env.importers.cloud_map import CloudMapConfig


def _floor_points(x0, x1, y0, y1, step=0.02):
    x, y = np.meshgrid(np.arange(x0, x1, step), np.arange(y0, y1, step))
    return np.column_stack([x.ravel(), y.ravel(), np.zeros(x.size)])


def test_a_person_is_set_aside_with_the_arms_beside_their_body_and_a_cabinet_by_them_kept():
    """Voxels of 0.1 m: a person's body in columns (20-21, 20) from the floor to 1.7 m, an arm sticking out at
    1.2 m in columns (22, 20) and (23, 20) over seen floor; a cabinet touching the arm, 1.9 m high, over floor
    never seen (its footprint x 2.4-2.8 m)."""
    body = [(x, 20, z) for x in (20, 21) for z in range(17)]
    arm = [(22, 20, 12), (23, 20, 12)]
    cabinet = [(x, 20, z) for x in range(24, 28) for z in range(19)]
    voxels = np.array(body + arm + cabinet)
    floor = np.vstack([_floor_points(1.5, 2.4, 1.5, 2.5), _floor_points(2.8, 3.5, 1.5, 2.5)])
    ghosts = ghost_voxels(voxels, np.ones(len(voxels), dtype=bool), floor, CloudMapConfig())
    assert ghosts[: len(body) + len(arm)].all()  # the body and its arm, which does not rise from the floor
    assert not ghosts[len(body) + len(arm) :].any()  # the cabinet, over floor the map never saw


def test_a_passer_by_seen_by_two_rings_is_set_aside_and_a_table_top_a_shelf_and_a_thing_over_hidden_floor_kept():
    """Voxels of 0.1 m, none rising from the floor: two rings' hits on a passer-by (0.3-0.4 and 0.6-0.7 m, 0.2 m
    long) over seen floor; a table top 0.8 m long at 0.7 m over seen floor; a shelf board beside a wall (the
    wall's voxels are not clutter); the passer-by's piece again over floor never seen."""
    passer = [(10, 10, 3), (10, 11, 3), (10, 10, 6), (10, 11, 6)]
    table = [(x, y, 7) for x in range(20, 28) for y in (10, 11)]
    shelf = [(30, y, 9) for y in (10, 11)]
    wall = [(31, y, z) for y in (10, 11) for z in range(25)]
    hidden = [(x + 30, y + 20, z) for x, y, z in passer]
    voxels = np.array(passer + table + shelf + wall + hidden)
    clutter = np.ones(len(voxels), dtype=bool)
    clutter[len(passer) + len(table) + len(shelf) : len(voxels) - len(hidden)] = False
    floor = _floor_points(0.5, 3.3, 0.5, 1.5)
    ghosts = ghost_voxels(voxels, clutter, floor, CloudMapConfig())
    assert ghosts[: len(passer)].all()
    assert not ghosts[len(passer) :].any()
