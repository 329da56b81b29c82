"""Metrics for long runs: when did the localizer first find the pose and hold it, and how much of the time after
that was it right?

The thesis's convergence time (``metrics.py``: within 3 m and 30 deg from then to the end) suits its 1-2 minute
trials; on a log of tens of minutes one bad row late in the run moves it near the end. Here a *fix* is the first
time the estimate comes within ``FIX_POSITION_M`` and ``FIX_ANGLE_DEG`` of the truth and stays there for
``FIX_HOLD_S``; after it, ``localized_share`` is the share of the time the estimate is that close. Rows with no
truth (NaN) count as neither.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pimm_agents.scoring.metrics import angle_errors_deg, position_errors
from pimm_agents.scoring.trial_log import TrialLog

FIX_POSITION_M = 0.5
FIX_ANGLE_DEG = 10.0
FIX_HOLD_S = 10.0


@dataclass(frozen=True)
class FixMetrics:
    time_to_fix_s: float | None  # from the log's start to the first fix (None: never fixed)
    localized_share: float | None  # of the time from the fix on, the share within the fix's bounds


def fix_metrics(log: TrialLog) -> FixMetrics:
    """The fix metrics of ``log`` (see the module's text)."""
    if len(log) == 0:
        return FixMetrics(None, None)
    with np.errstate(invalid="ignore"):
        close = (position_errors(log) < FIX_POSITION_M) & (angle_errors_deg(log) < FIX_ANGLE_DEG)
    padded = np.concatenate([[False], close, [False]])
    edges = np.flatnonzero(padded[1:] != padded[:-1])  # run k covers rows edges[2k] .. edges[2k + 1] - 1
    for first, end in zip(edges[::2], edges[1::2], strict=True):
        held = (log.time[end] if end < len(log) else log.time[-1]) - log.time[first]
        if held >= FIX_HOLD_S:
            durations = np.diff(log.time[first:], append=log.time[-1])
            total = float(durations.sum())
            share = float(durations[close[first:]].sum()) / total if total > 0 else 1.0
            return FixMetrics(float(log.time[first] - log.time[0]), share)
    return FixMetrics(None, None)


def fix_summary(trials: list[FixMetrics]) -> dict[str, float | None]:
    """Over a scenario's trials: the median time to a fix (of the trials that got one), the mean share of the
    time localized after it, and the share of the trials that got a fix."""
    times = [t.time_to_fix_s for t in trials if t.time_to_fix_s is not None]
    shares = [t.localized_share for t in trials if t.localized_share is not None]
    return {
        "time_to_fix_s": float(np.median(times)) if times else None,
        "localized_share": float(np.mean(shares)) if shares else None,
        "fixed_share": len(times) / len(trials) if trials else None,
    }
