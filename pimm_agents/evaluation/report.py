"""Evaluation results as the thesis shows them: summary.json, per-trial CSVs, tables and figures."""

from __future__ import annotations

import json
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

from pimm_agents.evaluation.metrics import (
    angle_errors_deg,
    best_and_worst,
    kidnap_recoveries,
    position_errors,
    summarize,
    timing_summary,
)
from pimm_agents.evaluation.provenance import machine, provenance
from pimm_agents.evaluation.trials import TrialResult, TrialSpec
from pimm_env.mapping.occupancy import OccupancyGrid

#: Thesis tables 4.2-4.5: convergence rate, mean convergence time (s), position (m) and angle (deg) error.
THESIS_RESULTS: dict[str, dict[str, tuple[float, float | None, float | None, float | None]]] = {
    "area_a": {"amcl": (0.4, 55.93, 1.1, 1.08), "pimm": (1.0, 20.88, 0.84, 3.2)},
    "area_b": {"amcl": (1.0, 2.6, 0.30, 1.91), "pimm": (1.0, 4.53, 0.50, 7.65)},
    "a_c_b": {"amcl": (0.7, 12.54, 0.17, 1.46), "pimm": (1.0, 34.48, 0.89, 3.55)},
    "a_c_b_kidnap": {"amcl": (0.0, None, None, None), "pimm": (1.0, 7.33, 0.33, 2.16)},
}


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
        rows = [_trial_row(results[i], errors[i] if errors else None) for i in indices]
        entry["per_trial"] = rows
        entry["spread"] = _spread(rows)
        for kind in ("ape", "rpe"):
            stats = [r[kind] for r in rows if r.get(kind)]
            entry[f"{kind}_m"] = {k: float(np.mean([s[k] for s in stats])) for k in stats[0]} if stats else None
        scenarios.setdefault(scenario, {})[localizer] = entry
    return {"scenarios": scenarios}


def _trial_row(result: TrialResult, errors: dict[str, Any] | None) -> dict[str, Any]:
    m = result.metrics
    row: dict[str, Any] = {
        "trial": result.spec.trial,
        "seed": result.spec.seed,
        "converged": m.converged,
        "convergence_time_s": m.convergence_time_s,
        "position_error_m": m.position_error_m,
        "angle_error_deg": m.angle_error_deg,
        "completed": result.completed,
        "wall_s": round(result.wall_s, 2),
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


def _cell(value: float | None, fmt: str) -> str:
    return "-" if value is None else format(value, fmt)


def _name_width(names: Any, least: int) -> int:
    """Column width that fits every name with two spaces to spare."""
    return max([least, *(len(n) + 2 for n in names)])


def format_tables(summary: dict[str, Any]) -> str:
    """One table per scenario, ours beside the thesis's numbers (for localizers the thesis ran)."""
    lines = []
    w = _name_width((name for rows in summary["scenarios"].values() for name in rows), 16)
    for scenario, by_localizer in summary["scenarios"].items():
        lines.append(f"\n{scenario}")
        lines.append(
            f"  {'localizer':<{w}}{'trials':>7}{'conv. rate %':>14}{'conv. time s':>14}"
            f"{'pos. err m':>12}{'ang. err deg':>14}"
        )
        for localizer, row in by_localizer.items():
            lines.append(
                f"  {localizer:<{w}}{row['trials']:>7}{100 * row['convergence_rate']:>14.0f}"
                f"{_cell(row['convergence_time_s'], '.2f'):>14}{_cell(row['position_error_m'], '.2f'):>12}"
                f"{_cell(row['angle_error_deg'], '.2f'):>14}"
            )
            thesis = THESIS_RESULTS.get(scenario, {}).get(localizer.split("-")[0])
            if thesis is not None and localizer in ("amcl", "pimm"):
                rate, t, pos, ang = thesis
                lines.append(
                    f"  {'  thesis':<{w}}{10:>7}{100 * rate:>14.0f}{_cell(t, '.2f'):>14}{_cell(pos, '.2f'):>12}"
                    f"{_cell(ang, '.2f'):>14}"
                )
    return "\n".join(lines)


def format_timings(summary: dict[str, Any]) -> str:
    """Mean and peak ms per stage and localizer over all scenarios (thesis section 4.6), and where the time went:
    each stage's seconds in all and their share of the localizer's ``total`` stage."""
    stages: dict[str, dict[str, list[tuple[float, float, float]]]] = {}
    for by_localizer in summary["scenarios"].values():
        for localizer, row in by_localizer.items():
            for stage, t in row["timings_ms"].items():
                entry = (t["mean"], t["max"], t.get("seconds", float("nan")))
                stages.setdefault(localizer, {}).setdefault(stage, []).append(entry)
    w = _name_width(stages, 16)
    sw = _name_width((stage for by_stage in stages.values() for stage in by_stage), 14)
    lines = [f"\n  {'localizer':<{w}}{'stage':<{sw}}{'mean ms':>10}{'peak ms':>10}{'total s':>10}{'share':>8}"]
    for localizer, by_stage in stages.items():
        whole = float(np.sum([v[2] for v in by_stage.get("total", [])])) or float("nan")
        for stage, values in by_stage.items():
            mean = float(np.mean([v[0] for v in values]))
            peak = float(np.max([v[1] for v in values]))
            seconds = float(np.sum([v[2] for v in values]))
            share = f"{100 * seconds / whole:.0f} %" if np.isfinite(seconds / whole) else "-"
            lines.append(f"  {localizer:<{w}}{stage:<{sw}}{mean:>10.2f}{peak:>10.2f}{seconds:>10.1f}{share:>8}")
    return "\n".join(lines)


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
    """summary.json (with the version, commit and machine), run.json (what was run: world, scenarios, seeds), per trial
    the thesis's CSV with a JSON sidecar (what the trial was, where the kidnap happened) and a TUM pair, and the
    best/worst figures on ``occupancy`` (with the map's ``corners`` (N, 2) when given; one figure when the best
    trial is also the worst; none without a map, as for a sweep over several worlds) and a summary figure;
    returns the summary."""
    from pimm_agents.evaluation.trajectories import trajectory_errors, write_trial_tum

    folder = Path(folder)
    logs, tum = folder / "logs", folder / "tum"
    logs.mkdir(exist_ok=True)
    errors = []
    for result in results:
        stem = trial_stem(result)
        result.log.write_csv(logs / f"{stem}.csv")
        write_sidecar(logs / f"{stem}.json", result)
        write_trial_tum(tum / stem, result.log)
        errors.append(trajectory_errors(result.log.after_kidnap()))
    summary = {
        **summary_of(results, errors),
        "start": run_record.get("start", "global"),
        **provenance(),
        "machine": machine(),
    }
    (folder / "summary.json").write_text(json.dumps(summary, indent=2))
    (folder / "run.json").write_text(json.dumps(run_record, indent=2))
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


def write_sidecar(path: Path, result: TrialResult) -> Path:
    """What a trial's CSV holds, beside it: scenario, localizer, trial, seed, world, and the first row after
    the kidnap (the thesis's 11 columns stay as they are, so the thesis's tools still read the CSV)."""
    s = result.spec
    record = {
        "scenario": s.case,
        "localizer": s.name,
        "factory": s.localizer,
        "trial": s.trial,
        "seed": s.seed,
        "world": s.world,
        "kidnap_row": result.log.kidnap_index,
        "kidnap_rows": list(result.log.kidnap_rows),
        "rows": len(result.log),
    }
    Path(path).write_text(json.dumps(record, indent=1))
    return Path(path)


def plot_trial(
    occupancy: OccupancyGrid, trial: TrialResult, path: Path, label: str, corners: np.ndarray | None = None
) -> Path:
    """Trajectories on the map (true and estimated, start and kidnap marked, the map's corners) and position and
    angle error over time with the convergence thresholds, as thesis fig. 4.2."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from pimm_agents.evaluation.metrics import ANGLE_THRESHOLD_DEG, POSITION_THRESHOLD_M
    from pimm_env.envs.render import show_map

    log = trial.log
    fig, (ax_map, ax_err) = plt.subplots(1, 2, figsize=(14, 5.5), gridspec_kw={"width_ratios": [1.4, 1]})
    show_map(ax_map, occupancy)
    if corners is not None and len(corners):
        ax_map.plot(corners[:, 0], corners[:, 1], "s", ms=3, mfc="none", mec="0.45", label="map corners")
    true_xy = log.true[:, :2]
    if log.kidnap_rows:  # no line across a teleport
        true_xy = np.insert(true_xy, list(log.kidnap_rows), np.nan, axis=0)
    ax_map.plot(true_xy[:, 0], true_xy[:, 1], "-", color="tab:green", lw=1.5, label="true path")
    ax_map.plot(log.estimate[:, 0], log.estimate[:, 1], ".", color="tab:red", ms=2, label="estimate")
    if len(log.corners):
        ax_map.plot(log.corners[:, 1], log.corners[:, 2], "x", color="tab:orange", ms=3, mew=0.6, alpha=0.5,
                    label="detected corners (at the estimate)")  # fmt: skip
    if len(log):
        ax_map.plot(*log.true[0, :2], "^", color="tab:green", ms=10, mec="k", label="start")
    for k, row in enumerate(log.kidnap_rows):
        ax_map.plot(*log.true[row - 1, :2], "X", color="k", ms=10, label="kidnapped from" if k == 0 else None)
        ax_map.plot(
            *log.true[row, :2], "X", color="tab:purple", ms=10, mec="k", label="kidnapped to" if k == 0 else None
        )
    ax_map.set_xlabel("x (m)")
    ax_map.set_ylabel("y (m)")
    ax_map.legend(loc="upper right", fontsize=8)
    m = trial.metrics
    verdict = f"converged at {m.convergence_time_s:.1f} s" if m.converged else "did not converge"
    if m.converged and log.kidnap_index is not None:
        verdict += " after the kidnap"
    fig.suptitle(
        f"{trial.spec.name} in {trial.spec.case}: {label} of the trials (trial {trial.spec.trial}, "
        f"seed {trial.spec.seed}), {verdict}",
        fontsize=11,
    )
    t = log.time - log.time[0]
    ax_err.plot(t, position_errors(log), color="tab:blue", lw=1, label="position error (m)")
    ax_err.axhline(
        POSITION_THRESHOLD_M, color="tab:blue", ls=":", lw=0.8, label=f"{POSITION_THRESHOLD_M:g} m threshold"
    )
    ax_err.set_xlabel("time (s)")
    ax_err.set_ylabel("position error (m)", color="tab:blue")
    ax_ang = ax_err.twinx()
    ax_ang.plot(t, angle_errors_deg(log), color="tab:orange", lw=1, label="angle error (deg)")
    ax_ang.axhline(
        ANGLE_THRESHOLD_DEG, color="tab:orange", ls=":", lw=0.8, label=f"{ANGLE_THRESHOLD_DEG:g} deg threshold"
    )
    ax_ang.set_ylabel("angle error (deg)", color="tab:orange")
    for k, row in enumerate(log.kidnap_rows):
        ax_err.axvline(t[row], color="k", ls="--", lw=1, label="kidnap" if k == 0 else None)
    if m.converged:
        start = t[0] + m.convergence_time_s + (t[log.kidnap_index] if log.kidnap_index is not None else 0.0)
        ax_err.axvline(start, color="tab:green", ls="--", lw=1, label="converged")
    lines = ax_err.get_legend_handles_labels()
    more = ax_ang.get_legend_handles_labels()
    ax_err.legend(lines[0] + more[0], lines[1] + more[1], loc="upper right", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return Path(path)


def plot_summary(summary: dict[str, Any], path: Path) -> Path:
    """Convergence rate and mean convergence time per scenario and localizer, as bars, with the thesis's
    values beside them (hatched) for the localizers the thesis ran."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    scenarios = list(summary["scenarios"])
    localizers = list(dict.fromkeys(name for rows in summary["scenarios"].values() for name in rows))
    bars = [(name, False) for name in localizers]
    bars += [
        (name, True) for name in ("pimm", "amcl") if name in localizers and any(s in THESIS_RESULTS for s in scenarios)
    ]
    width = 0.8 / max(1, len(bars))
    fig, (ax_rate, ax_time) = plt.subplots(1, 2, figsize=(max(10, 2.2 * len(scenarios) + 4), 4.5))
    colors = {name: f"C{i}" for i, name in enumerate(localizers)}
    for k, (name, thesis) in enumerate(bars):
        rates, times = [], []
        for scenario in scenarios:
            if thesis:
                rate, time_s, _, _ = THESIS_RESULTS.get(scenario, {}).get(name, (np.nan, None, None, None))
            else:
                row = summary["scenarios"][scenario].get(name, {})
                rate, time_s = row.get("convergence_rate", np.nan), row.get("convergence_time_s")
            rates.append(100 * rate)
            times.append(np.nan if time_s is None else time_s)
        x = np.arange(len(scenarios)) + (k - (len(bars) - 1) / 2) * width
        style = {"color": colors[name], "hatch": "//" if thesis else None, "alpha": 0.45 if thesis else 1.0}
        label = f"{name} (thesis)" if thesis else name
        ax_rate.bar(x, rates, width, label=label, edgecolor="k", lw=0.5, **style)
        ax_time.bar(x, times, width, label=label, edgecolor="k", lw=0.5, **style)
    for ax, ylabel in ((ax_rate, "convergence rate (%)"), (ax_time, "mean convergence time (s)")):
        ax.set_xticks(np.arange(len(scenarios)), scenarios, rotation=20, ha="right")
        ax.set_ylabel(ylabel)
        ax.grid(axis="y", lw=0.4)
    ax_rate.set_ylim(0, 105)
    ax_time.legend(fontsize=8)
    trials = sorted({row["trials"] for rows in summary["scenarios"].values() for row in rows.values()})
    fig.suptitle(f"convergence per scenario ({'/'.join(map(str, trials))} trials each; thesis: 10)", fontsize=11)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return Path(path)
