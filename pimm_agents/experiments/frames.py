"""A finished trial simulated again, with a watcher that keeps the frames of its animation."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from pimm_agents.experiments.experiment import Outcome
from pimm_agents.experiments.runner import run_shared
from pimm_agents.results.video import EVERY_SCANS, Frame
from pimm_agents.scoring.trial import TrialSpec
from pimm_env.errors import ExperimentError


def collect_frames(spec: TrialSpec, every: int = EVERY_SCANS) -> list[Frame]:
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
        estimate = info["estimate"]
        inner = {key: value for key, value in estimate.inside.items() if key != "walls"}  # map-frame arrays
        modes = np.array([[h.x, h.y, h.theta] for h in estimate.hypotheses]).reshape(-1, 3)
        frames.append(Frame(float(obs["time"][0]), true, estimate.pose, scan, inner, kidnapped, estimate.status, modes))

    run_shared([spec], watch=watch)
    return frames


def write_videos(outcome: Outcome, which: str, progress: bool = True) -> None:
    """Simulate the chosen trials (``best``, ``worst`` or ``all``) of every scenario and localizer of a finished
    experiment again and write their animations under its folder's ``videos/``."""
    from tqdm import tqdm

    from pimm_agents.results.folder import file_safe
    from pimm_agents.results.video import chosen_trials, write_video
    from pimm_agents.scoring.metrics import best_and_worst
    from pimm_agents.scoring.summaries import grouped

    folder, results, maps = outcome.folder, outcome.results, outcome.maps
    if which not in ("best", "worst", "all") or maps is None:
        raise ExperimentError(f"videos: expected best, worst or all, of a run in one world; got {which!r}")
    jobs = []
    for (scenario, localizer), trials in grouped(results, [r.spec for r in results]).items():
        best, worst = best_and_worst([t.metrics for t in trials])
        for label, index in chosen_trials(which, best, worst, len(trials)):
            jobs.append((scenario, localizer, label, trials[index]))
    (Path(folder) / "videos").mkdir(exist_ok=True)
    for scenario, localizer, label, trial in tqdm(jobs, desc="videos", unit="video", disable=not progress):
        frames = collect_frames(trial.spec)
        title = f"{localizer}, {scenario}, {label} trial (seed {trial.spec.seed})"
        target = Path(folder) / "videos" / f"{file_safe(scenario)}_{file_safe(localizer)}_{label}"
        write_video(frames, maps.occupancy, maps.corners.xy, target, title)
