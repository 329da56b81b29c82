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
