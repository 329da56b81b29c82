"""Record a scenario's sensor streams (and the truth) into a rosbag2, as a robot's drive would be recorded."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from pimm_env.bags.messages import KIDNAP, TOPICS, TYPES, laser_scan, odometry, point_cloud, typestore
from pimm_env.errors import BagError

#: A file beside the bag's own metadata saying what was recorded (world, scenario, seed, sensors).
RECORD_FILE = "pimm_record.yaml"
#: A sensors file beside it with the LiDARs' whole configuration, the 3D LiDAR's mount pose included.
SENSORS_FILE = "sensors.yaml"


class BagRecorder(gym.Wrapper):
    """Writes every observation the env gives into ``writer``: odometry and the truth at every step, each
    fresh scan and cloud, and a ``kidnap`` event when ``reset`` kidnaps the robot."""

    def __init__(self, env: gym.Env, writer: Any) -> None:
        super().__init__(env)
        from pimm_env.sim.lidar import beam_angles_2d

        self.store = typestore()
        self.writer = writer
        self.connections = {topic: writer.add_connection(topic, TYPES[topic], typestore=self.store)
                            for topic in TOPICS.values()}  # fmt: skip
        base: Any = env.unwrapped
        self.lidar2d, self.lidar3d = base.config.lidar2d, base.config.lidar3d
        self.angles = beam_angles_2d(self.lidar2d)
        self.messages = 0
        self._received = -1  # the bag's receive time (ns): the stamp, or 1 ns after the previous message

    def _write(self, topic: str, seconds: float, msg: Any) -> None:
        """Messages are received in the order written (a step's sensors, its truth, then its odometry, which
        closes the step), so a reader going by receive time sees each step whole even where stamps tie."""
        from pimm_env.bags.messages import nanoseconds

        raw = self.store.serialize_cdr(msg, TYPES[topic])
        self._received = max(nanoseconds(seconds), self._received + 1)
        self.writer.write(self.connections[topic], self._received, raw)
        self.messages += 1

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        obs, info = self.env.reset(seed=seed, options=options)
        kidnap = (options or {}).get("kidnap")
        if kidnap is not None and kidnap is not False:
            self._write(TOPICS["events"], float(obs["time"][0]), self.store.types["std_msgs/msg/String"](data=KIDNAP))
        self._record(obs, info, first=kidnap is None or kidnap is False)
        return obs, info

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        self._record(obs, info)
        return obs, reward, terminated, truncated, info

    def _record(self, obs: dict[str, np.ndarray], info: dict[str, Any], first: bool = False) -> None:
        t = float(obs["time"][0])
        if (info["fresh_cloud"] or first) and self.lidar3d.enabled:
            cloud_t = float(obs["cloud_time"][0])
            msg = point_cloud(self.store, cloud_t, obs["cloud"], obs["cloud_mask"], self.lidar3d.layers)
            self._write(TOPICS["points"], cloud_t, msg)
        if (info["fresh_scan"] or first) and self.lidar2d.enabled:
            scan_t = float(obs["scan_time"][0])
            self._write(TOPICS["scan"], scan_t, laser_scan(self.store, scan_t, obs["scan"], self.angles, self.lidar2d))
        self._write(TOPICS["truth"], t, odometry(self.store, t, info["true_pose"], "map"))
        self._write(TOPICS["odom"], t, odometry(self.store, t, obs["odom"], "odom"))  # last: closes the step


def record_scenario(
    scenario_name: str, out: Path, world: str = "iilab", seed: int = 0, sensors: str = "thesis", clouds: bool = True
) -> Path:
    """Drive ``scenario_name`` in ``world`` with ``seed`` and the LiDAR presets ``sensors``, and write it as the
    rosbag2 folder ``out`` (without ``clouds``: no 3D LiDAR, a 2D bag, a hundredth of the size)."""
    import yaml
    from rosbags.rosbag2 import Writer

    from pimm_env.driving.rollout import run
    from pimm_env.driving.scenarios import get_scenario
    from pimm_env.envs.base_env import SimConfig
    from pimm_env.envs.iilab_env import IILabEnv
    from pimm_env.sim.sensors import write_sensors_file
    from pimm_env.world.files import load_world

    out = Path(out)
    if out.exists():
        raise BagError(f"{out}: already exists; a bag is written to a new folder")
    loaded = load_world(world)
    scenario = get_scenario(scenario_name, loaded)
    config = SimConfig()
    if not clouds:
        config = replace(config, lidar3d=replace(config.lidar3d, enabled=False))
    env = IILabEnv(world=loaded, config=config, terminate_on_collision=False, sensors=sensors)
    with Writer(out, version=9) as writer:
        recorder = BagRecorder(env, writer)
        try:
            result = run(scenario, seed=seed, env=recorder)
        finally:
            recorder.close()
    record = {"world": world, "scenario": scenario_name, "seed": seed, "sensors": sensors, "clouds": clouds}
    record.update(completed=result.completed, sim_seconds=round(result.duration_s, 3), messages=recorder.messages)
    (out / RECORD_FILE).write_text(yaml.safe_dump(record, sort_keys=False))
    l3, l2 = env.config.lidar3d, env.config.lidar2d
    note = f"The LiDARs this bag was recorded with ({sensors}): layouts, noise, rates and mount poses."
    write_sensors_file(out / SENSORS_FILE, l3 if clouds else None, l2, note)
    return out
