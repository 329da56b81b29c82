"""SE(2) pose math shared by the simulator and the localizers: poses are (x, y, theta) in one frame."""

from __future__ import annotations

import numpy as np


def compose(origin: np.ndarray, poses: np.ndarray) -> np.ndarray:
    """Poses (N, 3) given in the frame of ``origin`` (x, y, theta), expressed in the frame ``origin`` is in."""
    poses = np.asarray(poses, dtype=float).reshape(-1, 3)
    c, s = np.cos(origin[2]), np.sin(origin[2])
    x = origin[0] + c * poses[:, 0] - s * poses[:, 1]
    y = origin[1] + s * poses[:, 0] + c * poses[:, 1]
    return np.stack([x, y, wrap_angle(poses[:, 2] + origin[2])], axis=1)


def relative_motion(previous: np.ndarray, current: np.ndarray) -> np.ndarray:
    """``current`` expressed in the frame of ``previous`` (both (x, y, theta) in one frame)."""
    c, s = np.cos(previous[2]), np.sin(previous[2])
    dx, dy = current[0] - previous[0], current[1] - previous[1]
    return np.array([c * dx + s * dy, -s * dx + c * dy, wrap_angle(current[2] - previous[2])])


def carry(pose: np.ndarray, odom_then: np.ndarray, odom_now: np.ndarray) -> np.ndarray:
    """A map-frame pose known when the odometry read ``odom_then``, moved on by the odometry since."""
    return compose(pose, relative_motion(odom_then, odom_now))[0]


def moved_rigidly(poses: np.ndarray, origin: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Poses (N, 3) moved by the rigid motion that takes the pose ``origin`` to the pose ``target``."""
    turn = wrap_angle(target[2] - origin[2])
    c, s = np.cos(turn), np.sin(turn)
    d = poses[:, :2] - origin[:2]
    x = target[0] + c * d[:, 0] - s * d[:, 1]
    y = target[1] + s * d[:, 0] + c * d[:, 1]
    return np.column_stack([x, y, wrap_angle(poses[:, 2] + turn)])


def wrap_angle(angle: float | np.ndarray) -> float | np.ndarray:
    """Angle in [-pi, pi)."""
    return (np.asarray(angle) + np.pi) % (2 * np.pi) - np.pi


def rotation_onto_z(normal: np.ndarray) -> np.ndarray:
    """The smallest rotation that takes the unit vector ``normal`` onto (0, 0, 1) (Rodrigues)."""
    n = np.asarray(normal, dtype=float) / np.linalg.norm(normal)
    axis = np.cross(n, [0.0, 0.0, 1.0])
    s, c = np.linalg.norm(axis), float(n[2])
    if s < 1e-12:
        return np.eye(3) if c > 0 else np.diag([1.0, -1.0, -1.0])
    k = axis / s
    skew = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + s * skew + (1 - c) * skew @ skew
