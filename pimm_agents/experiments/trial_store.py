"""Finished trials on disk, one file each, keyed by (world, scenario, localizer, config hash, seed).

``evaluate.py run`` saves every trial here as soon as its simulation ends, so a stopped run keeps what it
finished, and ``--resume`` runs only the keys a folder does not hold yet (an interrupted run, or
``--trials 20`` after 10). A file holds the whole trial log (truth, estimate, covariance, per-update
timings), so everything the results folder shows is rebuilt from the store.
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path
from typing import Any

import numpy as np

from pimm_agents.scoring.trial import TrialResult, TrialSpec, metrics_of
from pimm_agents.scoring.trial_log import TrialLog
from pimm_env.errors import ResultsError

FOLDER = "trials"


def config_hash(params: dict) -> str:
    """Ten hex digits that change whenever any resolved setting of the localizer changes."""
    text = json.dumps(params, sort_keys=True, default=str)
    return hashlib.sha1(text.encode()).hexdigest()[:10]


def world_label(world: str) -> str:
    """A world's short name: ``iilab`` stays, ``build/worlds/gen-900/world.yaml`` becomes ``gen-900``."""
    path = Path(world)
    return path.parent.name if path.suffix in (".yaml", ".yml") else world


def trial_key(spec: TrialSpec) -> str:
    """The file stem of a trial: world, scenario, localizer, config hash and seed, safe for a file name."""
    parts: tuple[str, ...] = (world_label(spec.world), spec.scenario, spec.localizer, config_hash(spec.params),
                              f"seed{spec.seed}")  # fmt: skip
    if spec.sensors != "thesis":  # the thesis's sensors leave the key as it was before presets existed
        parts = (*parts, spec.sensors)
    if spec.start != "global":
        parts = (*parts, f"start-{spec.start}")
    if spec.faults:
        parts = (*parts, f"faults-{spec.faults}")
    if spec.walkers or spec.unmapped:
        parts = (*parts, f"walkers{spec.walkers}-unmapped{spec.unmapped}")
    if spec.driver != "route":
        parts = (*parts, f"driver-{spec.driver}")
    if spec.maps:
        parts = (*parts, f"maps-{world_label(spec.maps)}")
    return "__".join("".join(c if c.isalnum() or c in "._-" else "-" for c in part) for part in parts)


def save_trial(folder: Path, result: TrialResult) -> Path:
    """Write ``result`` to ``folder/trials/KEY.npz`` (atomically: a stopped run leaves no half file)."""
    target = Path(folder) / FOLDER / f"{trial_key(result.spec)}.npz"
    target.parent.mkdir(parents=True, exist_ok=True)
    log, spec = result.log, result.spec
    stages = sorted({stage for timing in log.timings for stage in timing})
    rows = [[t.get(s, np.nan) for s in stages] for t in log.timings]
    timings = np.array(rows, dtype=float).reshape(len(rows), len(stages))
    meta = {
        "spec": {
            "scenario": spec.scenario,
            "localizer": spec.localizer,
            "trial": spec.trial,
            "seed": spec.seed,
            "world": spec.world,
            "params": spec.params,
            "sensors": spec.sensors,
            "start": spec.start,
            "label": spec.label,
            "row": spec.row,
            "faults": spec.faults,
            "walkers": spec.walkers,
            "unmapped": spec.unmapped,
        },
        "wall_s": result.wall_s,
        "completed": result.completed,
        "collided": result.collided,
        "kidnap_index": log.kidnap_index,
        "kidnap_rows": list(log.kidnap_rows),
        "stages": stages,
        "set_aside": log.set_aside,
        "rebased": log.rebased,
    }
    partial = target.with_name(target.name + ".part")
    with partial.open("wb") as handle:
        published: dict[str, Any] = {} if log.published is None else {"published": np.asarray(log.published, float)}
        np.savez_compressed(
            handle,
            meta=np.array(json.dumps(meta)),
            time=log.time,
            estimate_time=log.estimate_time,
            true=log.true,
            estimate=log.estimate,
            cov=log.cov,
            timings=timings,
            corners=log.corners,
            status=np.asarray(log.status, dtype=np.int8),
            cov_xy=np.asarray(log.cov_xy, dtype=float),
            **published,
        )
    os.replace(partial, target)
    return target


def load_trial(path: Path) -> TrialResult:
    """A saved trial; errors name the file."""
    try:
        with np.load(Path(path), allow_pickle=False) as data:
            meta = json.loads(str(data["meta"]))
            stages = meta["stages"]
            timings = [
                {s: float(v) for s, v in zip(stages, row, strict=True) if np.isfinite(v)} for row in data["timings"]
            ]
            log = TrialLog(
                data["time"],
                data["estimate_time"],
                data["true"],
                data["estimate"],
                data["cov"],
                meta["kidnap_index"],
                timings,
                data["corners"] if "corners" in data.files else np.zeros((0, 3)),
                tuple(meta.get("kidnap_rows", ())),  # older files: TrialLog derives it from kidnap_index
                data["status"] if "status" in data.files else None,  # older files: always localized
                data["cov_xy"] if "cov_xy" in data.files else None,
                {str(k): int(v) for k, v in meta.get("set_aside", {}).items()},
                int(meta.get("rebased", 0)),
                data["published"] if "published" in data.files else None,  # older files: none
            )
        spec = TrialSpec(**meta["spec"])
    except (OSError, KeyError, ValueError, TypeError) as error:
        raise ResultsError(f"{path}: not a saved trial ({error})") from None
    return TrialResult(
        spec, log, metrics_of(log), float(meta["wall_s"]), bool(meta["completed"]), bool(meta.get("collided", False))
    )


def stored_keys(folder: Path) -> set[str]:
    """Keys of the trials saved under ``folder``."""
    return {p.stem for p in (Path(folder) / FOLDER).glob("*.npz")}


def load_stored(folder: Path, specs: list[TrialSpec]) -> dict[int, TrialResult]:
    """The saved results for those of ``specs`` that ``folder`` holds, by index in ``specs``; the trial number
    is taken from the spec asked for (the same seed may have been trial 3 of another run)."""
    have = stored_keys(folder)
    found: dict[int, TrialResult] = {}
    for i, spec in enumerate(specs):
        key = trial_key(spec)
        if key in have:
            result = load_trial(Path(folder) / FOLDER / f"{key}.npz")
            result.spec = spec
            found[i] = result
    return found
