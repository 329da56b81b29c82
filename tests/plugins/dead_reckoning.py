"""A user's localizer, outside the project: dead reckoning from the start pose (the README's example)."""

import numpy as np

from pimm_agents import PoseEstimate
from pimm_env.geometry import carry


class DeadReckoning:
    """Reports the start pose (the origin if unknown) moved on by the wheel odometry: no map, no scans."""

    sensors = ("odom",)

    def __init__(self, name: str = "dead-reckoning", spread: float = 1.0) -> None:
        self.name, self.spread = name, spread
        self.reset()

    def reset(self, seed=None, initial_pose=None, initial_cov=None) -> None:
        self.start = np.zeros(3) if initial_pose is None else np.asarray(initial_pose, dtype=float)
        self.first_odom = None

    def update(self, obs) -> PoseEstimate:
        odom = np.asarray(obs["odom"], dtype=float)
        if self.first_odom is None:
            self.first_odom = odom
        x, y, theta = carry(self.start, self.first_odom, odom)
        cov = np.diag([self.spread**2, self.spread**2, 0.1])
        return PoseEstimate(float(x), float(y), float(theta), cov, float(obs["time"][0]))


def make(world, spread: float = 1.0) -> DeadReckoning:
    """The factory ``--localizers tests.plugins.dead_reckoning:make`` calls, with the params section's keys."""
    return DeadReckoning(spread=spread)


class CloudCounter(DeadReckoning):
    """Dead reckoning that also reads the 3D cloud (it counts the returns), so a simulation feeding it casts one."""

    sensors = ("odom", "cloud")

    def update(self, obs) -> PoseEstimate:
        self.returns = int(np.count_nonzero(obs["cloud_mask"]))
        return super().update(obs)


def make_cloud_reader(world) -> CloudCounter:
    return CloudCounter(name="cloud-counter")
