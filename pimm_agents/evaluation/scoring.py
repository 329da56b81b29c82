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

import json
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from pimm_agents.evaluation.metrics import TrialMetrics, summarize, trial_metrics
from pimm_agents.evaluation.trial_log import TrialLog, read_csv

GAP_S = 1.0
#: ``run``'s names (``area_b_pimm_trial03``) and the thesis's (``Nave_A_MM_2025-07-24_11-51``): the group is
#: what comes before the trial number or the date.
_GROUPED_NAME = re.compile(r"^(?P<group>.+?)_(trial\d+|\d{4}-\d{2}-\d{2}_\d{2}-\d{2}(-\d{2})?)$")


@dataclass(frozen=True)
class LogFaults:
    repeated_stamps: int
    stale_truth: int
    uninitialised_leading: int
    gaps: int
    longest_gap_s: float

    @property
    def any(self) -> bool:
        return bool(self.repeated_stamps or self.stale_truth or self.uninitialised_leading or self.gaps)

    def describe(self) -> str:
        parts = []
        if self.repeated_stamps:
            parts.append(f"{self.repeated_stamps} repeated stamps")
        if self.stale_truth:
            parts.append(f"{self.stale_truth} rows of stale truth")
        if self.uninitialised_leading:
            parts.append(f"{self.uninitialised_leading} leading rows with an uninitialised (0, 0) estimate")
        if self.gaps:
            parts.append(f"{self.gaps} gaps over {GAP_S:g} s (longest {self.longest_gap_s:.1f} s)")
        return ", ".join(parts)


@dataclass
class ScoredLog:
    path: Path
    group: str  # "SCENARIO / LOCALIZER" when known, else the file's stem
    log: TrialLog
    faults: LogFaults
    metrics: TrialMetrics
    sidecar: dict[str, Any] = field(default_factory=dict)


def find_logs(paths: list[Path]) -> list[Path]:
    """The CSV files named, and those under the folders named (sorted); errors name what is missing."""
    found: list[Path] = []
    for path in map(Path, paths):
        if path.is_dir():
            inside = sorted(path.rglob("*.csv"))
            if not inside:
                raise FileNotFoundError(f"{path}: the folder holds no .csv trial log")
            found += inside
        elif path.is_file():
            found.append(path)
        else:
            raise FileNotFoundError(f"{path}: no such log file or folder")
    return found


def _leading_uninitialised(log: TrialLog) -> int:
    zero = np.all(log.estimate[:, :2] == 0.0, axis=1)
    return int(np.argmax(~zero)) if (~zero).any() else len(zero)


def faults_of(log: TrialLog) -> LogFaults:
    steps = np.diff(log.time)
    stale = np.all(np.diff(log.true, axis=0) == 0.0, axis=1) & (steps > 0)
    gaps = steps[steps > GAP_S]
    return LogFaults(
        repeated_stamps=int(np.count_nonzero(steps == 0)),
        stale_truth=int(np.count_nonzero(stale)),
        uninitialised_leading=_leading_uninitialised(log),
        gaps=len(gaps),
        longest_gap_s=float(gaps.max()) if len(gaps) else 0.0,
    )


def _rows(log: TrialLog, keep: np.ndarray) -> TrialLog:
    """The rows of ``log`` where ``keep``; the kidnap row moves with the rows dropped before it."""
    kidnap = None
    if log.kidnap_index is not None:
        kidnap = int(np.count_nonzero(keep[: log.kidnap_index]))
    timings = [t for t, k in zip(log.timings, keep, strict=False) if k] if len(log.timings) == len(keep) else []
    return TrialLog(log.time[keep], log.estimate_time[keep], log.true[keep], log.estimate[keep], log.cov[keep],
                    kidnap, timings)  # fmt: skip


def cleaned(log: TrialLog, drop_repeated: bool = False, drop_uninitialised: bool = False) -> TrialLog:
    """``log`` without the rows of the faults asked for (repeated stamps keep their first row)."""
    keep = np.ones(len(log), dtype=bool)
    if drop_repeated:
        keep[1:] &= np.diff(log.time) != 0
    if drop_uninitialised:
        keep[: _leading_uninitialised(log)] = False
    if not keep.any():
        raise ValueError("dropping those rows leaves the log empty")
    return _rows(log, keep)


def read_sidecar(csv_path: Path) -> dict[str, Any]:
    path = Path(csv_path).with_suffix(".json")
    if not path.is_file():
        return {}
    try:
        record = json.loads(path.read_text())
    except json.JSONDecodeError as error:
        raise ValueError(f"{path}: not JSON ({error})") from None
    kidnap = record.get("kidnap_row")
    if kidnap is not None and (not isinstance(kidnap, int) or kidnap < 0):
        raise ValueError(f"{path}: kidnap_row must be a row index or null, got {kidnap!r}")
    return record


def score_log(path: Path, drop_repeated: bool = False, drop_uninitialised: bool = False) -> ScoredLog:
    """Read, check and score one log (a kidnap trial from the kidnap on when its sidecar marks it)."""
    sidecar = read_sidecar(path)
    log = read_csv(path)
    if sidecar.get("kidnap_row") is not None:
        if sidecar["kidnap_row"] >= len(log):
            raise ValueError(f"{Path(path).with_suffix('.json')}: kidnap_row {sidecar['kidnap_row']} is past the "
                             f"log's {len(log)} rows")  # fmt: skip
        log.kidnap_index = int(sidecar["kidnap_row"])
    faults = faults_of(log)
    try:
        log = cleaned(log, drop_repeated, drop_uninitialised)
    except ValueError as error:
        raise ValueError(f"{path}: {error}") from None
    if sidecar.get("scenario") and sidecar.get("localizer"):
        group = f"{sidecar['scenario']} / {sidecar['localizer']}"
    else:
        match = _GROUPED_NAME.match(Path(path).stem)
        group = match["group"] if match else Path(path).stem
    return ScoredLog(Path(path), group, log, faults, trial_metrics(log.after_kidnap()), sidecar)


def group_summaries(scored: list[ScoredLog]) -> dict[str, dict[str, Any]]:
    """The thesis's summary per group, in order of first appearance."""
    groups: dict[str, list[TrialMetrics]] = {}
    for item in scored:
        groups.setdefault(item.group, []).append(item.metrics)
    return {name: summarize(metrics) for name, metrics in groups.items()}
