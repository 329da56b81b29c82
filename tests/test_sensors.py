from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from pimm_agents.amcl.localizer import Amcl, AmclConfig
from pimm_agents.experiments.replay import replay_bag, replay_specs
from pimm_agents.experiments.runner import run_shared
from pimm_agents.scoring.trial import TrialSpec
from pimm_env.bags.record import record_scenario
from pimm_env.driving.rollout import drive
from pimm_env.envs.base_env import SimConfig
from pimm_env.envs.iilab_env import IILabEnv
from pimm_env.mapping.derived_maps import ensure_derived_maps
from pimm_env.sim.lidar import beam_angles_2d, beam_bearings_2d, mount_rotation, to_robot_frame
from pimm_env.sim.sensors import LIDAR_2D, sensor_layouts
from pimm_env.world.files import load_world
from tests.rooms import ROUTES

AMCL = {"max_particles": 500, "min_particles": 100}


def test_presets_lay_out_the_beams_as_their_datasheets():
    hokuyo = beam_angles_2d(LIDAR_2D["hokuyo-utm30lx"])
    assert len(hokuyo) == 1081 and np.degrees(hokuyo[[0, -1]]) == pytest.approx([-135, 135])
    assert np.degrees(np.diff(hokuyo)) == pytest.approx(np.full(1080, 0.25))
    sick = beam_angles_2d(LIDAR_2D["sick-lms200"])
    assert len(sick) == 181 and np.degrees(sick[[0, -1]]) == pytest.approx([-90, 90])
    thesis = beam_angles_2d(LIDAR_2D["thesis"])  # a full circle: -180 deg included, +180 deg (the same) not
    assert len(thesis) == 360 and np.degrees(thesis[[0, -1]]) == pytest.approx([-180, 179])
    lidar3d, lidar2d = sensor_layouts("sick-lms200")
    assert lidar2d.beams == 181 and lidar3d.layers == 40  # a 2D preset keeps the thesis's 3D LiDAR
    with pytest.raises(
        ValueError, match="unknown sensor preset 'velodyne'; valid: hokuyo-utm30lx, os0-64, os1-128, sick"
    ):
        sensor_layouts("velodyne")
    with pytest.raises(ValueError, match="angle_min_deg < angle_max_deg"):
        replace(LIDAR_2D["thesis"], angle_min_deg=10.0, angle_max_deg=-10.0)


def test_the_env_takes_a_preset_by_name(room_file: Path):
    ensure_derived_maps(load_world(room_file))
    env = IILabEnv(world=room_file, sensors="sick-lms200")
    obs, _ = env.reset(seed=0, options={"pose": [1.0, 1.0, 0.0]})
    assert obs["scan"].shape == (181,) and env.observation_space["scan"].shape == (181,)
    assert env.observation_space.contains(obs)
    ahead = obs["scan"][90]  # straight ahead: the east wall, 5 m away
    assert ahead == pytest.approx(5.0, abs=0.05)
    env.close()


def test_amcl_knows_where_its_laser_is_mounted(room_file: Path):
    mounted = replace(SimConfig().lidar2d, mount_x=0.25, mount_y=0.1, mount_yaw_deg=90.0)
    config = replace(SimConfig(), lidar2d=mounted)
    ensure_derived_maps(load_world(room_file))
    env = IILabEnv(world=room_file, config=config, terminate_on_collision=False)
    amcl = Amcl(ensure_derived_maps(load_world(room_file)).occupancy, AmclConfig(max_particles=500), lidar=mounted)
    amcl.reset(seed=1, initial_pose=np.array([1.0, 1.0, 0.0]))
    errors = []

    def step(obs, info):
        errors.append(np.hypot(*(amcl.update(obs).pose[:2] - info["true_pose"][:2])))

    obs, info = env.reset(seed=1, options={"pose": [1.0, 1.0, 0.0]})
    step(obs, info)
    drive(env, np.array([[1.0, 1.0], [4.0, 1.0], [4.0, 3.0], [1.5, 3.0]]), 0.5, step)
    env.close()
    assert np.median(errors[len(errors) // 2 :]) < 0.1
    assert np.degrees(beam_bearings_2d(mounted)[0]) == pytest.approx(-90.0)


def test_a_hokuyo_bag_replays_to_the_live_run(room_file: Path, tmp_path: Path):
    (room_file.parent / "scenarios.yaml").write_text(ROUTES)
    world = str(room_file)
    ensure_derived_maps(load_world(room_file))
    bag = record_scenario("there", tmp_path / "bag", world, seed=1, sensors="hokuyo-utm30lx", clouds=False)
    (spec,) = replay_specs(bag, ["amcl"], {"amcl": AMCL}, 1, world)
    assert spec.sensors == str(bag / "sensors.yaml")  # the layouts recorded with the bag
    assert sensor_layouts(spec.sensors) == sensor_layouts("hokuyo-utm30lx")
    live = run_shared([TrialSpec("there", "amcl", 0, 1, world, AMCL, "hokuyo-utm30lx")])[0]
    (replayed,), _ = replay_bag(bag, [spec], map_path=room_file.parent / "occupancy.yaml")
    assert np.array_equal(live.log.estimate, replayed.log.estimate) and len(replayed.log) > 100
    # The room is nearly symmetric under a half turn (only the post tells): from a global start AMCL took the
    # mirror image in 2 of seeds 1-4 with this LiDAR, so this seed shows the replay, not a convergence rate.
    assert replayed.metrics.converged and replayed.metrics.position_error_m < 0.2


@pytest.mark.expensive
def test_amcl_converges_on_a_hokuyo_bag_of_the_iilab(tmp_path: Path):
    # a_c_b with hokuyo-utm30lx, seeds 0-4, live: 5 of 5 converged (34.6 s, 0.98 m); area_b: 2 of 5 (2026-11-23)
    bag = record_scenario("a_c_b", tmp_path / "bag", "iilab", seed=0, sensors="hokuyo-utm30lx", clouds=False)
    assert sum(p.stat().st_size for p in bag.rglob("*")) < 20e6  # no clouds: a small bag
    (spec,) = replay_specs(bag, ["amcl"], {}, 0, "iilab")
    (result,), has_truth = replay_bag(bag, [spec], map_path=Path("maps/iilab/occupancy.yaml"))
    assert has_truth and result.metrics.converged


def test_a_tilted_offset_3d_lidar_is_simulated_from_its_mount_and_turned_back_by_to_robot_frame(room_file: Path):
    ensure_derived_maps(load_world(room_file))
    tilted = replace(
        SimConfig().lidar3d, mount_x=0.3, mount_y=-0.1, height=0.8, mount_pitch_deg=20.0, mount_roll_deg=5.0
    )
    env = IILabEnv(world=room_file, config=replace(SimConfig(), lidar3d=tilted))
    obs, info = env.reset(seed=0, options={"pose": [2.0, 2.0, 0.7]})
    env.close()
    mask = obs["cloud_mask"].astype(bool)
    raw, robot = obs["cloud"][mask], to_robot_frame(obs["cloud"], tilted)[mask]
    floor, ceiling = info["labels"][mask] == 2, info["labels"][mask] == 1
    assert np.abs(robot[floor, 2] + 0.8).max() < 0.05  # the floor 0.8 m under the sensor, level
    assert np.abs(robot[ceiling, 2] - 2.2).max() < 0.05  # the 3 m ceiling
    assert np.ptp(raw[floor, 2]) > 1.0  # in the sensor's own frame the floor slopes
    c, s = np.cos(0.7), np.sin(0.7)  # in the map frame the walls' faces are x = 0, x = 6, y = 0, y = 4
    walls = robot[info["labels"][mask] == 0]
    x, y = 2.0 + c * walls[:, 0] - s * walls[:, 1], 2.0 + s * walls[:, 0] + c * walls[:, 1]
    on_a_face = (np.abs(x) < 0.05) | (np.abs(x - 6) < 0.05) | (np.abs(y) < 0.05) | (np.abs(y - 4) < 0.05)
    assert len(walls) > 100 and on_a_face.mean() > 0.99
    thesis = SimConfig().lidar3d
    assert to_robot_frame(obs["cloud"], thesis) is obs["cloud"]  # the thesis's mount: no copy, no change
    with pytest.raises(ValueError, match="prism.*roll or pitch"):
        IILabEnv(world=room_file, config=replace(SimConfig(), lidar3d=tilted, ray_caster="prism"))


def test_mount_rotation_is_a_urdf_rpy(room_file: Path):
    turn = mount_rotation(replace(SimConfig().lidar3d, mount_yaw_deg=90.0))
    assert turn @ np.array([1.0, 0.0, 0.0]) == pytest.approx([0.0, 1.0, 0.0])
    pitch = mount_rotation(replace(SimConfig().lidar3d, mount_pitch_deg=90.0))
    assert pitch @ np.array([1.0, 0.0, 0.0]) == pytest.approx([0.0, 0.0, -1.0])  # nose down
    both = mount_rotation(replace(SimConfig().lidar3d, mount_roll_deg=30.0, mount_pitch_deg=-10.0, mount_yaw_deg=45.0))
    assert both @ both.T == pytest.approx(np.eye(3)) and np.linalg.det(both) == pytest.approx(1.0)


def test_a_recorded_bag_carries_the_3d_lidar_mount_and_replay_reads_it(room_file: Path, tmp_path: Path):
    (room_file.parent / "scenarios.yaml").write_text(ROUTES)
    ensure_derived_maps(load_world(room_file))
    sensors = tmp_path / "tilted.yaml"
    sensors.write_text("lidar3d: {layers: 8, points_per_layer: 90, mount_x: 0.2, mount_pitch_deg: 12.0}\n")
    bag = record_scenario("there", tmp_path / "bag", str(room_file), seed=1, sensors=str(sensors))
    (spec,) = replay_specs(bag, ["registration"], {}, 1, str(room_file))
    lidar3d = sensor_layouts(spec.sensors)[0]
    assert (lidar3d.mount_x, lidar3d.mount_pitch_deg, lidar3d.layers) == (0.2, 12.0, 8)
