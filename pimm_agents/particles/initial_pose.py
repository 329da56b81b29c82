"""Particles drawn about a known start pose, as nav2's ``initial_pose`` with its covariance."""

from __future__ import annotations

import numpy as np

from pimm_env.errors import LocalizerError
from pimm_env.geometry import wrap_angle

#: nav2_amcl's default initial covariance: 0.5 m standard deviation in x and y, pi/12 rad in heading.
NAV2_INITIAL_COV = np.diag([0.25, 0.25, (np.pi / 12) ** 2])


def gaussian_poses(mean: np.ndarray, cov: np.ndarray | None, n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` poses (x, y, theta) drawn from N(mean, cov); ``cov`` None means nav2's default."""
    mean = np.asarray(mean, dtype=float)
    cov = NAV2_INITIAL_COV if cov is None else np.asarray(cov, dtype=float)
    if mean.shape != (3,) or not np.all(np.isfinite(mean)):
        raise LocalizerError(f"initial_pose must be 3 finite numbers [x, y, theta], got {mean.tolist()}")
    if cov.shape != (3, 3) or not np.all(np.isfinite(cov)):
        raise LocalizerError(f"initial_cov must be a finite 3 x 3 matrix, got shape {cov.shape}")
    poses = rng.multivariate_normal(mean, cov, n)
    poses[:, 2] = wrap_angle(poses[:, 2])
    return poses
