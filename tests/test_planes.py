import numpy as np
import pytest

from pimm_agents.corners.planes import PlaneParams, constrained_ransac, extract_planes, robust_refit


def wall_and_clutter(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """300 points on the upright plane x + y = 4 (noise 1 cm), then 200 scattered points."""
    t = rng.uniform(0, 3, 300)
    wall = np.column_stack([4 - t, t, rng.uniform(0, 3, 300)])
    wall += rng.normal(0, 0.01, wall.shape) * np.array([1, 1, 0]) / np.sqrt(2)
    clutter = rng.uniform(-5, 5, (200, 3))
    clutter = clutter[np.abs(clutter[:, 0] + clutter[:, 1] - 4) / np.sqrt(2) > 0.3]
    return np.concatenate([wall, clutter]), np.arange(300)


@pytest.mark.parametrize("orientation", ["vertical", "any"])
def test_constrained_ransac_finds_the_dominant_plane(orientation):
    points, on_wall = wall_and_clutter(np.random.default_rng(0))
    found = constrained_ransac(points, 0.05, 200, orientation, np.random.default_rng(1), score_points=250)
    # an upright hypothesis through two wall points holds the whole wall; three noisy points may tilt a little
    assert set(found) <= set(on_wall) and len(found) >= (300 if orientation == "vertical" else 290)


def test_level_planes_and_bad_orientation():
    rng = np.random.default_rng(2)
    ceiling = np.column_stack([rng.uniform(0, 4, (150, 2)), np.full(150, 2.7)])
    tilted = np.column_stack([rng.uniform(0, 4, (250, 2)), np.zeros(250)])
    tilted[:, 2] = 0.5 * tilted[:, 0]  # more points, but 27 deg off level: a "horizontal" search skips it
    points = np.concatenate([ceiling, tilted])
    assert constrained_ransac(points, 0.05, 100, "horizontal", rng).tolist() == list(range(150))
    assert constrained_ransac(np.zeros((0, 3)), 0.05, 100, "vertical", rng).size == 0
    with pytest.raises(ValueError, match="orientation 'diagonal'"):
        constrained_ransac(points, 0.05, 100, "diagonal", rng)


def test_extract_planes_by_either_ransac_takes_planes_largest_first():
    rng = np.random.default_rng(3)
    big = np.column_stack([np.full(400, 1.0), rng.uniform(0, 4, 400), rng.uniform(0, 3, 400)])
    small = np.column_stack([rng.uniform(-3, 0, 200), np.full(200, 5.0), rng.uniform(0, 3, 200)])
    points = np.concatenate([big, small]) + rng.normal(0, 0.005, (600, 3))
    for method in ("open3d", "constrained"):
        planes = extract_planes(points, PlaneParams(min_inliers=50, method=method), seed=0, orientation="vertical")
        assert len(planes) == 2 and 395 <= len(planes[0].inliers) <= 400 and 195 <= len(planes[1].inliers) <= 200
        assert abs(abs(planes[0].normal[0]) - 1) < 1e-3 and abs(abs(planes[1].normal[1]) - 1) < 1e-3
    with pytest.raises(ValueError, match="method 'magic'"):
        PlaneParams(method="magic")


def test_the_robust_refit_trims_the_band_of_a_meeting_wall():
    # a wall x = 0 and the first 0.2 m of a wall y = 0 meeting it: RANSAC's 0.2 m band takes both in
    rng = np.random.default_rng(4)
    wall = np.column_stack([rng.normal(0, 0.005, 400), rng.uniform(0.2, 4, 400), rng.uniform(0, 3, 400)])
    meeting = np.column_stack([rng.uniform(0, 0.2, 60), rng.normal(0, 0.005, 60), rng.uniform(0, 3, 60)])
    normal, d, rms, kept = robust_refit(np.concatenate([wall, meeting]))
    assert abs(abs(normal[0]) - 1) < 1e-3 and abs(d) < 0.01 and rms < 0.01
    assert 395 <= len(kept) <= 420  # the wall's points, few of the meeting wall's
