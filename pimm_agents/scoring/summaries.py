"""A run's trials summed up per scenario and localizer, in the schema of ``summary.json``."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import asdict
from typing import Any, TypeVar

import numpy as np

from pimm_agents.scoring.fix import fix_metrics, fix_summary
from pimm_agents.scoring.honesty import HonestyMetrics, honesty_metrics
from pimm_agents.scoring.metrics import kidnap_recoveries, summarize, timing_summary
from pimm_agents.scoring.trial import TrialResult, TrialSpec

T = TypeVar("T")


def grouped(items: Iterable[T], specs: Sequence[TrialSpec]) -> dict[tuple[str, str], list[T]]:
    """``items`` (one per spec) by (scenario row, localizer label), in order of first appearance."""
    groups: dict[tuple[str, str], list[T]] = {}
    for item, spec in zip(items, specs, strict=True):
        groups.setdefault((spec.case, spec.name), []).append(item)
    return groups


def summary_of(results: Sequence[TrialResult], errors: Sequence[dict[str, Any]] | None = None) -> dict[str, Any]:
    """``{"scenarios": {scenario: {localizer: {...}}}}`` in the schema of ARCHITECTURE.md; each entry also has
    ``per_trial`` rows (seed, metrics, APE/RPE when ``errors`` gives them, wall time), the ``spread`` (std, min,
    max) of each metric over the trials that converged, and the mean of the trials' APE and RPE statistics."""
    groups = grouped(range(len(results)), [r.spec for r in results])
    scenarios: dict[str, dict[str, Any]] = {}
    for (scenario, localizer), indices in groups.items():
        trials = [results[i] for i in indices]
        entry: dict[str, Any] = summarize([t.metrics for t in trials])
        entry["timings_ms"] = timing_summary([timing for t in trials for timing in t.log.timings])
        honesty = [
            honesty_metrics(t.log.after_kidnap(), t.metrics.convergence_time_s, t.log.kidnap_index is not None)
            for t in trials
        ]
        fixes = [fix_metrics(t.log.after_kidnap()) for t in trials]
        rows = [
            {**_trial_row(results[i], h, errors[i] if errors else None), **asdict(f)}
            for i, h, f in zip(indices, honesty, fixes, strict=True)
        ]
        entry["per_trial"] = rows
        entry["collisions"] = sum(bool(t.collided) for t in trials)  # trials whose robot touched an obstacle
        entry.update(honesty_summary(honesty))
        entry.update(fix_summary(fixes))
        entry["spread"] = _spread(rows)
        for kind in ("ape", "rpe"):
            stats = [r[kind] for r in rows if r.get(kind)]
            entry[f"{kind}_m"] = {k: float(np.mean([s[k] for s in stats])) for k in stats[0]} if stats else None
        scenarios.setdefault(scenario, {})[localizer] = entry
    return {"scenarios": scenarios}


def _trial_row(result: TrialResult, honesty: HonestyMetrics, errors: dict[str, Any] | None) -> dict[str, Any]:
    m = result.metrics
    row: dict[str, Any] = {
        "trial": result.spec.trial,
        "seed": result.spec.seed,
        "converged": m.converged,
        "convergence_time_s": m.convergence_time_s,
        "position_error_m": m.position_error_m,
        "angle_error_deg": m.angle_error_deg,
        "completed": result.completed,
        "collided": result.collided,
        "wall_s": round(result.wall_s, 2),
        "set_aside": result.log.set_aside,  # observations the localizer's guard set aside
        "rebased": result.log.rebased,
        **asdict(honesty),
    }
    if len(result.log.kidnap_rows) > 1:  # a fault run's kidnaps: how long each took to recover from
        row["kidnap_recoveries_s"] = kidnap_recoveries(result.log)
    if errors is not None:
        row.update(errors)
    return row


def _spread(rows: list[dict[str, Any]]) -> dict[str, dict[str, float] | None]:
    out: dict[str, dict[str, float] | None] = {}
    for key in ("convergence_time_s", "position_error_m", "angle_error_deg"):
        values = [r[key] for r in rows if r[key] is not None]
        out[key] = (
            {"std": float(np.std(values)), "min": float(np.min(values)), "max": float(np.max(values))}
            if values
            else None
        )
    return out


def honesty_summary(trials: list[HonestyMetrics]) -> dict[str, float | None]:
    """Over a scenario's trials: the median time to localized (of the trials that got there), the mean and
    longest false-localized time, the false-localized rate over all localized time, the share of trials with no
    false-localized time at all, the mean 3-sigma share and the median NEES, after kidnaps the longest time to
    notice one, and the share of rows whose covariance (chosen or published) was overconfident."""

    def finite(values: list[float | None]) -> list[float]:
        return [v for v in values if v is not None and np.isfinite(v)]

    times = finite([t.time_to_localized_s for t in trials])
    localized = sum(t.localized_s for t in trials)
    within, nees = finite([t.within_3sigma for t in trials]), finite([t.nees for t in trials])
    noticed = [t.kidnap_noticed_s for t in trials if t.kidnap_noticed_s is not None]
    rows = sum(t.rows for t in trials)
    published = [t.published_overconfident_rows for t in trials]
    return {
        "time_to_localized_s": float(np.median(times)) if times else None,
        "false_localized_s": float(np.mean([t.false_localized_s for t in trials])) if trials else None,
        "false_localized_rate": sum(t.false_localized_s for t in trials) / localized if localized > 0 else None,
        "max_false_localized_s": max((t.max_false_localized_s for t in trials), default=None),
        "false_free_share": float(np.mean([t.false_localized_s == 0 for t in trials])) if trials else None,
        "within_3sigma": float(np.mean(within)) if within else None,
        "nees": float(np.median(nees)) if nees else None,
        "kidnap_noticed_s": max(noticed) if noticed else None,
        # rows > 1 m off with a position sigma < 0.5 m, by the chosen mode's covariance and by the published one
        "overconfident_share": sum(t.overconfident_rows for t in trials) / rows if rows else None,
        "published_overconfident_share": (
            sum(p for p in published if p is not None) / rows if rows and None not in published else None
        ),
    }
