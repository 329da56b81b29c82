"""The walls of a point-cloud map: ends met at L corners and T junctions, a wall seen from both rooms made whole."""

import numpy as np

from pimm_env.importers.cloud_map import CloudMapConfig
from pimm_env.importers.cloud_walls import meet, wall_planes


def _wall(x0, y0, x1, y1):
    return [x0, y0, x1, y1, 0.1, 0.0, 3.0]


def test_a_partition_stopping_short_of_the_wall_it_meets_is_carried_to_it():
    walls = np.array([_wall(0.0, 0.0, 8.0, 0.0), _wall(3.0, -0.25, 3.0, -5.0)])  # a T, 0.25 m short
    met = meet(walls, 0.4)
    assert np.allclose(met[0], walls[0])  # the wall running past is left as it was
    assert np.allclose(met[1, :4], [3.0, 0.0, 3.0, -5.0])
    far = np.array([_wall(0.0, 0.0, 8.0, 0.0), _wall(3.0, -0.6, 3.0, -5.0)])  # further than reach: a doorway
    assert np.allclose(meet(far, 0.4), far)
    beside = np.array([_wall(0.0, 0.0, 2.0, 0.0), _wall(3.0, -0.25, 3.0, -5.0)])  # the line runs, the wall not
    assert np.allclose(meet(beside, 0.4), beside)


def test_an_l_corner_hidden_by_furniture_is_closed_on_both_walls():
    met = meet(np.array([_wall(0.0, 0.3, 0.0, 5.0), _wall(0.3, 0.0, 6.0, 0.0)]), 0.4)
    assert np.allclose(met[0, :2], [0.0, 0.0]) and np.allclose(met[1, :2], [0.0, 0.0])


def test_a_wall_seen_from_both_rooms_stands_between_its_two_faces():
    """A 0.2 m wall along y = 0 (faces at -0.1 and 0.1), floor seen on both sides: one box fills it, not two boxes
    centred on the faces with a slot between them."""
    rng = np.random.default_rng(0)
    config = CloudMapConfig()
    x = rng.uniform(0.0, 5.0, 400)
    faces = np.column_stack([x, np.where(np.arange(400) % 2, 0.1, -0.1), rng.uniform(1.2, 2.5, 400)])
    floor = {(i, j) for i in range(-5, 55) for j in range(-20, 20) if abs(j + 0.5) > 2}
    walls, on_plane = wall_planes(faces, np.full(400, 2.6), floor, config)
    assert on_plane.all() and len(walls) == 2
    covered = []
    for _, y0, _, y1, thickness, _, _ in walls:
        assert abs(y0 - y1) < 0.02
        covered.append((y0 - thickness / 2, y0 + thickness / 2))
    low, high = min(c[0] for c in covered), max(c[1] for c in covered)
    assert -0.12 < low < -0.08 and 0.08 < high < 0.12  # the wall's own faces, within 2 cm
    assert sorted(covered)[0][1] >= sorted(covered)[1][0] - 1e-9  # no slot between the two boxes
