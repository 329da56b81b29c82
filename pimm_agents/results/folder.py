"""The results folder: summary.json, run.yaml, per-trial logs (thesis CSV, sidecar, TUM) and figures."""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from pimm_agents.results.figures import plot_summary, plot_trial
from pimm_agents.results.log_files import write_csv, write_sidecar
from pimm_agents.results.provenance import machine, provenance
from pimm_agents.scoring.metrics import (
    best_and_worst,
)
from pimm_agents.scoring.summaries import grouped, summary_of
from pimm_agents.scoring.trial import TrialResult
from pimm_env.mapping.occupancy import OccupancyGrid


def file_safe(name: str) -> str:
    """A localizer name fit for a file name: ``my_pkg.mod:make`` becomes ``my_pkg.mod-make``."""
    return "".join(c if c.isalnum() or c in "._-" else "-" for c in name)


def trial_stem(result: TrialResult) -> str:
    s = result.spec
    return f"{file_safe(s.case)}_{file_safe(s.name)}_trial{s.trial:02d}"


def write_results(
    folder: Path,
    results: Sequence[TrialResult],
    run_record: dict[str, Any],
    occupancy: OccupancyGrid | None,
    corners: np.ndarray | None = None,
) -> dict[str, Any]:
    """Write the results folder and return the summary: summary.json (with the run's record, the version,
    commit and machine); run.yaml unless the run wrote its own (``write_run_record``); per trial the thesis's
    CSV with a JSON sidecar (what the trial was, where the kidnap happened) and a TUM pair; the best and worst
    trial's figures on ``occupancy`` (with the map's ``corners`` (N, 2) when given; one figure when the best is
    also the worst; none without a map, as for a sweep over several worlds); and a summary figure."""
    from pimm_agents.results.tum import write_trial_tum
    from pimm_agents.scoring.trajectory_errors import trajectory_errors

    folder = Path(folder)
    logs, tum = folder / "logs", folder / "tum"
    logs.mkdir(exist_ok=True)
    errors = []
    for result in results:
        stem = trial_stem(result)
        write_csv(result.log, logs / f"{stem}.csv")
        write_sidecar(logs / f"{stem}.json", result)
        write_trial_tum(tum / stem, result.log)
        errors.append(trajectory_errors(result.log.after_kidnap()))
    summary = {
        **summary_of(results, errors),
        "start": run_record.get("start", "global"),
        "run": run_record,
        **provenance(),
        "machine": machine(),
    }
    (folder / "summary.json").write_text(json.dumps(summary, indent=2))
    write_run_record(folder, run_record)
    groups = grouped(results, [r.spec for r in results])
    figures = folder / "figures"
    figures.mkdir(exist_ok=True)
    for (scenario, localizer), trials in groups.items():
        if occupancy is None:
            break
        best, worst = best_and_worst([t.metrics for t in trials])
        picks = [("best and worst", best)] if best == worst else [("best", best), ("worst", worst)]
        for label, index in picks:
            if index is not None:
                name = f"{file_safe(scenario)}_{file_safe(localizer)}_{label.replace(' and ', '_')}.png"
                plot_trial(occupancy, trials[index], figures / name, label, corners)
    plot_summary(summary, figures / "summary.png")
    return summary


def write_run_record(folder: Path, record: dict[str, Any]) -> Path:
    """``run.yaml`` for a run that has none of its own (a replay): what was run and how. A run or a sweep
    writes its own, which reads back to repeat it (``experiments/run_plan.py``)."""
    import yaml

    path = Path(folder) / "run.yaml"
    if not path.exists():
        path.write_text(yaml.safe_dump(record, sort_keys=False, default_flow_style=None, width=120))
    return path
