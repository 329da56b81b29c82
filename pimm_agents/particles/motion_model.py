"""Odometry motion models: move particles by the odometry displacement, with noise."""

from __future__ import annotations

import numpy as np

from pimm_env.geometry import wrap_angle


def odometry_delta(previous: np.ndarray, current: np.ndarray) -> tuple[float, float, float]:
    """The motion between two odometry poses as (rotation 1, translation, rotation 2) in the robot frame."""
    dx, dy = current[0] - previous[0], current[1] - previous[1]
    translation = float(np.hypot(dx, dy))
    # Below 1 cm the heading of the displacement is noise: treat it as a turn on the spot (as nav2 does).
    rot1 = 0.0 if translation < 0.01 else float(wrap_angle(np.arctan2(dy, dx) - previous[2]))
    rot2 = float(wrap_angle(wrap_angle(current[2] - previous[2]) - rot1))
    return rot1, translation, rot2


def sample_differential(
    poses: np.ndarray,
    delta: tuple[float, float, float],
    alphas: tuple[float, float, float, float],
    rng: np.random.Generator,
) -> np.ndarray:
    """The sampling odometry model of Probabilistic Robotics (table 5.6), as nav2's DifferentialMotionModel.

    alpha1: rotation noise from rotation, alpha2: rotation from translation, alpha3: translation from
    translation, alpha4: translation from rotation. A rotation's noise is measured against the nearer of
    0 and pi, so driving backwards does not count as a half turn.
    """
    rot1, trans, rot2 = delta
    a1, a2, a3, a4 = alphas
    rot1_size = min(abs(rot1), abs(float(wrap_angle(rot1 - np.pi))))
    rot2_size = min(abs(rot2), abs(float(wrap_angle(rot2 - np.pi))))
    n = len(poses)
    rot1_hat = rot1 - rng.normal(0.0, np.sqrt(a1 * rot1_size**2 + a2 * trans**2), n)
    trans_hat = trans - rng.normal(0.0, np.sqrt(a3 * trans**2 + a4 * rot1_size**2 + a4 * rot2_size**2), n)
    rot2_hat = rot2 - rng.normal(0.0, np.sqrt(a1 * rot2_size**2 + a2 * trans**2), n)
    heading = poses[:, 2] + rot1_hat
    out = np.empty_like(poses)
    out[:, 0] = poses[:, 0] + trans_hat * np.cos(heading)
    out[:, 1] = poses[:, 1] + trans_hat * np.sin(heading)
    out[:, 2] = wrap_angle(heading + rot2_hat)
    return out
