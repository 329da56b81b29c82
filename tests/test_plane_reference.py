"""The plane-fit reference of a scan without labels: a box room's walls, floor, ceiling and corners."""

import numpy as np
import pytest

from pimm_agents.measurement.plane_reference import corners_found, plane_reference, score_labels


def room_with_a_desk(rng: np.random.Generator, n: int = 30_000) -> tuple[np.ndarray, np.ndarray]:
    """A 6 x 4 x 2.5 m room (walls 0, ceiling 1, floor 2) with a 1.2 x 0.6 m desk top at 0.75 m (clutter 3),
    seen from a sensor 1 m up at (2, 1.5)."""
    u, v, w = rng.uniform(0, 1, (3, n))
    side = rng.integers(0, 7, n)
    x = np.select([side == 0, side == 1, side == 6], [np.zeros(n), np.full(n, 6.0), 3.5 + 1.2 * u], 6 * u)
    y = np.select([side == 2, side == 3, side == 6], [np.zeros(n), np.full(n, 4.0), 2.5 + 0.6 * v], 4 * v)
    z = np.select([side == 4, side == 5, side == 6], [np.zeros(n), np.full(n, 2.5), np.full(n, 0.75)], 2.5 * w)
    labels = np.select([side < 4, side == 5, side == 4], [0, 1, 2], 3)
    return np.column_stack([x - 2.0, y - 1.5, z - 1.0]) + rng.normal(0, 0.005, (n, 3)), labels


def test_a_room_is_labelled_as_a_person_would_and_its_four_corners_found():
    points, truth = room_with_a_desk(np.random.default_rng(0))
    reference = plane_reference(points)
    assert reference.floor.height == pytest.approx(1.0, abs=0.02)
    scores = score_labels(reference.labels, truth)
    assert all(iou > 0.9 for iou in scores["iou"].values()), scores["iou"]  # the desk top is no floor
    corners = np.array([[-2.0, -1.5], [4.0, -1.5], [4.0, 2.5], [-2.0, 2.5]])
    found = corners_found(reference.corners, corners, 0.2)
    assert found["matched"] == 4 and found["unmatched_found"] == 0


def test_scores_and_corner_matches_by_hand():
    scores = score_labels(np.array([0, 0, 1, 3]), np.array([0, 1, 1, 3]))
    assert scores["iou"]["wall"] == pytest.approx(0.5) and scores["iou"]["ceiling"] == pytest.approx(0.5)
    assert np.isnan(scores["iou"]["floor"]) and scores["mean_iou"] == pytest.approx((0.5 + 0.5 + 1.0) / 3)
    found = corners_found(np.array([[0.0, 0.0], [5.0, 5.0]]), np.array([[0.1, 0.0], [3.0, 0.0]]), 0.2)
    assert found == {"reference": 2, "found": 2, "matched": 1, "unmatched_found": 1}
