import numpy as np
import pytest

import pimm_agents.corners.detector as detector
from pimm_agents.corners.detector import CornerDetectorConfig, _ends_at, detect_corners
from pimm_agents.corners.planes import Plane
from pimm_env.world.semantics import SemanticClass

WALL, CEILING = int(SemanticClass.WALL), int(SemanticClass.CEILING)


def grid_points(u: np.ndarray, v: np.ndarray, place) -> np.ndarray:
    uu, vv = np.meshgrid(u, v)
    return place(uu.ravel(), vv.ravel())


def room_corner(rng: np.random.Generator, noise: float = 0.005, with_ceiling: bool = True, second_wall: bool = True):
    """Walls x = 2 (y 0..3) and y = 3 (x -1..2) meeting under a ceiling at z = 2.5, in the sensor frame."""
    step = np.arange(0.0, 3.0, 0.05)
    height = np.arange(-0.5, 2.5, 0.05)
    parts = [(grid_points(step, height, lambda a, z: np.column_stack([np.full_like(a, 2.0), a, z])), WALL)]
    if second_wall:
        parts.append(
            (grid_points(step - 1.0, height, lambda a, z: np.column_stack([a, np.full_like(a, 3.0), z])), WALL)
        )
    if with_ceiling:
        parts.append(
            (grid_points(step - 1.0, step, lambda a, b: np.column_stack([a, b, np.full_like(a, 2.5)])), CEILING)
        )
    points = np.concatenate([p for p, _ in parts])
    labels = np.concatenate([np.full(len(p), c) for p, c in parts])
    return points + rng.normal(0, noise, points.shape), labels


def test_synthetic_corner_is_found_to_a_centimetre_and_a_degree():
    points, labels = room_corner(np.random.default_rng(0))
    found = detect_corners(points, labels, stamp=4.2)
    assert found.stamp == 4.2 and len(found) == 1
    corner = found.features[0]
    assert np.hypot(corner.x - 2.0, corner.y - 3.0) < 0.01
    assert abs(np.degrees(corner.theta) - (-135.0)) < 1.0  # bisector towards both walls' centroids
    assert np.all(np.linalg.eigvalsh(corner.position_covariance) > 0) and corner.orientation_variance > 0
    assert 0.7 < corner.confidence <= 1.0  # the vertex itself is in view (to within the subsample spacing)


def test_one_wall_or_no_ceiling_gives_no_corner():
    rng = np.random.default_rng(1)
    assert len(detect_corners(*room_corner(rng, second_wall=False))) == 0
    assert len(detect_corners(*room_corner(rng, with_ceiling=False))) == 0


def test_a_wall_seen_on_both_sides_of_a_doorway_gives_no_phantom_corner():
    # one wall y = 3 with a 1 m doorway between x = 0 and 1, each side fitted on its own, under a ceiling
    rng = np.random.default_rng(2)
    height = np.arange(-0.5, 2.5, 0.05)
    left = grid_points(np.arange(-2.0, 0.0, 0.05), height, lambda a, z: np.column_stack([a, np.full_like(a, 3.0), z]))
    right = grid_points(np.arange(1.0, 3.0, 0.05), height, lambda a, z: np.column_stack([a, np.full_like(a, 3.05), z]))
    ceiling = grid_points(
        np.arange(-2.0, 3.0, 0.05),
        np.arange(0.0, 3.0, 0.05),
        lambda a, b: np.column_stack([a, b, np.full_like(a, 2.5)]),
    )
    points = np.concatenate([left, right, ceiling]) + rng.normal(0, 0.005, (len(left) + len(right) + len(ceiling), 3))
    labels = np.concatenate([np.full(len(left) + len(right), WALL), np.full(len(ceiling), CEILING)])
    assert len(detect_corners(points, labels)) == 0


def wall_x(x: float, y: np.ndarray, z: np.ndarray) -> np.ndarray:
    return grid_points(y, z, lambda a, h: np.column_stack([np.full_like(a, x), a, h]))


def wall_y(y: float, x: np.ndarray, z: np.ndarray) -> np.ndarray:
    return grid_points(x, z, lambda a, h: np.column_stack([a, np.full_like(a, y), h]))


def scene(walls: list[np.ndarray], rng: np.random.Generator, ceiling_z: float = 2.5) -> tuple[np.ndarray, np.ndarray]:
    """The given wall patches under a ceiling at ``ceiling_z`` over x -1..4, y -2..5."""
    ceiling = grid_points(
        np.arange(-1.0, 4.0, 0.1),
        np.arange(-2.0, 5.0, 0.1),
        lambda a, b: np.column_stack([a, b, np.full_like(a, ceiling_z)]),
    )
    points = np.concatenate([*walls, ceiling])
    labels = np.concatenate([np.full(sum(map(len, walls)), WALL), np.full(len(ceiling), CEILING)])
    return points + rng.normal(0, 0.005, points.shape), labels


def test_a_wall_that_runs_past_the_intersection_makes_no_corner_there():
    # wall x = 2 runs from y = -1.5 to 4.5; wall y = 3 stops 0.4 m short of it (as a wall in the next room,
    # seen through a doorway, does): the planes meet at (2, 3), but no wall ends there
    rng = np.random.default_rng(6)
    height = np.arange(-0.5, 2.5, 0.05)
    stops_short = wall_y(3.0, np.arange(-1.0, 1.6, 0.05), height)
    assert len(detect_corners(*scene([wall_x(2.0, np.arange(-1.5, 4.5, 0.05), height), stops_short], rng))) == 0
    # the same wall ending at y = 3 makes the corner
    found = detect_corners(*scene([wall_x(2.0, np.arange(-1.5, 3.0, 0.05), height), stops_short], rng))
    assert len(found) == 1 and np.hypot(found.features[0].x - 2.0, found.features[0].y - 3.0) < 0.02


def test_a_wall_that_runs_on_only_under_a_step_in_the_ceiling_keeps_its_corner():
    # a wall y = 3 runs past x = 2 only below z = 0.4, under a lower room's ceiling, more than
    # through_band below this corner's ceiling at 2.5: the corner where it meets wall x = 2 stands
    rng = np.random.default_rng(7)
    height = np.arange(-0.5, 2.5, 0.05)
    walls = [
        wall_x(2.0, np.arange(-1.5, 3.0, 0.05), np.arange(0.6, 2.5, 0.05)),
        wall_y(3.0, np.arange(-1.0, 2.0, 0.05), height),
        wall_y(3.0, np.arange(2.0, 4.0, 0.05), np.arange(-0.5, 0.4, 0.05)),
    ]
    found = detect_corners(*scene(walls, rng))
    assert len(found) == 1 and np.hypot(found.features[0].x - 2.0, found.features[0].y - 3.0) < 0.02


def test_a_wall_whose_face_stays_far_below_the_corner_does_not_end_there(monkeypatch):
    # the plane y = 3 holds a full-height pier for the last 0.25 m before the corner (2, 3) at the 4.5 m
    # ceiling, shorter than min_face, and beyond it a 1.5 m partition: the face lies more than face_band below
    # the ceiling, so this is not the wall of that ceiling's corner (B's inner wall and the low rooms beyond it)
    corner = np.array([2.0, 3.0, 4.5])
    pier = wall_y(3.0, np.arange(1.75, 2.0, 0.05), np.arange(-0.5, 4.5, 0.05))
    low = wall_y(3.0, np.arange(-1.0, 1.75, 0.05), np.arange(-0.5, 1.0, 0.05))
    full = wall_y(3.0, np.arange(-1.0, 1.75, 0.05), np.arange(-0.5, 4.5, 0.05))
    normal = np.array([0.0, 1.0, 0.0])
    config = CornerDetectorConfig()
    assert not _ends_at(Plane(normal, -3.0, np.concatenate([pier, low]), 0.0), corner, config)
    assert _ends_at(Plane(normal, -3.0, np.concatenate([pier, full]), 0.0), corner, config)
    monkeypatch.setattr(detector, "FACE_BAND", 99.0)  # the test is that of the face band
    assert _ends_at(Plane(normal, -3.0, np.concatenate([pier, low]), 0.0), corner, config)


def test_nan_points_are_ignored_and_empty_input_gives_an_empty_list():
    points, labels = room_corner(np.random.default_rng(3))
    points[::7] = np.nan
    found = detect_corners(points, labels)
    assert len(found) == 1 and np.hypot(found.features[0].x - 2.0, found.features[0].y - 3.0) < 0.02
    assert len(detect_corners(np.zeros((0, 3)), np.zeros(0, dtype=int))) == 0
    with pytest.raises(ValueError, match="labels"):
        detect_corners(np.zeros((5, 3)), np.zeros(4, dtype=int))


def test_detection_is_reproducible():
    points, labels = room_corner(np.random.default_rng(4), noise=0.03)
    a, b = detect_corners(points, labels, seed=5), detect_corners(points, labels, seed=5)
    assert [(f.x, f.y, f.theta) for f in a.features] == [(f.x, f.y, f.theta) for f in b.features]


@pytest.mark.parametrize("field", ["distance_threshold", "max_corner_distance", "merge_distance"])
def test_a_negative_setting_is_refused_by_name(field: str) -> None:
    with pytest.raises(ValueError, match=f"corners.{field} must be positive, got -1"):
        CornerDetectorConfig(**{field: -1})
    with pytest.raises(ValueError, match="corners.min_inliers must be at least 3, got 2"):
        CornerDetectorConfig(min_inliers=2)


def test_faces_that_end_either_side_of_a_doorway_make_no_corner_in_the_gap(monkeypatch):
    # a corridor wall y = 0 resumes at x = 0.6 after a doorway; a partition x = 0 starts 0.15 m past it (behind
    # the corridor wall's thickness): their planes meet at (0, 0), in the doorway, 0.6 m from the corridor wall
    rng = np.random.default_rng(8)
    height = np.arange(-0.5, 2.5, 0.05)
    partition = wall_x(0.0, np.arange(0.15, 3.0, 0.05), height)
    resumed = wall_y(0.0, np.arange(0.6, 4.0, 0.05), height)
    assert len(detect_corners(*scene([partition, resumed], rng))) == 0
    with monkeypatch.context() as patch:
        patch.setattr(detector, "MAX_WALL_GAP", 0.0)
        found = detect_corners(*scene([partition, resumed], rng))
    assert len(found) == 1, "the test is that of the wall gap: without it the phantom is there"
    # the same two walls meeting at (0, 0) make a corner
    meeting = [wall_x(0.0, np.arange(0.0, 3.0, 0.05), height), wall_y(0.0, np.arange(0.0, 4.0, 0.05), height)]
    found = detect_corners(*scene(meeting, rng))
    assert len(found) == 1 and np.hypot(found.features[0].x, found.features[0].y) < 0.02


def test_the_gap_is_measured_on_every_wall_return_not_only_the_subsample_the_planes_were_fitted_to(monkeypatch):
    # two walls meeting at (0, 0) under a ceiling, each seen near the corner only as a thin column of returns
    # 0.2 m from it (as far, grazing walls give), densely from 0.6 m on: the planes are fitted to 150 points of
    # each class, which keep none of the columns, but the scan has them, so the walls reach the corner
    rng = np.random.default_rng(9)
    height = np.arange(-0.5, 2.5, 0.05)
    column = np.array([0.2])
    partition = np.concatenate([wall_x(0.0, column, height[::6]), wall_x(0.0, np.arange(0.6, 3.0, 0.05), height)])
    corridor = np.concatenate([wall_y(0.0, column, height[::6]), wall_y(0.0, np.arange(0.6, 4.0, 0.05), height)])
    monkeypatch.setattr(detector, "MAX_POINTS_PER_CLASS", 150)
    config = CornerDetectorConfig()
    points, labels = scene([partition, corridor], rng)
    found = detect_corners(points, labels, config=config)
    assert len(found) == 1 and np.hypot(found.features[0].x, found.features[0].y) < 0.05
    # the columns are what reach the corner: without them both faces stop 0.6 m short, as in a doorway's gap
    near = (np.hypot(points[:, 0], points[:, 1]) < 0.25) & (labels == WALL)
    assert near.sum() == 20 and len(detect_corners(points[~near], labels[~near], config=config)) == 0
