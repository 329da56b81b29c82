"""The rival check's kept scans stacked for scoring, and the turn a fit gives a pose about them.

A place is scored against the kept scans by carrying it back along each scan's odometry motion (rivals.py,
scan_evidence.py). :class:`ScanStack` holds them as one array; its ``centre`` is where a fit turns a pose about
(kept_scans.py): turned about the robot, a small change of heading swings scans far back sideways, so
heading and sideways offset form one narrow valley for coordinate steps (docs/design.md).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class ScanStack:
    """Kept scans stacked for scoring: every wall point with its scan, and each scan's pose from now."""

    points: np.ndarray  # (P, 2) wall points, robot frame at their scan
    scan_of: np.ndarray  # (P,) their scan
    motions: np.ndarray  # (S, 3) each scan's robot pose in the robot's frame now
    centre: np.ndarray  # (2,) the points' mean in the robot's frame now: what a fit turns a pose about


def points_centre(points: np.ndarray, scan_of: np.ndarray, motions: np.ndarray) -> np.ndarray:
    """The mean (2,) of wall ``points`` (robot frame at their scan ``scan_of``) placed by their scans' ``motions``
    (robot frame now); the origin when there are none."""
    if len(points) == 0:
        return np.zeros(2)
    m = motions[scan_of]
    c, s = np.cos(m[:, 2]), np.sin(m[:, 2])
    x = m[:, 0] + c * points[:, 0] - s * points[:, 1]
    y = m[:, 1] + s * points[:, 0] + c * points[:, 1]
    return np.array([x.mean(), y.mean()])


def turned(poses: np.ndarray, centre: np.ndarray, angle: float) -> np.ndarray:
    """Each pose (K, 3) turned by ``angle`` about the point ``centre`` (2,) given in the pose's own frame: the
    point stays where it is, the heading changes by ``angle``."""
    c, s = np.cos(poses[:, 2]), np.sin(poses[:, 2])
    px = poses[:, 0] + c * centre[0] - s * centre[1]
    py = poses[:, 1] + s * centre[0] + c * centre[1]
    heading = poses[:, 2] + angle
    ch, sh = np.cos(heading), np.sin(heading)
    return np.column_stack([px - (ch * centre[0] - sh * centre[1]), py - (sh * centre[0] + ch * centre[1]), heading])
