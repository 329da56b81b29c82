"""The thesis's localization metrics (section 4.1.1), as pure functions of trial logs."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pimm_agents.scoring.trial_log import TrialLog
from pimm_env.geometry import wrap_angle

POSITION_THRESHOLD_M = 3.0
ANGLE_THRESHOLD_DEG = 30.0


@dataclass(frozen=True)
class TrialMetrics:
    converged: bool
    convergence_time_s: float | None  # from the log's first estimate
    position_error_m: float | None  # mean after convergence
    angle_error_deg: float | None  # mean absolute wrapped, after convergence


def position_errors(log: TrialLog) -> np.ndarray:
    return np.hypot(*(log.estimate[:, :2] - log.true[:, :2]).T)


def angle_errors_deg(log: TrialLog) -> np.ndarray:
    return np.degrees(np.abs(wrap_angle(log.estimate[:, 2] - log.true[:, 2])))


def excursions(
    log: TrialLog,
    position_threshold: float = POSITION_THRESHOLD_M,
    angle_threshold_deg: float = ANGLE_THRESHOLD_DEG,
    held_s: float = 0.0,
) -> tuple[int, float]:
    """How often, after the estimate first stayed within both thresholds for ``held_s`` seconds (0: after it
    first came within them), it left them again, and for how long in all (s): the jumps to a look-alike place
    that the convergence metric only sees as a late time. With ``held_s`` > 0, a global start's first estimate
    that lands near the truth by chance for a moment does not count as a pose the filter had found."""
    if len(log) == 0:
        return 0, 0.0
    bad = (position_errors(log) >= position_threshold) | (angle_errors_deg(log) >= angle_threshold_deg)
    start = _first_held(log.time, ~bad, held_s)
    if start is None:
        return 0, 0.0
    after = bad[start:]
    starts = np.count_nonzero(after[1:] & ~after[:-1])
    dt = np.diff(log.time[start:], append=log.time[-1])
    return int(starts), float(dt[after].sum())


def kidnap_recoveries(
    log: TrialLog, position_threshold: float = POSITION_THRESHOLD_M, angle_threshold_deg: float = ANGLE_THRESHOLD_DEG
) -> list[float | None]:
    """For each kidnap in ``log.kidnap_rows``: the time (s) from it until the estimate came within both
    thresholds and stayed there up to the next kidnap (or the end); None where it never did."""
    good = (position_errors(log) < position_threshold) & (angle_errors_deg(log) < angle_threshold_deg)
    rows = sorted(log.kidnap_rows)
    out: list[float | None] = []
    for k, start in enumerate(rows):
        end = rows[k + 1] if k + 1 < len(rows) else len(log)
        segment = good[start:end]
        if segment.size == 0 or not segment[-1]:
            out.append(None)
            continue
        bad = np.flatnonzero(~segment)
        first = start + (int(bad[-1]) + 1 if bad.size else 0)
        out.append(float(log.time[first] - log.time[start]))
    return out


def _first_held(time: np.ndarray, good: np.ndarray, held_s: float) -> int | None:
    """The first index of a run of ``good`` rows spanning at least ``held_s`` seconds."""
    run_start = None
    for i in range(len(good)):
        if not good[i]:
            run_start = None
            continue
        run_start = i if run_start is None else run_start
        if time[i] - time[run_start] >= held_s:
            return run_start
    return None


def trial_metrics(
    log: TrialLog, position_threshold: float = POSITION_THRESHOLD_M, angle_threshold_deg: float = ANGLE_THRESHOLD_DEG
) -> TrialMetrics:
    """Converged at t if from t to the end the errors stay under both thresholds; the earliest such t counts."""
    if len(log) == 0:
        return TrialMetrics(False, None, None, None)
    pos, ang = position_errors(log), angle_errors_deg(log)
    bad = (pos >= position_threshold) | (ang >= angle_threshold_deg)
    if bad[-1]:
        return TrialMetrics(False, None, None, None)
    start = int(np.nonzero(bad)[0][-1]) + 1 if bad.any() else 0
    return TrialMetrics(
        True,
        float(log.time[start] - log.time[0]),
        float(pos[start:].mean()),
        float(ang[start:].mean()),
    )


def summarize(trials: list[TrialMetrics]) -> dict[str, float | int | None]:
    """Convergence rate over all trials; time and errors averaged over the trials that converged."""
    done = [t for t in trials if t.converged]

    def mean(values: list[float | None]) -> float | None:
        known = [v for v in values if v is not None]  # every converged trial has all three
        return float(np.mean(known)) if known else None

    return {
        "trials": len(trials),
        "convergence_rate": len(done) / len(trials) if trials else 0.0,
        "convergence_time_s": mean([t.convergence_time_s for t in done]),
        "position_error_m": mean([t.position_error_m for t in done]),
        "angle_error_deg": mean([t.angle_error_deg for t in done]),
    }


def _or_inf(value: float | None) -> float:
    return float("inf") if value is None else value


def best_and_worst(trials: list[TrialMetrics]) -> tuple[int | None, int | None]:
    """Indices of the best trial (lowest convergence time) and the worst (highest mean position error)
    among the trials that converged; a trial that never converged is the worst if there is one."""
    done = [i for i, t in enumerate(trials) if t.converged]
    never = [i for i, t in enumerate(trials) if not t.converged]
    best = min(done, key=lambda i: _or_inf(trials[i].convergence_time_s)) if done else None
    worst: int | None
    if never:
        worst = never[0]
    else:
        worst = max(done, key=lambda i: _or_inf(trials[i].position_error_m)) if done else None
    return best, worst


def timing_summary(timings: list[dict[str, float]]) -> dict[str, dict[str, float]]:
    """Mean and peak ms of every stage over the updates that reported it, and the seconds it took in all."""
    stages: dict[str, list[float]] = {}
    for entry in timings:
        for stage, ms in entry.items():
            stages.setdefault(stage, []).append(ms)
    return {
        s: {"mean": float(np.mean(v)), "max": float(np.max(v)), "seconds": float(np.sum(v)) / 1000}
        for s, v in stages.items()
    }
