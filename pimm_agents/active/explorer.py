"""Exploring without a map: the primitive that heads for the most open direction not yet faced from about here.

Both the ``greedy`` baseline (policies.py) and the active env (env.py, its ``explore`` observation) keep one. It
reads only what a robot knows: the observation's 2D scan sectors and its odometry increments. The scan's sectors
are scored by their free range (up to 8 m), less 0.5 m per radian of turn to face them (of equally open ways, the
one needing least turning) and 3 m for each time the robot has already faced that way from about here (cells of
2 m in the odometry frame, 8 headings; driving on in one cell and heading counts once): it goes forward when the
best sector is within half a turn ahead (22.5 deg, and 5 deg of margin so that it does not turn back and forth
across a direction between two headings) and the way ahead is clear, and turns toward it otherwise. Corridors are
driven to their ends and rooms are looked into, which is where look-alike places differ.
"""

from __future__ import annotations

import numpy as np

from pimm_agents.active.primitives import FORWARD, LEFT, RIGHT, STOP_RANGE, blocked_ahead
from pimm_env.geometry import wrap_angle


def sector_bearings(n: int) -> np.ndarray:
    """The centres of the ``scan`` observation's ``n`` sectors (robot frame, from behind, counter-clockwise)."""
    return -np.pi + (np.arange(n) + 0.5) * 2 * np.pi / n


def sectors_blocked(scan: np.ndarray, stop_range: float = STOP_RANGE, turn: float = 0.0) -> bool:
    """The forward guard's test (``blocked_ahead``) on the ``scan`` observation's sectors (ranges in metres),
    each sector's nearest return taken at its centre and at both its edges: the guard itself reads every beam,
    and a return near a sector's edge, tested at the centre only, fell outside the lane the body sweeps while the
    guard stopped the robot at it (a policy chose forward three times at a pillar and stood). With ``turn``
    (rad), the test after turning that much on the spot."""
    n = len(scan)
    half = np.pi / n
    bearings = np.concatenate([sector_bearings(n) + k * half - turn for k in (-1, 0, 1)])
    return blocked_ahead(np.tile(np.asarray(scan, dtype=float), 3), bearings, stop_range)


class Explorer:
    """The exploring of the module docstring: called once per primitive with the env's observation, it keeps its
    dead reckoning and what it has faced up to date and returns the primitive that heads where it has not yet
    looked; on its own, it is what ``greedy`` does without a map."""

    CELL_M = 2.0
    HEADINGS = 8
    OPEN_M = 8.0
    SEEN_PENALTY_M = 3.0  # free range (m) a direction loses for each time it was already faced from here
    AHEAD_MARGIN = np.radians(5.0)
    TURN_COST_M = 0.5  # per radian of turn to face a direction

    def __init__(self, max_range: float = 20.0) -> None:
        self.max_range = max_range
        self.reset()

    def reset(self, seed: int | None = None) -> None:
        self.pose = np.zeros(3)  # dead-reckoned from the odometry increments, in the episode's own frame
        self.faced: dict[tuple[int, int, int], int] = {}
        self.last_faced: tuple[int, int, int] | None = None

    def __call__(self, observation: dict[str, np.ndarray]) -> int:
        dx, dy, dtheta = np.asarray(observation["odom_delta"], dtype=float) * np.array([1.0, 1.0, np.pi])
        c, s = np.cos(self.pose[2]), np.sin(self.pose[2])
        self.pose = np.array([self.pose[0] + c * dx - s * dy, self.pose[1] + s * dx + c * dy, self.pose[2] + dtheta])
        scan = np.asarray(observation["scan"], dtype=float) * self.max_range
        n = len(scan)
        bearings = sector_bearings(n)
        cell = (int(np.floor(self.pose[0] / self.CELL_M)), int(np.floor(self.pose[1] / self.CELL_M)))
        # open range up to OPEN_M, less a little per radian off ahead: of directions equally open (beyond OPEN_M
        # many are), the one needing the least turning wins, instead of the first sector's (behind the robot)
        score = np.minimum(scan, self.OPEN_M) - self.TURN_COST_M * np.abs(bearings)
        for i, bearing in enumerate(bearings):
            score[i] -= self.SEEN_PENALTY_M * self.faced.get((*cell, self._heading_bin(self.pose[2] + bearing)), 0)
        best = float(bearings[int(np.argmax(score))])
        facing = (*cell, self._heading_bin(self.pose[2]))
        if facing != self.last_faced:  # driving on in one cell and heading faces that way once, not at every step
            self.faced[facing] = self.faced.get(facing, 0) + 1
            self.last_faced = facing
        # within half a turn (and a margin: a best direction half a turn off either way would otherwise have the
        # robot turn back and forth across it) and clear ahead, in the cone and in the lane the body sweeps (with
        # the cone alone it chose forward, stopped by the guard, for the rest of an episode): drive on
        if abs(best) <= np.pi / 8 + self.AHEAD_MARGIN and not sectors_blocked(scan, STOP_RANGE + 0.2):
            return FORWARD
        return LEFT if best > 0 else RIGHT

    def _heading_bin(self, heading: float) -> int:
        return int(np.floor((wrap_angle(heading) + np.pi) / (2 * np.pi) * self.HEADINGS)) % self.HEADINGS
