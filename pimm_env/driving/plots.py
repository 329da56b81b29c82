"""Figures of rollouts: true and odometry paths over the map."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from pimm_env.driving.rollout import RolloutResult
from pimm_env.mapping.occupancy import OccupancyGrid


def plot_rollouts(occupancy: OccupancyGrid, results: Sequence[RolloutResult], path: Path) -> Path:
    """Top-down picture of each rollout's true path and its odometry, one panel per scenario in a grid of two
    columns; a kidnap's teleport is marked, not drawn as a line."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from pimm_env.envs.render import show_map

    n = max(1, len(results))
    cols = min(2, n)
    rows = int(np.ceil(n / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(7 * cols, 5 * rows), squeeze=False)
    for ax in axes.flat[n:]:
        ax.set_visible(False)
    for ax, result in zip(axes.flat, results, strict=False):
        show_map(ax, occupancy)
        true_path = result.true_path[:, :2].astype(float)
        jumps = np.nonzero(np.linalg.norm(np.diff(true_path, axis=0), axis=1) > 1.0)[0]  # a kidnap's teleport
        true_path = np.insert(true_path, jumps + 1, np.nan, axis=0)  # no line through the walls
        ax.plot(true_path[:, 0], true_path[:, 1], "-", color="tab:green", lw=1.5, label="true path")
        for jump in jumps:
            ax.plot(*result.true_path[jump + 1, :2], "X", color="tab:purple", ms=9, mec="k", label="kidnapped to")
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


def write_rollouts(
    folder: Path, world: str, seed: int, results: Sequence[RolloutResult], rows: dict, occupancy: OccupancyGrid
) -> dict:
    """``folder/rollouts.json`` (world, seed, a row per scenario) and ``folder/rollouts.png``; returns the record."""
    import json

    record = {"world": world, "seed": seed, "rollouts": rows}
    (Path(folder) / "rollouts.json").write_text(json.dumps(record, indent=2))
    plot_rollouts(occupancy, results, Path(folder) / "rollouts.png")
    return record
