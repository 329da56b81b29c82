import numpy as np
import pytest

from pimm_env.sim.robot import DiffDriveRobot, RobotConfig, integrate_odometry


def test_odometry_equations():
    r, half_axle = 0.094, 0.165
    pose = integrate_odometry(np.zeros(3), 1.0, 1.0, r, half_axle)
    assert pose == pytest.approx([0.094, 0.0, 0.0])
    pose = integrate_odometry(np.zeros(3), -1.0, 1.0, r, half_axle)
    assert pose == pytest.approx([0.0, 0.0, 0.094 / 0.165])
    pose = integrate_odometry(np.array([1.0, 2.0, np.pi / 2]), 0.5, 1.5, r, half_axle)
    d, dth = r / 2 * 2.0, r / (2 * half_axle) * 1.0
    assert pose == pytest.approx(
        [1.0 + d * np.cos(np.pi / 2 + dth / 2), 2.0 + d * np.sin(np.pi / 2 + dth / 2), np.pi / 2 + dth]
    )


def test_perfect_robot_odometry_follows_the_truth():
    config = RobotConfig(radius_error=0.0, axle_error=0.0, slip=0.0, encoder_noise=0.0, encoder_ticks_per_rev=10**7)
    robot = DiffDriveRobot(config)
    rng = np.random.default_rng(0)
    robot.reset(np.zeros(3), rng)
    for _ in range(200):
        robot.step(0.5, 0.3, rng, lambda x, y: False)
    assert robot.odom == pytest.approx(robot.pose, abs=1e-4)
    assert robot.travelled == pytest.approx(0.5 * 200 * 0.032, rel=1e-6)


def test_noisy_odometry_drifts_but_quantizes_and_is_seeded():
    def drive(seed):
        robot = DiffDriveRobot(RobotConfig())
        rng = np.random.default_rng(seed)
        robot.reset(np.zeros(3), rng)
        for _ in range(600):
            robot.step(0.5, 0.05, rng, lambda x, y: False)
        return robot

    a, b, c = drive(1), drive(1), drive(2)
    assert np.array_equal(a.odom, b.odom) and not np.array_equal(a.odom, c.odom)
    assert 0 < np.linalg.norm(a.odom[:2] - a.pose[:2]) < 0.1 * a.travelled
    assert a.ticks.dtype == np.int64


def test_blocked_robot_stays_put_but_wheels_turn():
    robot = DiffDriveRobot(RobotConfig())
    rng = np.random.default_rng(0)
    robot.reset(np.zeros(3), rng)
    collided = robot.step(0.5, 0.0, rng, lambda x, y: x > 0.005)
    assert collided
    assert robot.pose[0] <= 0.005
    assert robot.odom[0] > 0.01, "odometry counts wheel turns even when the body is stopped"
