"""The generalization benchmark: perception and localization on buildings no training or tuning used.

For each held-out seed (``training.buildings.HELD_OUT_SEEDS``) the building is written and prepared with the
weights under test (fingerprints made with them), then measured as a user would, in this process: perception
on fresh scans (what ``evaluate.py perception`` prints) and the localizers on its generated routes (an
``Experiment``, as ``evaluate.py run``). The table has one row per building and one
for all of them; ``heldout.json`` keeps every figure.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

#: Excursions are also counted from the first time the estimate held within 3 m / 30 deg this long (s): a pose
#: the filter had found, not a global start's first guess that passed near the truth.
HELD_S = 5.0


def needs_preparing(world_file: Path) -> bool:
    """True unless the world's fingerprint map is newer than its world file and recorded as made with the
    weights it uses."""
    from pimm_agents.perception.files import fingerprint_path, fingerprints_match_weights

    fingerprints, scenarios = fingerprint_path(str(world_file)), world_file.parent / "scenarios.yaml"
    if not fingerprints.is_file() or not scenarios.is_file():
        return True
    return fingerprints.stat().st_mtime < world_file.stat().st_mtime or not fingerprints_match_weights(str(world_file))


def measure_building(
    world_file: Path, localizers: dict[str, dict[str, Any]], trials: int, scans: int, workers: int, out: Path
) -> dict[str, Any]:
    """Perception (once: kept in ``out/perception.json``) and ``trials`` trials per route of ``localizers``
    (``{name: resolved params}``, ``resolve_localizers``), continuing the run already in ``out``
    (``evaluate.py run --resume``): a stopped benchmark loses no finished trial."""
    from pimm_agents.experiments.experiment import Execution, Experiment
    from pimm_agents.experiments.run_plan import RunPlan
    from pimm_agents.measurement.perception_quality import measure_world

    out.mkdir(parents=True, exist_ok=True)
    cached = out / "perception.json"
    asked = {"world": str(world_file), "scans": scans, "seed": 1}
    perception = json.loads(cached.read_text()) if cached.is_file() else None
    if perception is None or perception.get("asked") != asked:
        perception = measure_world(str(world_file), scans, 1)
        perception["asked"] = asked
        cached.write_text(json.dumps(perception, indent=1))
    plan = RunPlan(str(world_file), localizers, trials=trials)
    experiment = Experiment.of_plan(plan, Execution(workers, progress=False))
    outcome = experiment.run(out, resume=True)
    return {"perception": perception, "run": {**outcome.summary, "folder": str(outcome.folder)}}


def building_row(result: dict[str, Any], localizer: str) -> dict[str, float | None]:
    """Segmentation, retrieval and one localizer's figures over all routes of one building."""
    perception, scenarios = result["perception"], result["run"]["scenarios"]
    rows = [by[localizer] for name, by in scenarios.items() if localizer in by]
    routes = [by[localizer] for name, by in scenarios.items() if localizer in by and not name.endswith("_kidnap")]
    kidnaps = [by[localizer] for name, by in scenarios.items() if localizer in by and name.endswith("_kidnap")]

    def pooled(items: list[dict], key: str) -> float | None:
        weights = [r["trials"] * r["convergence_rate"] for r in items if r[key] is not None]
        values = [r[key] for r in items if r[key] is not None]
        return float(np.average(values, weights=weights)) if values and sum(weights) > 0 else None

    return {
        "excursions_per_trial": _excursions(Path(result["run"]["folder"]), localizer),
        "excursions_held_per_trial": _excursions(Path(result["run"]["folder"]), localizer, HELD_S),
        "miou": perception["segmentation"]["miou"],
        "recall_at_3": perception["retrieval"]["recall_at_3_2m"],
        "corner_recall": perception["corners"]["predicted_labels"]["recall"],
        "convergence_rate": float(
            np.average([r["convergence_rate"] for r in routes], weights=[r["trials"] for r in routes])
        ),
        "convergence_time_s": pooled(routes, "convergence_time_s"),
        "position_error_m": pooled(rows, "position_error_m"),
        "kidnap_recovery": float(np.mean([r["convergence_rate"] for r in kidnaps])) if kidnaps else None,
        **_honesty(Path(result["run"]["folder"]), localizer),
    }


def _honesty(folder: Path, localizer: str) -> dict[str, float | None]:
    """Its trials' honesty (every trial, kidnaps from the kidnap on): pooled sums that add up over buildings
    (trials, trials with no false-localized time, false-localized and localized seconds, the longest spell,
    trials localized right), with the median time to localized and the mean 3-sigma share."""
    from pimm_agents.results.folder import file_safe
    from pimm_agents.results.scored_logs import score_log

    honesty = [score_log(p).honesty for p in sorted((folder / "logs").glob(f"*_{file_safe(localizer)}_trial*.csv"))]
    times = [h.time_to_localized_s for h in honesty if h.time_to_localized_s is not None]
    within = [h.within_3sigma for h in honesty if h.within_3sigma is not None]
    noticed = [h.kidnap_noticed_s for h in honesty if h.kidnap_noticed_s is not None]
    return {
        "trials": float(len(honesty)),
        "false_free_trials": float(sum(h.false_localized_s == 0 for h in honesty)),
        "false_localized_s": float(sum(h.false_localized_s for h in honesty)),
        "localized_s": float(sum(h.localized_s for h in honesty)),
        "max_false_localized_s": max((h.max_false_localized_s for h in honesty), default=None),
        "localized_right_trials": float(len(times)),
        "time_to_localized_s": float(np.median(times)) if times else None,
        "within_3sigma": float(np.mean(within)) if within else None,
        "kidnap_noticed_s": max(noticed) if noticed else None,
        # rows more than 1 m off shown a position sigma under 0.5 m by the covariance on amcl_pose (a consumer
        # without the status); None where a log has no published covariance
        "rows": float(sum(h.rows for h in honesty)),
        "published_overconfident_rows": (
            None
            if any(h.published_overconfident_rows is None for h in honesty)
            else float(sum(h.published_overconfident_rows or 0 for h in honesty))
        ),
    }


def _excursions(folder: Path, localizer: str, held_s: float = 0.0) -> float | None:
    """Mean count per route trial (kidnaps left out) of the estimate leaving 3 m / 30 deg after first meeting it."""
    from pimm_agents.results.folder import file_safe
    from pimm_agents.results.log_files import read_csv
    from pimm_agents.scoring.metrics import excursions

    logs = [p for p in (folder / "logs").glob(f"*_{file_safe(localizer)}_trial*.csv") if "_kidnap_" not in p.name]
    counts = [excursions(read_csv(p), held_s=held_s)[0] for p in logs]
    return float(np.mean(counts)) if counts else None


def format_table(rows: dict[str, dict[str, dict[str, float | None]]], localizers: list[str]) -> str:
    from pimm_agents.results.tables import cell

    lines = [
        "| building | localizer | mIoU | recall@3 (2 m) | corner recall | conv. rate | conv. time s | pos. err m "
        "| excursions / trial | after 5 s held | kidnap | loc. time s | false-free trials | false loc. % "
        "| longest false s | 3-sigma % | kidnap noticed s | published overconf. % |",
        "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for building, by_localizer in rows.items():
        for localizer in localizers:
            r = by_localizer[localizer]
            lines.append(
                f"| {building} | {localizer} | {cell(r['miou'], '.2f')} | {cell(r['recall_at_3'], '.2f')} | "
                f"{cell(r['corner_recall'], '.2f')} | {cell(r['convergence_rate'], '.0f', 100)} % | "
                f"{cell(r['convergence_time_s'], '.1f')} | {cell(r['position_error_m'], '.2f')} | "
                f"{cell(r['excursions_per_trial'], '.2f')} | {cell(r.get('excursions_held_per_trial'), '.2f')} | "
                f"{cell(r['kidnap_recovery'], '.0f', 100)} % | {cell(r.get('time_to_localized_s'), '.1f')} | "
                f"{_share(r.get('false_free_trials'), r.get('trials'))} | "
                f"{_share(r.get('false_localized_s'), r.get('localized_s'), '.1f')} | "
                f"{cell(r.get('max_false_localized_s'), '.1f')} | {cell(r.get('within_3sigma'), '.0f', 100)} | "
                f"{cell(r.get('kidnap_noticed_s'), '.1f')} | "
                f"{_share(r.get('published_overconfident_rows'), r.get('rows'), '.2f')} |"
            )
    return "\n".join(lines)


def _share(part: float | None, whole: float | None, spec: str = ".0f") -> str:
    from pimm_agents.results.tables import cell

    return cell(part / whole if part is not None and whole else None, spec, 100) + " %"


def summarize(rows: dict[str, dict[str, dict[str, float | None]]], localizer: str) -> dict[str, float | None]:
    """Means over buildings (median for the convergence and localization times); the honesty counts summed
    (their shares are then pooled over all trials) and the longest spells the longest."""
    items = [by[localizer] for by in rows.values()]

    def mean(key: str) -> float | None:
        values = [v for v in (r[key] for r in items) if v is not None]
        return float(np.mean(values)) if values else None

    times = [t for t in (r["convergence_time_s"] for r in items) if t is not None]
    summary = {key: mean(key) for key in items[0]}
    summary["convergence_time_s"] = float(np.median(times)) if times else None
    for key in ("trials", "false_free_trials", "false_localized_s", "localized_s", "localized_right_trials", "rows"):
        summary[key] = float(sum(r.get(key) or 0.0 for r in items))
    published = [r.get("published_overconfident_rows") for r in items]
    summary["published_overconfident_rows"] = None if None in published else float(sum(published))  # type: ignore[arg-type]
    for key in ("max_false_localized_s", "kidnap_noticed_s"):
        values = [v for v in (r.get(key) for r in items) if v is not None]
        summary[key] = max(values) if values else None
    located = [t for t in (r.get("time_to_localized_s") for r in items) if t is not None]
    summary["time_to_localized_s"] = float(np.median(located)) if located else None
    return summary


def ready_building(seed: int, worlds: Path) -> Path:
    """The world file of generated building ``seed`` under ``worlds``, written and prepared if need be."""
    from pimm_agents.preparation.prepare import prepare_world
    from training.buildings import write_building

    world_file = worlds / f"gen-{seed}" / "world.yaml"
    if not world_file.is_file():
        write_building(seed, worlds)
    if needs_preparing(world_file):
        prepare_world(world_file, progress=False)
    return world_file


def run_buildings(
    seeds: list[int],
    localizers: dict[str, dict[str, Any]],
    trials: int,
    scans: int,
    workers: int,
    worlds: Path,
    out: Path,
    settings: list[str],
    made: str,
    echo: Any,
) -> None:
    """Measure ``localizers`` on generated buildings ``seeds`` (written and prepared under ``worlds`` if need be)
    in passes, one trial per route more each pass, writing ``heldout.json`` and ``heldout.md`` (headed by the
    command ``made``, the commit and the machine) under ``out`` after each; a stopped run continues."""
    from pimm_agents.results.markdown import provenance_here

    out.mkdir(parents=True, exist_ok=True)
    for seed in seeds:
        ready_building(seed, worlds)
    names = list(localizers)
    for done in range(1, trials + 1):
        results, rows = {}, {}
        for seed in seeds:
            echo(f"gen-{seed}: {done} trial(s) per route ...", err=True)
            world_file = worlds / f"gen-{seed}" / "world.yaml"
            results[f"gen-{seed}"] = measure_building(world_file, localizers, done, scans, workers, out / f"gen-{seed}")
            rows[f"gen-{seed}"] = {name: building_row(results[f"gen-{seed}"], name) for name in names}
        summary = {name: summarize(rows, name) for name in names}
        table = format_table({**rows, "all (mean; time: median)": summary}, names)
        record = {"trials_per_route": done, "seeds": seeds, "settings": settings, "rows": rows, "summary": summary}
        (out / "heldout.json").write_text(json.dumps({**record, "raw": results}, indent=1))
        (out / "heldout.md").write_text(f"{provenance_here(made)}\n\n{done} trial(s) per route\n\n{table}\n")
        echo(f"\n{done} trial(s) per route:\n{table}")
