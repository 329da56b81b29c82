"""People and unmapped furniture: ray casting against boxes, where they are placed and how people walk, and
what the env's LiDARs make of them."""

import gymnasium as gym
import numpy as np
import pytest

import pimm_env  # noqa: F401  (registers pimm/IILab-v1)
from pimm_env.envs.iilab_env import IILabEnv
from pimm_env.sim.movers import Boxes, Walkers, cast_boxes, free_clearance, place_furniture
from pimm_env.world.semantics import SemanticClass

START = [-10.0, 4.2, 0.0]


def one_box(x=3.0, y=0.0, yaw=0.0, length=1.0, width=0.5, height=1.0) -> Boxes:
    return Boxes(np.array([[x, y]]), np.array([yaw]), np.array([[length / 2, width / 2]]), np.array([height]))


def test_rays_hit_a_box_where_its_faces_are():
    origin = np.array([0.0, 0.0, 0.5])
    directions = np.array([[1, 0, 0], [-1, 0, 0], [np.cos(0.05), np.sin(0.05), 0], [np.cos(1.0), 0, np.sin(1.0)]])
    ranges = cast_boxes(origin, directions.astype(float), one_box(), floor_z=0.0)
    assert ranges[0] == pytest.approx(2.5)  # the near face at x = 2.5
    assert np.isinf(ranges[1])  # behind the sensor
    assert ranges[2] == pytest.approx(2.5 / np.cos(0.05))
    assert np.isinf(ranges[3])  # steeply up: over the 1 m top
    turned = cast_boxes(origin, directions[:1].astype(float), one_box(yaw=np.pi / 2), floor_z=0.0)
    assert turned[0] == pytest.approx(2.75)  # turned 90 deg: the 0.5 m side faces the sensor
    inside = cast_boxes(np.array([3.0, 0.0, 0.5]), directions[:1].astype(float), one_box(), floor_z=0.0)
    assert inside[0] == pytest.approx(0.5)  # from inside, the far side


def test_walkers_and_furniture_are_seeded_stay_in_free_space_and_walk_at_their_speed():
    env = IILabEnv(walkers=4, unmapped=6, terminate_on_collision=False)
    occupancy = env.maps.occupancy
    _, first = env.reset(seed=3, options={"pose": START})
    _, again = env.reset(seed=3, options={"pose": START})
    np.testing.assert_array_equal(first["walkers"], again["walkers"])
    np.testing.assert_array_equal(first["unmapped"], again["unmapped"])
    _, other = env.reset(seed=4, options={"pose": START})
    assert not np.array_equal(first["unmapped"], other["unmapped"])
    clearance = free_clearance(occupancy)
    rows, cols, inside = occupancy.grid.cells_of(first["unmapped"][:, :2])
    assert inside.all() and np.all(clearance[rows, cols] < 0.6)  # along walls, off the middle of the room
    env.reset(seed=3, options={"pose": START})
    walkers = env.movers.walkers
    before = walkers.position.copy()
    steps = 50
    for _ in range(steps):
        env.robot.pose[:2] = [100.0, 100.0]  # far away: nobody waits for it
        walkers.step(0.032, env.robot.pose[:2])
    moved = np.hypot(*(walkers.position - before).T)
    assert np.all(moved <= walkers.speed * 0.032 * steps + 1e-6) and np.all(moved > 0.5 * walkers.speed * 0.032 * steps)
    rows, cols, inside = occupancy.grid.cells_of(walkers.position)
    assert inside.all() and np.all(clearance[rows, cols] > 0.3)
    env.close()


def test_a_walker_waits_while_the_robot_stands_ahead_of_it():
    env = IILabEnv(walkers=1, terminate_on_collision=False)
    env.reset(seed=0, options={"pose": START})
    walkers: Walkers = env.movers.walkers
    walkers.step(0.032, np.array([1e3, 1e3]))  # sets off, so it has a heading
    facing = np.array([np.cos(walkers.heading[0]), np.sin(walkers.heading[0])])
    robot = walkers.position[0] + 0.6 * facing
    held = walkers.position[0].copy()
    walkers.step(0.5, robot)
    np.testing.assert_array_equal(walkers.position[0], held)
    env.close()


def test_both_lidars_see_unmapped_furniture_as_clutter_the_maps_do_not_have():
    plain = IILabEnv(terminate_on_collision=False)
    obs_plain, _ = plain.reset(seed=0, options={"pose": START})
    plain.close()
    env = IILabEnv(unmapped=1, terminate_on_collision=False)
    env.reset(seed=0, options={"pose": START})
    # a cabinet of our own 1.7 m ahead in place of the drawn one, and both scans taken again
    env.movers.furniture = one_box(x=START[0] + 2.0, y=START[1], length=0.6, width=0.6, height=1.2)
    env._next_cloud = env._next_scan = env.sim_time
    env._sense()
    obs, info = env._observation(), env._info()
    ahead = np.argmin(np.abs(env._azimuths2d))
    assert obs["scan"][ahead] == pytest.approx(1.7, abs=0.05) and obs_plain["scan"][ahead] > 2.5
    points = obs["cloud"][obs["cloud_mask"].astype(bool)]
    labels = info["labels"][obs["cloud_mask"].astype(bool)]
    front = (np.abs(points[:, 0] - 1.7) < 0.05) & (np.abs(points[:, 1]) < 0.25) & (np.abs(points[:, 2]) < 0.4)
    assert front.sum() > 5 and np.all(labels[front] == int(SemanticClass.CLUTTER))
    assert not env.maps.occupancy.occupied[env.maps.occupancy.grid.cells_of(np.array([[-8.0, 4.2]]))[:2]].any()
    frame = IILabEnv(unmapped=3, walkers=2, render_mode="rgb_array", terminate_on_collision=False)
    frame.reset(seed=0, options={"pose": START})
    image = frame.render()
    frame.close()
    assert np.any(np.all(image == [255, 140, 0], axis=-1))  # drawn in orange
    env.close()


def test_bad_counts_are_named():
    with pytest.raises(ValueError, match="walkers must be a whole number >= 0, got -1"):
        IILabEnv(walkers=-1)
    with pytest.raises(ValueError, match="unmapped must be a whole number"):
        gym.make("pimm/IILab-v1", unmapped=2.5)
    occupancy = IILabEnv(terminate_on_collision=False).maps.occupancy
    assert len(place_furniture(occupancy, 0, np.random.default_rng(0))) == 0
