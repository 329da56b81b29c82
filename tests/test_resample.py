from pathlib import Path

import numpy as np

from pimm_agents.perception.resample import LayoutResampler
from pimm_env.envs.iilab_env import IILabEnv
from pimm_env.mapping.derived_maps import ensure_derived_maps
from pimm_env.sim.lidar import Lidar3DConfig
from pimm_env.sim.sensors import LIDAR_3D
from pimm_env.world.files import load_world


def test_the_networks_own_layout_resamples_to_itself():
    layout = Lidar3DConfig()
    rng = np.random.default_rng(0)
    cloud = rng.normal(size=(layout.num_points, 3)).astype(np.float32)
    mask = rng.random(layout.num_points) < 0.8
    out, out_mask = LayoutResampler(layout, layout)(cloud, mask)
    assert np.array_equal(out_mask, mask) and np.array_equal(out[mask], cloud[mask])


def test_an_os0_scan_read_as_the_thesis_layout_sees_what_the_thesis_lidar_sees(room_file: Path):
    ensure_derived_maps(load_world(room_file))
    scans = {}
    for sensors in ("thesis", "os0-64"):
        env = IILabEnv(world=room_file, sensors=sensors)
        obs, _ = env.reset(seed=0, options={"pose": [2.0, 1.5, 0.3]})
        scans[sensors] = (obs["cloud"], obs["cloud_mask"].astype(bool))
        env.close()
    assert len(scans["os0-64"][0]) == 64 * 1024
    thesis = Lidar3DConfig()
    cloud, mask = LayoutResampler(LIDAR_3D["os0-64"], thesis)(*scans["os0-64"])
    assert cloud.shape == (thesis.num_points, 3)
    both = mask & scans["thesis"][1]
    ranges = np.linalg.norm(cloud[both], axis=1), np.linalg.norm(scans["thesis"][0][both], axis=1)
    assert np.median(np.abs(ranges[0] - ranges[1])) < 0.05  # the same surfaces, nearly the same rays
    elevations = np.degrees(np.arcsin(scans["thesis"][0][scans["thesis"][1], 2] / np.linalg.norm(
        scans["thesis"][0][scans["thesis"][1]], axis=1)))  # fmt: skip
    assert elevations.max() > 50 and not mask.reshape(40, 360)[-1].any()  # the OS0 does not look 60 deg up
