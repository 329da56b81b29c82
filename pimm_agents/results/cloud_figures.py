"""Pictures of one labelled scan: from above and from the side, each point coloured by its class, corners marked."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from pimm_env.envs.render import CLASS_COLORS
from pimm_env.world.semantics import CLASS_NAMES

#: at most this many points are drawn (an even spread over the scan), so a million-point cloud draws quickly
MAX_DRAWN = 60_000


def draw_labelled_cloud(
    points: np.ndarray,
    labels: np.ndarray,
    corners: np.ndarray,
    path: Path,
    title: str,
    reference_corners: np.ndarray | None = None,
) -> Path:
    """Top view (x, y) over side view (x, z), the middle 98 % of the points in frame, written to ``path`` (PNG)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    step = max(1, len(points) // MAX_DRAWN)
    shown, classes = np.asarray(points)[::step], np.asarray(labels)[::step]
    colors = CLASS_COLORS[np.clip(classes, 0, len(CLASS_COLORS) - 1)] / 255.0
    low, high = np.percentile(shown, 1, axis=0) - 1.0, np.percentile(shown, 99, axis=0) + 1.0
    fig, (top, side) = plt.subplots(2, 1, figsize=(9, 11), gridspec_kw={"height_ratios": [3, 1.2]})
    order = np.argsort(shown[:, 2])  # higher points over lower ones from above
    top.scatter(shown[order, 0], shown[order, 1], c=colors[order], s=0.4, linewidths=0)
    side.scatter(shown[:, 0], shown[:, 2], c=colors, s=0.4, linewidths=0)
    corners = np.asarray(corners).reshape(-1, 2)
    if reference_corners is not None and len(reference_corners):
        ref = np.asarray(reference_corners).reshape(-1, 2)
        top.scatter(ref[:, 0], ref[:, 1], s=90, facecolors="none", edgecolors="black", label="reference corner")
    if len(corners):
        top.scatter(corners[:, 0], corners[:, 1], marker="x", s=60, c="black", label="corner found")
    top.scatter([0], [0], marker="^", s=50, c="magenta", label="sensor")
    top.set_xlim(low[0], high[0])
    top.set_ylim(low[1], high[1])
    side.set_xlim(low[0], high[0])
    side.set_ylim(low[2] - 0.2, high[2] - 0.8)
    top.set_aspect("equal")
    top.set_xlabel("x (m)")
    top.set_ylabel("y (m)")
    top.set_title("from above")
    side.set_aspect("equal")
    side.set_xlabel("x (m)")
    side.set_ylabel("z (m)")
    side.set_title("from the side")
    for k, name in enumerate(CLASS_NAMES):
        side.scatter([], [], c=[CLASS_COLORS[k] / 255.0], s=20, label=name)
    side.legend(loc="upper right", fontsize=8, markerscale=1.5)
    top.legend(loc="upper right", fontsize=8)
    fig.suptitle(title)
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
