"""Score trial logs made anywhere: find them, check them, group them, and compute the thesis's metrics.

A log is the thesis's 11-column CSV. When a JSON sidecar of the same stem lies beside it (``run`` writes
one), it says which scenario, localizer and seed the trial was and where the kidnap happened, so that a
kidnap trial is scored from the kidnap on, exactly as ``run`` scored it. Without one, the file name groups
the logs (``SCENARIO_LOCALIZER_trialNN.csv`` as ``run`` names them, or a name ending in a date and time as the
thesis's logs do; otherwise each file stands alone).

Logs recorded on a robot carry faults a simulator's do not; each is counted and reported, and can be dropped:
- repeated stamps: rows whose ``timestamp_real`` equals the previous row's (the thesis's public logs hold 425);
- stale truth: rows whose true pose is exactly the previous row's while the clock moved on (the ground-truth
  source did not update; a simulated robot standing still shows this too, so it is only reported);
- uninitialised estimates: leading rows whose estimate is exactly (0, 0) before the localizer's first output;
- gaps: steps of more than ``GAP_S`` between rows.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pimm_agents.results.log_files import read_csv, read_sidecar, status_rows
from pimm_agents.scoring.fix import FixMetrics, fix_metrics, fix_summary
from pimm_agents.scoring.honesty import HonestyMetrics, honesty_metrics
from pimm_agents.scoring.log_faults import LogFaults, cleaned, faults_of
from pimm_agents.scoring.metrics import TrialMetrics, summarize, trial_metrics
from pimm_agents.scoring.summaries import honesty_summary
from pimm_agents.scoring.trial_log import TrialLog
from pimm_env.errors import MissingFileError, ResultsError

#: ``run``'s names (``area_b_pimm_trial03``) and the thesis's (``Nave_A_MM_2025-07-24_11-51``): the group is
#: what comes before the trial number or the date.
_GROUPED_NAME = re.compile(r"^(?P<group>.+?)_(trial\d+|\d{4}-\d{2}-\d{2}_\d{2}-\d{2}(-\d{2})?)$")


@dataclass
class ScoredLog:
    path: Path
    group: str  # "SCENARIO / LOCALIZER" when known, else the file's stem
    log: TrialLog
    faults: LogFaults
    metrics: TrialMetrics
    honesty: HonestyMetrics
    sidecar: dict[str, Any] = field(default_factory=dict)
    fix: FixMetrics = field(default_factory=lambda: FixMetrics(None, None))


def find_logs(paths: list[Path]) -> list[Path]:
    """The CSV files named, and those under the folders named (sorted); errors name what is missing."""
    found: list[Path] = []
    for path in map(Path, paths):
        if path.is_dir():
            inside = sorted(path.rglob("*.csv"))
            if not inside:
                raise MissingFileError(f"{path}: the folder holds no .csv trial log")
            found += inside
        elif path.is_file():
            found.append(path)
        else:
            raise MissingFileError(f"{path}: no such log file or folder")
    return found


def score_log(path: Path, drop_repeated: bool = False, drop_uninitialised: bool = False) -> ScoredLog:
    """Read, check and score one log (a kidnap trial from the kidnap on when its sidecar marks it)."""
    sidecar = read_sidecar(path)
    log = read_csv(path)
    if sidecar.get("kidnap_row") is not None:
        if sidecar["kidnap_row"] >= len(log):
            raise ResultsError(f"{Path(path).with_suffix('.json')}: kidnap_row {sidecar['kidnap_row']} is past the "
                             f"log's {len(log)} rows")  # fmt: skip
        log.kidnap_index = int(sidecar["kidnap_row"])
    if sidecar.get("status"):
        log.status = status_rows(sidecar["status"], len(log), Path(path).with_suffix(".json"))
    faults = faults_of(log)
    try:
        log = cleaned(log, drop_repeated, drop_uninitialised)
    except ValueError as error:
        raise ResultsError(f"{path}: {error}") from None
    if sidecar.get("scenario") and sidecar.get("localizer"):
        group = f"{sidecar['scenario']} / {sidecar['localizer']}"
    else:
        match = _GROUPED_NAME.match(Path(path).stem)
        group = match["group"] if match else Path(path).stem
    metrics = trial_metrics(log.after_kidnap())
    honesty = honesty_metrics(log.after_kidnap(), metrics.convergence_time_s, log.kidnap_index is not None)
    return ScoredLog(Path(path), group, log, faults, metrics, honesty, sidecar, fix_metrics(log.after_kidnap()))


def group_summaries(scored: list[ScoredLog]) -> dict[str, dict[str, Any]]:
    """The thesis's summary per group, in order of first appearance, with the honesty metrics beside it (a log
    whose sidecar gives no status counts as localized throughout)."""
    groups: dict[str, list[ScoredLog]] = {}
    for item in scored:
        groups.setdefault(item.group, []).append(item)
    return {
        name: {
            **summarize([i.metrics for i in items]),
            **honesty_summary([i.honesty for i in items]),
            **fix_summary([i.fix for i in items]),
        }
        for name, items in groups.items()
    }


def score_record(scored: list[ScoredLog]) -> dict[str, Any]:
    """``evaluate.py score --json``: every log's metrics, group and faults, and the groups' summaries."""
    trials = {
        str(s.path): {**vars(s.metrics), **vars(s.honesty), **vars(s.fix), "group": s.group, "faults": vars(s.faults)}
        for s in scored
    }
    return {"trials": trials, "groups": group_summaries(scored)}


def fault_warnings(scored: list[ScoredLog], dropped: bool) -> list[str]:
    """A warning per log that has faults, and how to drop their rows unless they were dropped."""
    lines = [f"warning: {s.path}: {s.faults.describe()}" for s in scored if s.faults.any]
    if lines and not dropped:
        lines.append("(faults reported above: --drop-repeated / --drop-uninitialised leave those rows out)")
    return lines
