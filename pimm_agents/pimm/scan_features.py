"""What one scan gives PIMM's filter: its corner features as an array, its wall points, and both moved from the
robot's frame at the scan's time to its frame now by the odometry between (latency compensation, thesis 3.4.2)."""

from __future__ import annotations

from collections import deque

import numpy as np

from pimm_agents.corners.detector import FeatureList
from pimm_agents.pimm.config import WALL_BAND_M
from pimm_env.errors import LocalizerError
from pimm_env.geometry import compose, relative_motion
from pimm_env.world.semantics import SemanticClass

#: How far back (s) a feature's scan time can be looked up in the odometry (ours).
ODOMETRY_HISTORY_S = 5.0


def wall_points(cloud: np.ndarray, labels: np.ndarray, count: int) -> np.ndarray:
    """(M <= count, 2) x, y of the scan's wall-labelled points within the height band (``WALL_BAND_M``), spread
    evenly over their bearings (sensor frame)."""
    low, high = WALL_BAND_M
    band = (labels == int(SemanticClass.WALL)) & (cloud[:, 2] >= low) & (cloud[:, 2] <= high)
    xy = np.asarray(cloud[band, :2], dtype=float)
    if len(xy) <= count:
        return xy
    order = np.argsort(np.arctan2(xy[:, 1], xy[:, 0]))
    return xy[order[np.linspace(0, len(xy) - 1, count).astype(int)]]


def feature_array(features: FeatureList, min_sigma_pos: float = 0.0, min_sigma_theta: float = 0.0) -> np.ndarray:
    """(K, 5) x, y, theta, sigma_pos, sigma_theta of the features; sigma_pos = sqrt(var_x + var_y) (eq. 3.15)."""
    rows = [
        (
            f.x,
            f.y,
            f.theta,
            max(min_sigma_pos, float(np.sqrt(f.position_covariance[0, 0] + f.position_covariance[1, 1]))),
            max(min_sigma_theta, float(np.sqrt(f.orientation_variance))),
        )
        for f in features.features
    ]
    return np.array(rows, dtype=float).reshape(-1, 5)


def compensate(features: np.ndarray, odom_at_scan: np.ndarray, odom_now: np.ndarray) -> np.ndarray:
    """Features (x, y, theta, ...) or points (x, y) seen from the robot at scan time, in the robot frame now."""
    if len(features) == 0:
        return features
    motion = relative_motion(odom_at_scan, odom_now)  # the robot now, in its frame at scan time
    back = relative_motion(motion, np.zeros(3))  # scan-time frame in the frame of now
    moved = features.copy()
    if features.shape[1] == 2:
        moved[:] = compose(back, np.column_stack([features, np.zeros(len(features))]))[:, :2]
    else:
        moved[:, :3] = compose(back, features[:, :3])
    return moved


class OdometryHistory:
    """Recent (time, odometry) pairs; the odometry at a past time by interpolation."""

    def __init__(self, span_s: float = ODOMETRY_HISTORY_S) -> None:
        self.span_s = span_s
        self._items: deque[tuple[float, np.ndarray]] = deque()

    def clear(self) -> None:
        self._items.clear()

    def add(self, stamp: float, odom: np.ndarray) -> None:
        if self._items and stamp < self._items[-1][0]:
            self._items.clear()  # time went back: a new episode
        self._items.append((stamp, odom.copy()))
        while self._items and self._items[0][0] < stamp - self.span_s:
            self._items.popleft()

    def at(self, stamp: float) -> np.ndarray:
        """Odometry at ``stamp``, interpolated; clamped to the oldest and newest kept."""
        if not self._items:
            raise LocalizerError("no odometry recorded yet")
        times = np.array([t for t, _ in self._items])
        k = int(np.searchsorted(times, stamp))
        if k == 0:
            return self._items[0][1].copy()
        if k >= len(times):
            return self._items[-1][1].copy()
        (t0, a), (t1, b) = self._items[k - 1], self._items[k]
        u = (stamp - t0) / (t1 - t0) if t1 > t0 else 1.0
        return compose(a, u * relative_motion(a, b))[0]
