"""The ends of a point-cloud map's walls: met at L corners (one a cabinet hides, not across a doorway beside one)
and T junctions, and one wall fitted as two planes closed across a cabinet's shadow."""

import numpy as np

from pimm_env.importers.cloud_wall_ends import bridged, meet
from pimm_env.mapping.corner_map import SEEN_ALONG_M


def _wall(x0, y0, x1, y1):
    return [x0, y0, x1, y1, 0.1, 0.0, 3.0]


def test_a_partition_stopping_short_of_the_wall_it_meets_is_carried_to_it():
    walls = np.array([_wall(0.0, 0.0, 8.0, 0.0), _wall(3.0, -0.25, 3.0, -5.0)])  # a T, 0.25 m short
    met = meet(walls, 0.4)
    assert np.allclose(met[0], walls[0])  # the wall running past is left as it was
    assert np.allclose(met[1, :4], [3.0, 0.05, 3.0, -5.0])  # to its far face: no notch beside the partition
    far = np.array([_wall(0.0, 0.0, 8.0, 0.0), _wall(3.0, -0.6, 3.0, -5.0)])  # further than reach: a doorway
    assert np.allclose(meet(far, 0.4), far)
    beside = np.array([_wall(0.0, 0.0, 1.5, 0.0), _wall(3.0, -0.25, 3.0, -5.0)])  # the line runs, the wall not
    assert np.allclose(meet(beside, 0.4), beside)


def test_how_far_a_wall_stops_short_is_measured_to_the_face_it_meets_and_a_stub_past_a_wall_is_kept():
    """A partition's last stretch seen at a grazing angle: it stops 0.33 m short of a 0.2 m thick wall's face
    (0.43 m of the wall's middle line) and meets it; a wall running 0.43 m on past a partition's line (a stub
    beside a doorway) is not cut back to it."""
    thick = [0.0, 0.0, 8.0, 0.0, 0.2, 0.0, 3.0]
    short = np.array([thick, _wall(3.0, -0.43, 3.0, -5.0)])
    assert np.allclose(meet(short, 0.4)[1, :4], [3.0, 0.1, 3.0, -5.0])
    stub = np.array([[3.0, -5.0, 3.0, 0.43, 0.2, 0.0, 3.0], [8.0, 0.0, 3.1, 0.0, 0.1, 0.0, 3.0]])
    assert np.allclose(meet(stub, 0.4)[0], stub[0])


def test_one_wall_fitted_as_two_planes_across_a_cabinets_shadow_is_closed_and_a_doorway_is_not():
    """A corridor wall fitted as two planes 2 cm apart (a SLAM map's drift), its stretch behind a cabinet (0.45 m)
    not seen: both carried to the middle of the gap, whichever way each runs; a doorway (0.9 m) stays open, and
    a parallel wall 0.3 m aside is not in line."""
    walls = np.array([_wall(0.0, 0.0, 3.0, 0.0), _wall(6.0, 0.02, 3.45, 0.02)])
    closed = bridged(walls, 0.6, 0.08)
    assert np.allclose(closed[0, :4], [0.0, 0.0, 3.225, 0.0]) and np.allclose(closed[1, :4], [6.0, 0.02, 3.225, 0.02])
    doorway = np.array([_wall(0.0, 0.0, 3.0, 0.0), _wall(3.9, 0.0, 6.0, 0.0)])
    assert np.allclose(bridged(doorway, 0.6, 0.08), doorway)
    aside = np.array([_wall(0.0, 0.0, 3.0, 0.0), _wall(3.3, 0.3, 6.0, 0.3)])
    assert np.allclose(bridged(aside, 0.6, 0.08), aside)


def test_an_l_corner_hidden_by_furniture_is_closed_on_both_walls():
    """Each wall runs on past the meeting point of their middle lines by half the other's thickness: the boxes
    fill the corner's outer square, so that their outline turns once on each side (no 5 cm notch)."""
    met = meet(np.array([_wall(0.0, 0.3, 0.0, 5.0), _wall(0.3, 0.0, 6.0, 0.0)]), 0.4)
    assert np.allclose(met[0, :2], [0.0, -0.05]) and np.allclose(met[1, :2], [-0.05, 0.0])


def test_a_corner_a_cabinet_hides_is_closed_and_a_doorway_beside_a_corner_is_not():
    """Walls stopping 0.9 m and 0.5 m short of their corner (a cabinet standing in it, the floor behind it never
    seen) meet there; with the floor seen along the 0.9 m gap (a doorway beside the corner) they stay apart, as
    they do where one stops further than ``SEEN_ALONG_M`` short."""
    walls = np.array([_wall(0.0, 0.9, 0.0, 5.0), _wall(0.5, 0.0, 6.0, 0.0)])
    met = meet(walls, 0.4, set(), 0.1)
    assert np.allclose(met[0, :2], [0.0, -0.05]) and np.allclose(met[1, :2], [-0.05, 0.0])
    doorway = {(i, j) for i in (-1, 0) for j in range(9)}  # the floor's columns along x = 0 from y = 0 to 0.9
    assert np.allclose(meet(walls, 0.4, doorway, 0.1), walls)
    further = np.array([_wall(0.0, SEEN_ALONG_M + 0.1, 0.0, 5.0), _wall(0.5, 0.0, 6.0, 0.0)])
    assert np.allclose(meet(further, 0.4, set(), 0.1), further)
