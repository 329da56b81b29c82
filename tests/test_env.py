import pickle
import warnings
from dataclasses import replace

import gymnasium as gym
import numpy as np
import pytest

import pimm_env  # noqa: F401  (registers the env)
from pimm_env import SimConfig

ENV_IDS = ["pimm/IILab-v1"]
# Warnings the checkers raise that do not apply to this env (anything else fails the test):
# the action is a cmd_vel in physical units (m/s, rad/s) by contract, not a normalized [-1, 1] box, and the
# cloud is an (N, 3) point array by contract, neither an image nor a flat vector.
ALLOWED = ("symmetric and normalized space", "normalized Box action space", "unconventional shape")


@pytest.fixture
def env():
    e = gym.make("pimm/IILab-v1")
    yield e
    e.close()


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_gymnasium_and_sb3_checkers(env_id):
    from gymnasium.utils.env_checker import check_env
    from stable_baselines3.common.env_checker import check_env as sb3_check_env

    for checker in (lambda e: check_env(e, skip_render_check=False), sb3_check_env):
        e = gym.make(env_id, render_mode="rgb_array").unwrapped
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            checker(e)
        unexpected = [str(w.message) for w in caught if not any(a in str(w.message) for a in ALLOWED)]
        assert not unexpected, unexpected
        e.close()


def _rollout(seed: int, steps: int = 40):
    e = gym.make("pimm/IILab-v1")
    obs, info = e.reset(seed=seed)
    trace = [obs["odom"].copy(), obs["cloud"].copy(), info["true_pose"].copy()]
    for _ in range(steps):
        obs, _, _, _, info = e.step(np.array([0.4, 0.2], dtype=np.float32))
        trace += [obs["odom"].copy(), obs["scan"].copy(), info["true_pose"].copy()]
    trace.append(obs["cloud"].copy())
    e.close()
    return trace


def test_same_seed_same_rollout():
    a, b, c = _rollout(3), _rollout(3), _rollout(4)
    assert all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))
    assert not all(np.array_equal(x, y) for x, y in zip(a, c, strict=True))


def test_env_pickles_mid_episode(env):
    env.reset(seed=0, options={"pose": [-10.0, 4.2, 0.0]})
    for _ in range(5):
        env.step([0.3, 0.0])
    clone = pickle.loads(pickle.dumps(env.unwrapped))
    a = clone.step([0.3, 0.1])
    b = env.unwrapped.step([0.3, 0.1])
    assert np.array_equal(a[0]["cloud"], b[0]["cloud"]) and np.array_equal(a[4]["true_pose"], b[4]["true_pose"])
    clone.close()


def test_observation_contents_and_scan_timing(env):
    obs, info = env.reset(seed=0, options={"pose": [-10.0, 4.2, 0.5]})
    assert obs["cloud"].shape == (14400, 3) and obs["cloud_mask"].shape == (14400,)
    mask = obs["cloud_mask"].astype(bool)
    assert mask.mean() > 0.9
    ranges = np.linalg.norm(obs["cloud"][mask], axis=1)
    assert ranges.max() <= 10.0 and np.all(obs["cloud"][~mask] == 0)
    labels = info["labels"]
    assert np.all((labels >= 0) == mask) and set(np.unique(labels[mask])) == {0, 1, 2, 3}
    assert np.all(obs["scan"] <= 10.0) and (obs["scan"] < 10.0).mean() > 0.5
    assert np.array_equal(info["true_pose"], [-10.0, 4.2, 0.5]) and np.array_equal(obs["odom"], np.zeros(3))
    fresh = []
    for _ in range(100):
        obs, _, _, _, info = env.step([0.0, 0.0])
        fresh.append(info["fresh_cloud"])
        assert obs["time"][0] >= obs["cloud_time"][0]
    assert sum(fresh) == pytest.approx(32, abs=1), "3D scans at 10 Hz over 3.2 s"


def test_kidnap_moves_the_robot_but_not_odometry_or_time(env):
    env.reset(seed=0, options={"pose": [-10.0, 4.2, 0.0]})
    for _ in range(20):
        obs, *_ = env.step([0.5, 0.0])
    odom, t = obs["odom"].copy(), obs["time"][0]
    obs, info = env.reset(options={"kidnap": [-20.0, 16.0, 1.0]})
    assert np.array_equal(info["true_pose"], [-20.0, 16.0, 1.0]) and info["area"] == "B"
    assert np.array_equal(obs["odom"], odom) and obs["time"][0] == t
    obs, info = env.reset(options={"kidnap": True})
    assert np.array_equal(obs["odom"], odom) and not np.allclose(info["true_pose"][:2], [-20.0, 16.0])


def test_random_start_is_free_and_seeded(env):
    poses = [env.reset(seed=s)[1]["true_pose"] for s in (1, 1, 2)]
    assert np.array_equal(poses[0], poses[1]) and not np.array_equal(poses[0], poses[2])
    for pose in poses:
        assert env.unwrapped.clearance_at(*pose[:2]) >= 0.25


def test_bad_reset_options_and_actions(env):
    env.reset(seed=0)
    with pytest.raises(ValueError, match="inside an obstacle"):
        env.reset(options={"pose": [-4.5, 2.7, 0.0]})  # a square column of Area A
    with pytest.raises(ValueError, match="outside the map"):
        env.reset(options={"pose": [50.0, 50.0, 0.0]})
    with pytest.raises(ValueError, match="unknown reset option"):
        env.reset(options={"teleport": [0, 0, 0]})
    with pytest.raises(ValueError, match="three finite numbers"):
        env.reset(options={"pose": [1.0, 2.0]})
    env.reset(options={})
    with pytest.raises(ValueError, match="finite"):
        env.step([np.nan, 0.0])
    with pytest.raises(ValueError, match="shape"):
        env.step([0.1, 0.2, 0.3])


def test_out_of_range_actions_are_clipped():
    e = gym.make("pimm/IILab-v1").unwrapped
    e.reset(seed=0, options={"pose": [-10.0, 4.2, 0.0]})
    e.step([100.0, 0.0])
    moved = e.robot.pose[0] + 10.0
    assert moved == pytest.approx(1.0 * 0.032, rel=0.1)
    e.close()


def test_collision_terminates(env):
    env.reset(seed=0, options={"pose": [-0.6, 4.0, 0.0]})
    for _ in range(200):
        _, _, terminated, _, info = env.step([0.5, 0.0])
        if terminated:
            break
    assert terminated and info["collision"]
    assert env.unwrapped.robot.pose[0] < -0.19 - 0.2


def test_render_and_idempotent_close():
    e = gym.make("pimm/IILab-v1", render_mode="rgb_array")
    e.reset(seed=0)
    image = e.render()
    assert image.dtype == np.uint8 and image.ndim == 3 and image.shape[2] == 3
    assert (image == [30, 60, 230]).all(axis=2).any(), "the robot is drawn"
    e.close()
    e.close()


def test_a_switched_off_lidar_casts_nothing():
    config = SimConfig()
    config = replace(config, lidar3d=replace(config.lidar3d, enabled=False))
    e = gym.make("pimm/IILab-v1", config=config).unwrapped
    obs, info = e.reset(seed=0)
    for _ in range(10):
        obs, *_, info = e.step([0.2, 0.0])
        assert not info["fresh_cloud"] and not obs["cloud_mask"].any() and (info["labels"] == -1).all()
    assert info["fresh_scan"] or obs["scan_time"][0] > 0, "the 2D LiDAR still scans"
    assert (obs["scan"] < config.lidar2d.max_range).any()
    e.close()


def test_switching_off_the_3d_lidar_leaves_odometry_and_2d_scans_as_they_were():
    """Each LiDAR draws noise from its own stream: a simulation that casts the cloud for one localizer feeds
    the others exactly what a cloud-less simulation would."""
    config = SimConfig()
    without = replace(config, lidar3d=replace(config.lidar3d, enabled=False))

    def trace(sim_config: SimConfig) -> list[np.ndarray]:
        e = gym.make("pimm/IILab-v1", config=sim_config)
        obs, _ = e.reset(seed=5)
        out = [obs["odom"].copy(), obs["scan"].copy()]
        for step in range(60):
            if step == 30:
                obs, _ = e.reset(options={"kidnap": True})
            else:
                obs, *_ = e.step(np.array([0.3, 0.4], dtype=np.float32))
            out += [obs["odom"].copy(), obs["scan"].copy()]
        e.close()
        return out

    with_cloud, without_cloud = trace(config), trace(without)
    assert all(np.array_equal(a, b) for a, b in zip(with_cloud, without_cloud, strict=True))


def test_a_pickled_env_with_walkers_furniture_a_fault_and_other_sensors_rolls_out_as_the_original():
    from pimm_env.envs.faults import parse_faults, with_faults

    env = with_faults(
        gym.make("pimm/IILab-v1", walkers=2, unmapped=1, sensors="hokuyo-utm30lx").unwrapped,
        parse_faults("dropout@0.5:0.3"),
    )
    env.reset(seed=5)
    action = np.array([0.4, 0.3], dtype=np.float32)
    for _ in range(10):
        env.step(action)
    clone = pickle.loads(pickle.dumps(env))
    assert clone.unwrapped.config == env.unwrapped.config and clone.unwrapped.config.walkers == 2
    for _ in range(25):  # through the dropout and the walkers' moves
        a, b = clone.step(action), env.step(action)
        assert all(np.array_equal(a[0][k], b[0][k]) for k in b[0])
        assert np.array_equal(a[4]["walkers"], b[4]["walkers"]) and np.array_equal(a[4]["unmapped"], b[4]["unmapped"])
        assert np.array_equal(a[4]["true_pose"], b[4]["true_pose"])
    clone.close()
    env.close()


def test_no_pybullet_scene_unless_the_bullet_caster_is_chosen_and_render_fps_follows_the_control_step():
    env = gym.make("pimm/IILab-v1").unwrapped
    assert env.scene is None
    assert env.metadata["render_fps"] == round(1 / env.config.robot.control_dt)
    env.close()
    bullet = gym.make("pimm/IILab-v1", config=replace(SimConfig(), ray_caster="bullet")).unwrapped
    assert bullet.scene is not None
    bullet.reset(seed=0)
    bullet.close()


def test_the_retired_v0_points_to_v1():
    with pytest.warns(DeprecationWarning, match="out of date"), pytest.raises(gym.error.DeprecatedEnv, match="v1"):
        gym.make("pimm/IILab-v0")
