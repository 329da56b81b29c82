"""Results as figures: a trial's trajectories and errors (thesis fig. 4.2), and convergence per scenario."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from pimm_agents.perception.fingerprint_map import Retrieval
from pimm_agents.scoring.metrics import angle_errors_deg, position_errors
from pimm_agents.scoring.thesis import THESIS_RESULTS
from pimm_agents.scoring.trial import TrialResult
from pimm_agents.scoring.trial_log import TrialLog
from pimm_env.mapping.occupancy import OccupancyGrid
from pimm_env.world.semantics import CLASS_NAMES


def plot_trial(
    occupancy: OccupancyGrid, trial: TrialResult, path: Path, label: str, corners: np.ndarray | None = None
) -> Path:
    """Trajectories on the map (true and estimated, start and kidnap marked, the map's corners) and position and
    angle error over time with the convergence thresholds, as thesis fig. 4.2."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from pimm_agents.scoring.metrics import ANGLE_THRESHOLD_DEG, POSITION_THRESHOLD_M
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
    shade_statuses(ax_err, log)
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


def spells(flags: np.ndarray) -> list[tuple[int, int]]:
    """(first, last) row of each run of consecutive ``flags``."""
    padded = np.concatenate([[False], np.asarray(flags, dtype=bool), [False]])
    edges = np.flatnonzero(padded[1:] != padded[:-1])
    return [(int(a), int(b) - 1) for a, b in zip(edges[::2], edges[1::2], strict=True)]


def shade_statuses(ax: Any, log: TrialLog) -> None:
    """Behind the error curves: the rows the localizer called lost (grey) or ambiguous (yellow), the rows it
    called localized while wrong (red: false-localized, 1 m / 10 deg), and its reported 3-sigma position bound."""
    from pimm_agents.localizer import STATUSES
    from pimm_agents.scoring.honesty import RIGHT_ANGLE_DEG, RIGHT_POSITION_M

    if not len(log):
        return
    t = log.time - log.time[0]
    end = np.append(t[1:], t[-1])
    wrong = (position_errors(log) >= RIGHT_POSITION_M) | (angle_errors_deg(log) >= RIGHT_ANGLE_DEG)
    status = np.asarray(log.status)
    shades = (
        (status == STATUSES.index("lost"), "0.85", "lost"),
        (status == STATUSES.index("ambiguous"), "khaki", "ambiguous"),
        (log.localized & wrong, "tab:red", "localized while wrong"),
    )
    for flags, color, label in shades:
        for k, (a, b) in enumerate(spells(flags)):
            ax.axvspan(t[a], end[b], color=color, alpha=0.35, lw=0, label=label if k == 0 else None)
    sigma = 3.0 * np.sqrt(np.maximum(log.cov[:, 0] + log.cov[:, 1], 0.0))
    top = max(float(np.nanmax(position_errors(log))), 1.5) * 1.1
    ax.plot(t, np.minimum(sigma, top), color="0.4", ls="--", lw=0.8, label="reported 3 sigma (position)")
    ax.set_ylim(0, top)


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


def plot_perception(
    occupancy: OccupancyGrid, confusion: np.ndarray, retrievals: list[Retrieval], truths: np.ndarray, path: Path
) -> Path:
    """Left: each query's true position joined to its nearest retrieved one (green within 2 m, red beyond).
    Right: the confusion matrix, each row normalized to the true class's returns."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from pimm_env.envs.render import show_map

    fig, (ax_map, ax_conf) = plt.subplots(1, 2, figsize=(15, 5.5), gridspec_kw={"width_ratios": [1.6, 1]})
    show_map(ax_map, occupancy)
    for retrieval, truth in zip(retrievals, truths, strict=True):
        errors = np.linalg.norm(retrieval.positions - truth[:2], axis=1)
        best = retrieval.positions[int(np.argmin(errors))]
        color = "tab:green" if errors.min() <= 2.0 else "tab:red"
        ax_map.plot([truth[0], best[0]], [truth[1], best[1]], "-", color=color, lw=1.2)
        ax_map.plot(*truth[:2], "o", color=color, ms=3)
    from matplotlib.lines import Line2D

    ax_map.legend(
        handles=[
            Line2D([], [], color="tab:green", marker="o", ms=3, label="nearest suggestion within 2 m"),
            Line2D([], [], color="tab:red", marker="o", ms=3, label="all suggestions over 2 m away"),
        ],
        loc="upper right",
        fontsize=8,
        title="scan position -> nearest of k",
        title_fontsize=8,
    )
    ax_map.set_title(f"fingerprint retrieval: {len(retrievals)} fresh scans")
    ax_map.set_xlabel("x (m)")
    ax_map.set_ylabel("y (m)")
    shares = confusion / np.maximum(confusion.sum(axis=1, keepdims=True), 1)
    ax_conf.imshow(shares, cmap="Blues", vmin=0, vmax=1)
    for (i, j), v in np.ndenumerate(shares):
        ax_conf.text(j, i, f"{v:.2f}", ha="center", va="center", color="white" if v > 0.5 else "black")
    ax_conf.set_xticks(range(len(CLASS_NAMES)), CLASS_NAMES)
    ax_conf.set_yticks(range(len(CLASS_NAMES)), CLASS_NAMES)
    ax_conf.set_xlabel("predicted")
    ax_conf.set_ylabel("true")
    ax_conf.set_title("segmentation: share of each true class's returns")
    fig.tight_layout()
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return Path(path)
