"""A bag as a Gymnasium env: ``step`` ignores the action and serves the bag's next observation, so the same
evaluation wrappers that drive localizers in the simulator drive them on recorded data."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import gymnasium as gym
import numpy as np

from pimm_env.bags.read import Step
from pimm_env.envs.base_env import SimConfig
from pimm_env.envs.env_spaces import action_space, observation_space
from pimm_env.errors import BagError


class BagEnv(gym.Env):
    """Replays ``steps`` (from :func:`pimm_env.bags.read.read_steps`). ``reset()`` serves the first step;
    when the next step follows a kidnap, ``next_is_kidnap`` is true and ``reset(options={"kidnap": True})``
    serves it (as the simulator's kidnap reset would). ``info`` has the true pose (NaN without ground truth)
    and the fresh-scan flags."""

    def __init__(self, steps: Iterator[Step], config: SimConfig | None = None) -> None:
        self.config = config or SimConfig()
        self.action_space = action_space(self.config)
        self.observation_space = observation_space(self.config)
        self._steps = steps
        self._next: Step | None = None
        self.has_truth = False  # whether any step served had a true pose
        self.steps_without_truth = 0

    def _take(self) -> Step:
        step = self._next if self._next is not None else next(self._steps, None)
        if step is None:
            raise BagError("the bag has no more steps: reset the env to replay it again")
        self._next = next(self._steps, None)
        return step

    def skip_to_truth(self) -> int:
        """Pass over the steps before the first one with a true pose (a log's odometry before its first scan),
        so that the next ``reset`` serves that one; returns how many were passed over."""
        if self._next is None:
            self._next = next(self._steps, None)
        skipped = 0
        while self._next is not None and self._next.true_pose is None:
            self._next, skipped = next(self._steps, None), skipped + 1
        return skipped

    @property
    def done(self) -> bool:
        return self._next is None

    @property
    def next_is_kidnap(self) -> bool:
        return self._next is not None and self._next.kidnapped

    def _serve(self, step: Step) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        if step.true_pose is None:
            self.steps_without_truth += 1
        else:
            self.has_truth = True
        truth = np.full(3, np.nan) if step.true_pose is None else step.true_pose
        return step.obs, {"true_pose": truth, "fresh_scan": step.fresh_scan, "fresh_cloud": step.fresh_cloud}

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        return self._serve(self._take())

    def step(self, action):
        obs, info = self._serve(self._take())
        return obs, 0.0, False, self.done, info
