"""The registration localizer: the global search and the planar ICP on their own, then the localizer through
the contract in a small asymmetric room (global start, tracking, a kidnap, bad input)."""

import numpy as np
import pytest

from pimm_agents.registration.global_search import SearchConfig, distinct_best, ransac_poses
from pimm_agents.registration.localizer import RegistrationConfig, RegistrationLocalizer
from pimm_agents.registration.map_cloud import MapCloud, estimate_normals, fpfh, to_open3d
from pimm_agents.registration.planar_icp import PlanarIcp, transform
from pimm_env.errors import ObservationError
from pimm_env.geometry import wrap_angle

HEIGHT = 0.5  # the sensor above the floor


def room_surfaces(spacing: float = 0.1) -> tuple[np.ndarray, np.ndarray]:
    """An L-shaped room (12 x 8 m less a 5 x 4 m corner), 3 m high, with a 1 x 1 m pillar and a low cabinet:
    points on its walls, floor, ceiling and furniture, with normals into the room."""
    outline = np.array([[0, 0], [12, 0], [12, 4], [7, 4], [7, 8], [0, 8]], dtype=float)
    pillar = np.array([[3, 5], [4, 5], [4, 6], [3, 6]], dtype=float)
    points, normals = [], []

    def wall(a, b, inward, top=3.0):
        length = np.hypot(*(b - a))
        s, z = np.meshgrid(np.arange(0, length, spacing), np.arange(0, top, spacing))
        xy = a + np.outer(s.ravel() / length, b - a)
        points.append(np.column_stack([xy, z.ravel()]))
        normals.append(np.tile([*inward, 0.0], (len(xy), 1)))

    for i in range(len(outline)):  # counter-clockwise outline: the inside is on the left
        a, b = outline[i], outline[(i + 1) % len(outline)]
        d = (b - a) / np.hypot(*(b - a))
        wall(a, b, (-d[1], d[0]))
    for i in range(len(pillar)):  # the pillar's faces look out
        a, b = pillar[i], pillar[(i + 1) % len(pillar)]
        d = (b - a) / np.hypot(*(b - a))
        wall(a, b, (d[1], -d[0]))
    wall(np.array([9.0, 0.3]), np.array([11.0, 0.3]), (0.0, 1.0), top=1.2)  # a cabinet's front
    gx, gy = np.meshgrid(np.arange(0, 12, spacing), np.arange(0, 8, spacing))
    inside = ~((gx > 7) & (gy > 4)) & ~((gx > 3) & (gx < 4) & (gy > 5) & (gy < 6))
    for z, up in ((0.0, 1.0), (3.0, -1.0)):
        points.append(np.column_stack([gx[inside], gy[inside], np.full(inside.sum(), z)]))
        normals.append(np.tile([0.0, 0.0, up], (int(inside.sum()), 1)))
    return np.vstack(points), np.vstack(normals)


def room_map(voxel: float = 0.25) -> MapCloud:
    points, normals = room_surfaces()
    cloud = to_open3d(points, normals).voxel_down_sample(voxel)
    outward = np.asarray(cloud.normals).copy()
    estimate_normals(cloud, voxel)
    n = np.asarray(cloud.normals)
    n[np.einsum("ij,ij->i", n, outward) < 0] *= -1
    cloud.normals = to_open3d(n).points
    return MapCloud(np.asarray(cloud.points), n.copy(), fpfh(cloud, voxel))


def scan_at(pose, rng, points=None, reach: float = 10.0) -> dict[str, np.ndarray]:
    """What a sensor at ``pose`` returns: the room's surface points in reach, in the sensor's frame, with noise
    (no occlusion: the room is nearly convex), as the env's cloud observation."""
    points = room_surfaces(0.12)[0] if points is None else points
    near = np.hypot(points[:, 0] - pose[0], points[:, 1] - pose[1]) < reach
    local = points[near] - [pose[0], pose[1], 0.0]
    c, s = np.cos(-pose[2]), np.sin(-pose[2])
    cloud = np.column_stack(
        [c * local[:, 0] - s * local[:, 1], s * local[:, 0] + c * local[:, 1], local[:, 2] - HEIGHT]
    )
    cloud += rng.normal(0, 0.01, cloud.shape)
    return {"cloud": cloud.astype(np.float32), "cloud_mask": np.ones(len(cloud), dtype=np.int8)}


def observation(cloud: dict[str, np.ndarray], odom, t: float) -> dict[str, np.ndarray]:
    return {**cloud, "odom": np.asarray(odom, float), "time": np.array([t]), "cloud_time": np.array([t])}


def test_ransac_finds_the_pose_from_matches_with_outliers_and_is_seeded():
    rng = np.random.default_rng(0)
    scan = np.column_stack([rng.uniform(-5, 5, (300, 2)), rng.uniform(0, 3, 300)])
    truth = np.array([4.0, -2.0, 0.7])
    matched = transform(scan, truth)
    wrong = rng.random(300) < 0.6  # 60 % of the matches point anywhere
    matched[wrong] = np.column_stack([rng.uniform(-10, 10, (wrong.sum(), 2)), rng.uniform(0, 3, wrong.sum())])
    poses, inliers = ransac_poses(scan, matched, np.random.default_rng(1))
    assert np.hypot(*(poses[0, :2] - truth[:2])) < 0.1 and abs(wrap_angle(poses[0, 2] - truth[2])) < 0.02
    assert inliers[0] >= 100 and list(inliers) == sorted(inliers, reverse=True)
    again, _ = ransac_poses(scan, matched, np.random.default_rng(1))
    np.testing.assert_array_equal(poses, again)
    # heights must agree: with the matches lifted by 1 m, only chance pairs remain, and none is the truth
    lifted = matched + np.array([0.0, 0.0, 1.0])
    poses, inliers = ransac_poses(scan, lifted, np.random.default_rng(1), SearchConfig())
    assert not np.any(np.hypot(poses[:, 0] - truth[0], poses[:, 1] - truth[1]) < 0.5) and inliers.max() < 30


def test_distinct_best_keeps_one_pose_per_place():
    poses = np.array([[0, 0, 0], [0.2, 0, 0], [5, 0, 0], [0, 0, 3.0]])
    _, scores = distinct_best(poses, np.array([10, 9, 8, 7]), 5, 1.0, np.radians(20))
    np.testing.assert_array_equal(scores, [10, 8, 7])


def test_planar_icp_pulls_an_offset_scan_onto_the_map():
    m = room_map()
    icp = PlanarIcp(m.points, m.normals)
    truth = np.array([5.0, 2.5, 0.4])
    rng = np.random.default_rng(0)
    obs = scan_at(truth, rng)
    scan = obs["cloud"].astype(float) + np.array([0, 0, HEIGHT])
    pose = icp.align(scan, truth + np.array([0.3, -0.25, np.radians(6)]), max_distance=1.0, iterations=30)
    assert np.hypot(*(pose[:2] - truth[:2])) < 0.03 and abs(wrap_angle(pose[2] - truth[2])) < np.radians(0.5)
    assert icp.fitness(scan, pose, 0.3) > 0.95 > icp.fitness(scan, truth + np.array([1.0, 0, 0]), 0.3)


def test_localizes_globally_tracks_and_recovers_from_a_kidnap():
    rng = np.random.default_rng(3)
    surfaces = room_surfaces(0.12)[0]
    loc = RegistrationLocalizer(room_map(), RegistrationConfig(global_period_s=0.0, confirm_updates=1))
    loc.reset(seed=0)
    start = np.array([2.0, 2.0, 0.3])
    estimate = loc.update(observation(scan_at(start, rng, surfaces), (0.0, 0.0, 0.0), 0.0))
    assert loc.tracking and np.hypot(*(estimate.pose[:2] - start[:2])) < 0.1 and estimate.status == "localized"
    # drive 1 m along the robot's heading with odometry that says 0.95 m: ICP takes out the difference
    moved = start + np.array([np.cos(0.3), np.sin(0.3), 0.0])
    estimate = loc.update(observation(scan_at(moved, rng, surfaces), (0.95, 0.0, 0.0), 2.0))
    assert np.hypot(*(estimate.pose[:2] - moved[:2])) < 0.05
    # kidnapped to the other wing; the odometry does not know
    elsewhere = np.array([9.5, 2.0, 2.5])
    statuses = []
    for step in range(6):
        estimate = loc.update(observation(scan_at(elsewhere, rng, surfaces), (0.95, 0.0, 0.0), 2.1 + 0.1 * step))
        statuses.append(estimate.status)
    assert loc.tracking and np.hypot(*(estimate.pose[:2] - elsewhere[:2])) < 0.1
    assert "lost" in statuses and statuses[-1] == "localized"  # it said so while it searched
    assert abs(wrap_angle(estimate.pose[2] - elsewhere[2])) < np.radians(2)


def test_bad_input_is_named_and_an_empty_scan_keeps_a_finite_estimate():
    loc = RegistrationLocalizer(room_map())
    loc.reset(seed=0, initial_pose=np.array([2.0, 2.0, 0.0]))
    with pytest.raises(ValueError, match="'cloud' has shape"):
        loc.update({"cloud": np.zeros((5, 2)), "odom": np.zeros(3), "time": np.zeros(1), "cloud_time": np.zeros(1)})
    with pytest.raises(ObservationError, match="no 'cloud'"):
        loc.update({"odom": np.zeros(3), "time": np.zeros(1), "cloud_time": np.zeros(1)})
    empty = {"cloud": np.zeros((100, 3), np.float32), "cloud_mask": np.zeros(100, np.int8)}
    estimate = loc.update(observation(empty, (0.0, 0.0, 0.0), 0.0))
    assert np.all(np.isfinite(estimate.pose)) and np.allclose(estimate.pose, [2.0, 2.0, 0.0])
    with pytest.raises(ValueError, match="min_fitness"):
        RegistrationConfig(min_fitness=0.0)


def test_a_found_pose_is_confirmed_by_tracking_and_its_covariance_is_icps():
    rng = np.random.default_rng(3)
    surfaces = room_surfaces(0.12)[0]
    loc = RegistrationLocalizer(room_map(), RegistrationConfig(global_period_s=0.0))
    loc.reset(seed=0)
    start = np.array([2.0, 2.0, 0.3])
    statuses = []
    for step in range(12):  # standing still, a scan every 0.1 s
        estimate = loc.update(observation(scan_at(start, rng, surfaces), (0.0, 0.0, 0.0), 0.1 * step))
        statuses.append(estimate.status)
    assert statuses[0] != "localized" and statuses[-1] == "localized"  # 10 tracked scans confirm the find
    sigma = np.sqrt(np.diag(estimate.covariance))
    assert np.all(sigma[:2] < 0.15) and sigma[2] < np.radians(3)  # ICP's fit and the voxel, not a constant
    assert np.all(sigma[:2] >= 0.25 / np.sqrt(12) - 1e-9)  # never below the voxel's quantization
