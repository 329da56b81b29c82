"""A finished trial simulated again, with a watcher that keeps the frames of its animation."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from pimm_agents.experiments.runner import run_shared
from pimm_agents.results.video import EVERY_SCANS, Frame
from pimm_agents.scoring.trial import TrialSpec


def collect_frames(spec: TrialSpec, every: int = EVERY_SCANS, max_particles: int = 400) -> list[Frame]:
    """Simulate ``spec`` again and keep a frame at every ``every``-th fresh 2D scan."""
    from pimm_env.sim.lidar import beam_bearings_2d
    from pimm_env.sim.sensors import sensor_layouts

    lidar = sensor_layouts(spec.sensors)[1]
    angles = beam_bearings_2d(lidar)
    frames: list[Frame] = []
    scans = 0
    last_true: np.ndarray | None = None
    kidnapped = False

    def watch(localizers: Sequence[Any], obs: dict[str, Any], info: dict[str, Any]) -> None:
        nonlocal scans, last_true, kidnapped
        true = np.asarray(info["true_pose"], dtype=float)
        if last_true is not None and np.hypot(*(true[:2] - last_true[:2])) > 1.0:  # a teleport between two steps
            kidnapped = True
        last_true = true
        if not info.get("fresh_scan"):
            return
        scans += 1
        if (scans - 1) % every:
            return
        ranges = np.asarray(obs["scan"], dtype=float)
        hit = ranges < lidar.max_range
        bearing = angles[hit] + true[2]
        scan = np.column_stack([true[0] + ranges[hit] * np.cos(bearing), true[1] + ranges[hit] * np.sin(bearing)])
        localizer = localizers[0]
        inner = localizer.snapshot(max_particles) if hasattr(localizer, "snapshot") else {}
        frames.append(Frame(float(obs["time"][0]), true, info["estimate"].pose, scan, inner, kidnapped))

    run_shared([spec], watch=watch)
    return frames
