"""Faults a log recorded on a robot can carry, counted, and the rows they affect dropped on request."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pimm_agents.scoring.trial_log import TrialLog
from pimm_env.errors import ResultsError


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
    status, cov_xy = np.asarray(log.status)[keep], np.asarray(log.cov_xy)[keep]
    return TrialLog(log.time[keep], log.estimate_time[keep], log.true[keep], log.estimate[keep], log.cov[keep],
                    kidnap, timings, status=status, cov_xy=cov_xy, set_aside=log.set_aside,
                    rebased=log.rebased, published=None if log.published is None else log.published[keep])  # fmt: skip


def cleaned(log: TrialLog, drop_repeated: bool = False, drop_uninitialised: bool = False) -> TrialLog:
    """``log`` without the rows of the faults asked for (repeated stamps keep their first row)."""
    keep = np.ones(len(log), dtype=bool)
    if drop_repeated:
        keep[1:] &= np.diff(log.time) != 0
    if drop_uninitialised:
        keep[: _leading_uninitialised(log)] = False
    if not keep.any():
        raise ResultsError("dropping those rows leaves the log empty")
    return _rows(log, keep)


def with_truth(log: TrialLog) -> tuple[TrialLog, int]:
    """``log`` without the rows that have no true pose (NaN: a replayed bag's steps before its first truth
    message, or while its truth topic was silent), and how many rows that left out."""
    keep = np.all(np.isfinite(log.true), axis=1)
    if keep.all():
        return log, 0
    return _rows(log, keep), int(np.count_nonzero(~keep))


GAP_S = 1.0
