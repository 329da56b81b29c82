"""The walls of a point-cloud map: a wall seen from both rooms made whole (its faces in two planes or in one
plane's band), a jog not taken for a thickness, a wall seen from one room stood behind its face, a thin wall's two
faces and two partitions in line across a corridor fitted square to the building, furniture and a round pillar no
walls."""

import numpy as np

from pimm_env.importers.cloud_map import CloudMapConfig
from pimm_env.importers.cloud_walls import ONE_FACED_M, _squared, wall_planes


def test_a_wall_seen_from_both_rooms_stands_between_its_two_faces():
    """A 0.2 m wall along y = 0 (faces at -0.1 and 0.1), floor seen on both sides: one box fills it, not two boxes
    centred on the faces with a slot between them."""
    rng = np.random.default_rng(0)
    config = CloudMapConfig()
    x = rng.uniform(0.0, 5.0, 400)
    faces = np.column_stack([x, np.where(np.arange(400) % 2, 0.1, -0.1), rng.uniform(1.2, 2.5, 400)])
    floor = {(i, j) for i in range(-5, 55) for j in range(-20, 20) if abs(j + 0.5) > 2}
    walls, on_plane = wall_planes(faces, np.full(400, 2.6), (floor, floor), config)
    assert on_plane.all() and len(walls) == 2
    covered = []
    for _, y0, _, y1, thickness, _, _ in walls:
        assert abs(y0 - y1) < 0.02
        covered.append((y0 - thickness / 2, y0 + thickness / 2))
    low, high = min(c[0] for c in covered), max(c[1] for c in covered)
    assert -0.12 < low < -0.08 and 0.08 < high < 0.12  # the wall's own faces, within 2 cm
    assert sorted(covered)[0][1] >= sorted(covered)[1][0] - 1e-9  # no slot between the two boxes


def _face(rng, n, x0, x1, y):
    return np.column_stack([rng.uniform(x0, x1, n), y + rng.normal(0.0, 0.01, n), rng.uniform(1.2, 2.5, n)])


def test_a_wall_seen_from_one_room_stands_behind_its_face():
    """An outer wall's face at y = 0, the room's floor seen on the side y < 0: its body lies at y > 0, as thick as
    an outer wall, so that the corners of its back lie outside the building."""
    rng = np.random.default_rng(1)
    floor = {(i, j) for i in range(0, 50) for j in range(-40, -1)}
    walls, _ = wall_planes(_face(rng, 300, 0.0, 5.0, 0.0), np.full(300, 2.6), (floor, floor), CloudMapConfig())
    assert len(walls) == 1
    _, y0, _, _, thickness, _, _ = walls[0]
    assert thickness == ONE_FACED_M and abs(y0 - thickness / 2) < 0.02  # its room-side face on the points


def test_a_thin_walls_two_faces_seen_unevenly_are_one_wall_square_to_the_building():
    """A 0.1 m partition along x (faces at y = -0.05 and 0.05), one face seen at one end and the other at the
    other end, beside a long square wall: a slanted line across both faces holds more of them, but the wall
    is fitted square to the building, between its faces."""
    rng = np.random.default_rng(2)
    parts = [
        _face(rng, 800, -1.0, 9.0, 2.0),  # the long wall that sets the building's square
        _face(rng, 800, 0.0, 9.0, -3.0),
        _face(rng, 150, 0.0, 3.0, -0.05),  # the partition: its lower face at the left end ...
        _face(rng, 150, 2.0, 5.0, 0.05),  # ... its upper face at the right end
    ]
    centres = np.vstack(parts)
    floor = {(i, j) for i in range(-10, 90) for j in range(-29, 20) if abs(j + 0.5) > 2}
    walls, _ = wall_planes(centres, np.full(len(centres), 2.6), (floor, floor), CloudMapConfig())
    partition = [w for w in walls if abs((w[1] + w[3]) / 2) < 0.5]
    longest = max(walls, key=lambda w: np.hypot(w[2] - w[0], w[3] - w[1]))
    assert len(partition) == 1
    x0, y0, x1, y1, thickness, _, _ = partition[0]
    slant = np.arctan2(y1 - y0, x1 - x0) - np.arctan2(longest[3] - longest[1], longest[2] - longest[0])
    assert abs(np.sin(slant)) < 1e-9  # square to the building, not on a slant across the faces
    assert y0 - thickness / 2 <= -0.03 and y0 + thickness / 2 >= 0.03  # the wall between its faces


def test_a_thin_walls_two_faces_in_one_planes_band_are_its_thickness():
    """A 0.1 m partition along x seen from both rooms, more of it from one: its two faces lie in one plane's band
    (``wall_plane_m`` either side), and the wall stands between them, not at the denser face's median."""
    rng = np.random.default_rng(3)
    partition = [_face(rng, 300, 0.0, 5.0, 0.05), _face(rng, 120, 0.0, 5.0, -0.05)]
    centres = np.vstack([_face(rng, 800, -1.0, 9.0, 2.0), *partition])  # the long wall: the building's square
    floor = {(i, j) for i in range(-10, 90) for j in range(-20, 20) if abs(j + 0.5) > 2}
    walls, _ = wall_planes(centres, np.full(len(centres), 2.6), (floor, floor), CloudMapConfig())
    walls = [w for w in walls if abs((w[1] + w[3]) / 2) < 0.5]
    assert len(walls) == 1
    _, y0, _, y1, thickness, _, _ = walls[0]
    assert abs(y1 - y0) < 1e-3  # square, not on a slant across both faces (0.04 m over its length)
    assert abs(y0 - thickness / 2 + 0.05) < 0.02 and abs(y0 + thickness / 2 - 0.05) < 0.02


def test_a_jog_in_a_wall_is_not_taken_for_its_thickness():
    """A wall whose face steps back 0.1 m halfway along (each stretch seen from the room at y < 0): one face
    line per stretch, no box spanning the step."""
    rng = np.random.default_rng(4)
    centres = np.vstack([_face(rng, 200, 0.0, 3.0, 0.0), _face(rng, 200, 3.0, 6.0, 0.1)])
    floor = {(i, j) for i in range(0, 60) for j in range(-40, -1)}
    walls, _ = wall_planes(centres, np.full(len(centres), 2.6), (floor, floor), CloudMapConfig())
    assert all(w[4] == ONE_FACED_M for w in walls)


def _cabinet_face(rng, n, start, end, top):
    """A face from ``start`` to ``end`` (x, y) seen from 1.2 m up to ``top``."""
    t = rng.uniform(0.0, 1.0, n)[:, None]
    xy = np.asarray(start) + t * (np.asarray(end) - np.asarray(start)) + rng.normal(0.0, 0.01, (n, 2))
    return np.column_stack([xy, rng.uniform(1.2, top, n)])


def test_a_cabinet_short_of_the_ceiling_is_not_a_wall_nor_a_walls_other_face():
    """A room's wall along y = 0 seen from y < 0 (ceiling 2.6 m); a 1.9 m cabinet's side standing out of it
    (x = 2.5) and a cabinet's back 0.35 m behind it, seen through a doorway: neither is a wall (its corners would
    be none of the building's), and the wall stands as thick as a wall seen from one room. A partition as long as
    the cabinet's side but up to the ceiling stays a wall."""
    rng = np.random.default_rng(5)
    floor = {(i, j) for i in range(0, 60) for j in range(-40, -1)}
    wall = _face(rng, 400, 0.0, 5.0, 0.0)
    side = _cabinet_face(rng, 120, (2.5, -0.05), (2.5, -0.8), 1.9)
    back = _cabinet_face(rng, 120, (1.0, 0.35), (1.6, 0.35), 1.9)
    centres = np.vstack([wall, side, back])
    walls, on_plane = wall_planes(centres, np.full(len(centres), 2.6), (floor, floor), CloudMapConfig())
    assert len(walls) == 1 and walls[0][4] == ONE_FACED_M
    cabinet = centres[len(wall) :]
    assert on_plane[: len(wall)].all() and not on_plane[len(wall) :][np.abs(cabinet[:, 1]) > 0.15].any()
    partition = _cabinet_face(rng, 120, (2.5, -0.05), (2.5, -0.8), 2.5)
    walls, on_plane = wall_planes(np.vstack([wall, partition]), np.full(520, 2.6), (floor, floor), CloudMapConfig())
    assert len(walls) == 2 and on_plane[len(wall) :].mean() > 0.9


def test_two_partitions_nearly_in_line_across_the_building_are_each_fitted_square():
    """A room's partition at x = 5 and one across the corridor at x = 5.35, both along y: a line slanted by 2.5
    degrees holds most of both, more points than either square plane, but along the square plane's piece (the
    first partition) it holds fewer: the partition is fitted square, without the other's points."""
    rng = np.random.default_rng(6)
    first = np.column_stack([5.0 + rng.normal(0.0, 0.01, 300), rng.uniform(0.0, 4.0, 300), rng.uniform(1.2, 2.5, 300)])
    other = np.column_stack(
        [5.35 + rng.normal(0.0, 0.01, 300), rng.uniform(8.0, 12.0, 300), rng.uniform(1.2, 2.5, 300)]
    )
    xy = np.vstack([first, other])[:, :2]
    along = np.array([0.35, 8.0]) / np.hypot(0.35, 8.0)
    slanted = np.array([along[1], -along[0]])
    inliers = np.flatnonzero(np.abs((xy - [5.0, 2.0]) @ slanted) < CloudMapConfig().wall_plane_m)
    assert len(inliers) > 400 and np.count_nonzero(inliers >= 300) > 100  # the slanted line holds both
    kept, normal = _squared(xy, inliers, slanted, 0.0, CloudMapConfig())
    assert abs(normal[1]) < 1e-9  # square to the building (its walls' normals along x)
    assert set(kept.tolist()) == set(range(300)) or set(kept.tolist()) == set(range(300, 600))


def test_a_slanted_plane_whose_median_falls_between_its_two_ends_is_left_as_fitted():
    """A line 4 degrees off square holding two groups of 10 points 5 m apart along it: squared, their depths lie
    0.35 m apart, and the median of the 20 falls halfway between, 0.17 m from any point, beyond the band's 0.16 m:
    nothing to centre the squared band on, and the plane is kept as fitted (it raised on a generated building's
    map before)."""
    angle = np.radians(4.0)
    along = np.array([np.cos(np.pi / 2 + angle), np.sin(np.pi / 2 + angle)])
    slanted = np.array([along[1], -along[0]])
    xy = np.vstack([np.outer(np.linspace(0.0, 0.05, 10), along), np.outer(np.linspace(5.0, 5.05, 10), along)])
    inliers = np.arange(20)
    kept, normal = _squared(xy, inliers, slanted, 0.0, CloudMapConfig())
    assert kept.tolist() == inliers.tolist() and np.allclose(normal, slanted)


def test_a_plane_through_a_round_pillars_two_sides_is_not_a_wall():
    """A plane through a round pillar 0.5 m across holds its two sides (a voxel's mean points each, from 1.2 to
    2.5 m): 0.6 m end to end with a voxel, as long as a wall's shortest piece, but it fills two voxels along it,
    not six: no wall stands in the pillar."""
    rng = np.random.default_rng(7)
    z = np.arange(1.25, 2.5, 0.1)
    sides = np.array([[x, y, h] for x in (2.75, 3.25) for y in (2.95, 3.05) for h in z])
    centres = np.vstack([_face(rng, 600, 0.0, 6.0, 0.0), _face(rng, 600, 0.0, 6.0, 6.0), sides])
    floor = {(i, j) for i in range(0, 60) for j in range(1, 59)}
    walls, on_plane = wall_planes(centres, np.full(len(centres), 2.6), (floor, floor), CloudMapConfig())
    assert len(walls) == 2 and not on_plane[1200:].any()
