"""Pure-pursuit path following: turns a waypoint list into (linear, angular) velocity commands."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pimm_env.errors import EnvError
from pimm_env.geometry import wrap_angle


@dataclass(frozen=True)
class PursuitConfig:
    speed: float = 0.5  # m/s along straight stretches
    lookahead: float = 0.4  # m
    max_angular: float = 1.0  # rad/s
    turn_in_place: float = 0.8  # rad: heading errors above this are turned on the spot
    goal_tolerance: float = 0.10  # m
    #: where the path turns back by more than this (rad), the next segment is taken up within half the
    #: lookahead of the turn: otherwise the lookahead point wraps behind the robot and it stalls there
    turn_back: float = np.radians(100.0)


class PurePursuit:
    """Follows a polyline of waypoints; call :meth:`command` with the true pose each control step."""

    def __init__(self, waypoints: np.ndarray, config: PursuitConfig | None = None) -> None:
        self.path = np.asarray(waypoints, dtype=float).reshape(-1, 2)
        if len(self.path) < 2:
            raise EnvError(f"a path needs at least 2 waypoints, got {len(self.path)}")
        self.config = config or PursuitConfig()
        self.segment = 0
        self.done = False

    def _progress(self, position: np.ndarray) -> tuple[int, float]:
        """Index of the segment the robot is on and how far along it (0..1)."""
        while True:
            a, b = self.path[self.segment], self.path[self.segment + 1]
            ab = b - a
            t = float(np.dot(position - a, ab) / max(np.dot(ab, ab), 1e-12))
            last = self.segment == len(self.path) - 2
            if not last and (t >= 1.0 or self._turning_back(position)):
                self.segment += 1
                continue
            return self.segment, min(max(t, 0.0), 1.0)

    def _turning_back(self, position: np.ndarray) -> bool:
        a, b, c = self.path[self.segment : self.segment + 3]
        u, v = b - a, c - b
        cosine = float(np.dot(u, v) / max(np.linalg.norm(u) * np.linalg.norm(v), 1e-12))
        near = float(np.linalg.norm(b - position)) < self.config.lookahead / 2
        return near and cosine < np.cos(self.config.turn_back)

    def _lookahead_point(self, position: np.ndarray) -> np.ndarray:
        segment, t = self._progress(position)
        point = self.path[segment] + t * (self.path[segment + 1] - self.path[segment])
        remaining = self.config.lookahead
        while True:
            end = self.path[segment + 1]
            gap = float(np.linalg.norm(end - point))
            if gap >= remaining or segment == len(self.path) - 2:
                if gap == 0:
                    return end
                return point + (end - point) * min(1.0, remaining / gap)
            remaining -= gap
            point = end
            segment += 1

    def command(self, pose: np.ndarray) -> tuple[float, float]:
        c = self.config
        position = np.asarray(pose[:2], dtype=float)
        goal = self.path[-1]
        if self.segment == len(self.path) - 2 and np.linalg.norm(goal - position) < c.goal_tolerance:
            self.done = True
            return 0.0, 0.0
        target = self._lookahead_point(position)
        heading_error = float(wrap_angle(np.arctan2(target[1] - position[1], target[0] - position[0]) - pose[2]))
        if abs(heading_error) > c.turn_in_place:
            return 0.0, float(np.clip(2.0 * heading_error, -c.max_angular, c.max_angular))
        distance = float(np.linalg.norm(target - position))
        curvature = 2.0 * np.sin(heading_error) / max(distance, 1e-6)
        speed = c.speed * max(0.3, np.cos(heading_error))
        near_goal = float(np.linalg.norm(goal - position))
        if self.segment == len(self.path) - 2:
            speed = min(speed, max(0.1, near_goal))
        angular = float(np.clip(speed * curvature, -c.max_angular, c.max_angular))
        return float(speed), angular
