"""Figures of rollouts: true and odometry paths over the map."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from pimm_env.driving.rollout import RolloutResult
from pimm_env.mapping.occupancy import OccupancyGrid


def plot_rollouts(occupancy: OccupancyGrid, results: Sequence[RolloutResult], path: Path) -> Path:
    """Top-down picture of each rollout's true path and its odometry, one panel per scenario."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from pimm_env.envs.render import show_map

    n = max(1, len(results))
    fig, axes = plt.subplots(1, n, figsize=(7 * n, 5), squeeze=False)
    for ax, result in zip(axes[0], results, strict=False):
        show_map(ax, occupancy)
        ax.plot(result.true_path[:, 0], result.true_path[:, 1], "-", color="tab:green", lw=1.5, label="true path")
        if np.isfinite(result.final_drift_m):
            ax.plot(result.odom_path[:, 0], result.odom_path[:, 1], "--", color="tab:red", lw=1.0, label="odometry")
        ax.plot(*result.true_path[0, :2], "o", color="tab:blue", label="start")
        drift = "" if not np.isfinite(result.final_drift_m) else f", drift {result.final_drift_m:.2f} m"
        ax.set_title(f"{result.scenario}: {result.length_m:.1f} m in {result.duration_s:.0f} s{drift}")
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
        ax.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return Path(path)
