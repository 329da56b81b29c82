"""The evaluation wrapper: drives a localizer with the env's observations and records truth and estimate."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np

from pimm_agents.localizer import STATUSES, Localizer, PoseEstimate, published_covariance
from pimm_agents.scoring.trial_log import TrialLog
from pimm_env.errors import ExperimentError

#: How a trial starts the localizer: ``global`` (pose unknown, the thesis's experiments) or ``known`` (the true
#: start pose with nav2's initial covariance, 0.5 m, 0.5 m, pi/12 rad standard deviations).
STARTS = ("global", "known")


class LocalizationRecorder(gym.Wrapper):
    """Feeds every observation to ``localizer`` and records (truth, estimate) at every fresh scan.

    ``reset`` resets the localizer too (from ``start``), except for a kidnap (``options={"kidnap": ...}``), which the
    localizer must discover by itself; the log marks where it happened. ``info["estimate"]`` carries the
    latest estimate. ``trial_log()`` returns what was recorded since the last full reset.
    """

    def __init__(self, env: gym.Env, localizer: Localizer, start: str = "global") -> None:
        super().__init__(env)
        if start not in STARTS:
            raise ExperimentError(f"start must be one of {STARTS}, got {start!r}")
        self.localizer = localizer
        self.start = start
        #: observations passed over before the localizer started (a replay's known start waits for the first
        #: true pose): counted with what its guard set aside, as ``before_start``
        self.passed_over = 0
        self._rows: list[tuple[float, float, np.ndarray, np.ndarray, np.ndarray, float, int, np.ndarray]] = []
        self._timings: list[dict[str, float]] = []
        self._kidnap_rows: list[int] = []  # the first row after each kidnap; metrics count from the last
        self._corners: list[np.ndarray] = []  # (k, 3): row, x, y
        self._last: PoseEstimate | None = None  # the newest estimate: what the guard set aside so far

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        obs, info = self.env.reset(seed=seed, options=options)
        kidnap = (options or {}).get("kidnap")
        if kidnap is None or kidnap is False:
            if self.start == "known":  # the true start, with nav2's initial covariance
                self.localizer.reset(seed=seed, initial_pose=np.asarray(info["true_pose"], dtype=float))
            else:
                self.localizer.reset(seed=seed)
            self._rows, self._timings, self._kidnap_rows, self._corners = [], [], [], []
            self._last = None
        else:
            self._kidnap_rows.append(len(self._rows))
        self._observe(obs, info, record=True)
        return obs, info

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        if info.get("kidnapped"):  # a fault wrapper teleported the robot: count from here, as after a reset
            self._kidnap_rows.append(len(self._rows))
        self._observe(obs, info, record=bool(info.get("fresh_scan") or info.get("fresh_cloud")))
        return obs, reward, terminated, truncated, info

    def _observe(self, obs: dict[str, np.ndarray], info: dict[str, Any], record: bool) -> None:
        estimate = self.localizer.update(obs)
        info["estimate"] = estimate
        if estimate.timings:
            self._timings.append(dict(estimate.timings))
        self._last = estimate
        if "corners" in estimate.timings:
            # corners found in this update (PIMM perceives a scan when it weighs with it, not always on arrival),
            # kept with this row, or with the last row when this step records none
            corners = estimate.inside.get("corners")
            if corners is not None and len(corners):
                row = np.full((len(corners), 1), float(len(self._rows) if record else max(len(self._rows) - 1, 0)))
                self._corners.append(np.hstack([row, np.asarray(corners, dtype=float)[:, :2]]))
        if record:
            covariance = np.asarray(estimate.covariance, dtype=float)
            time = float(np.asarray(obs["time"]).reshape(-1)[0])
            true = np.asarray(info["true_pose"], float)
            status = STATUSES.index(estimate.status)
            shown = published_covariance(estimate)
            published = np.array([shown[0, 0], shown[1, 1], shown[2, 2], shown[0, 1]])
            self._rows.append(
                (time, float(estimate.stamp), true, estimate.pose, np.diag(covariance), covariance[0, 1], status,
                 published)
            )  # fmt: skip

    def trial_log(self) -> TrialLog:
        if not self._rows:
            empty = np.zeros((0, 3))
            return TrialLog(np.zeros(0), np.zeros(0), empty, empty, empty, None, [])
        times, stamps, true, est, cov, cov_xy, status, published = zip(*self._rows, strict=True)
        return TrialLog(
            np.array(times),
            np.array(stamps),
            np.array(true),
            np.array(est),
            np.array(cov),
            self._kidnap_rows[-1] if self._kidnap_rows else None,
            list(self._timings),
            np.vstack(self._corners) if self._corners else np.zeros((0, 3)),
            tuple(self._kidnap_rows),
            np.array(status, dtype=np.int8),
            np.array(cov_xy),
            *guard_counts(self._last, self.passed_over),
            np.array(published),
        )


def guard_counts(estimate: PoseEstimate | None, passed_over: int = 0) -> tuple[dict[str, int], int]:
    """(observations set aside by kind, odometry re-bases) by the localizer's input guard since its last reset,
    as its newest ``estimate`` carries them, with ``passed_over`` as ``before_start``."""
    counts = {} if estimate is None else dict(estimate.set_aside)
    if passed_over:
        counts["before_start"] = passed_over
    return counts, 0 if estimate is None else estimate.rebases
