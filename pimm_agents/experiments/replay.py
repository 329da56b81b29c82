"""Localizers on a recorded bag: the bag is read once and fed to every localizer, through the same recording
wrapper as a live trial, so a bag recorded from a scenario gives that scenario's live metrics."""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from pimm_agents.scoring.log_faults import with_truth
from pimm_agents.scoring.trial import TrialResult, TrialSpec, metrics_of
from pimm_env.errors import ExperimentError


def replay_bag(
    bag: Path, specs: Sequence[TrialSpec], map_path: Path | None = None, topics: Any = None, config: Any = None
) -> tuple[list[TrialResult], bool]:
    """Every spec's localizer (built for ``spec.world``, or from ``map_path`` alone) on the bag, each reset
    with its spec's seed; returns the results and whether the bag had ground truth (without it the logs'
    truth is NaN and the metrics mean nothing). Rows without a true pose (before the bag's first, or while its
    truth topic was silent) are left out of the scoring and counted in ``set_aside`` as ``no_truth_rows``; the
    messages the reader set aside (``non_finite_odometry``, ``non_finite_truth``) are counted there too."""
    from pimm_agents.experiments.recorder import LocalizationRecorder
    from pimm_agents.factory import make_localizer
    from pimm_env.bags.read import BagTopics, read_steps
    from pimm_env.bags.replay_env import BagEnv
    from pimm_env.envs.sim_config import SimConfig, with_sensors

    if not specs:
        return [], True
    seeds, layouts = {spec.seed for spec in specs}, {spec.sensors for spec in specs}
    if len(seeds) != 1 or len(layouts) != 1:
        raise ExperimentError(f"one replay feeds localizers one seed and one sensor layout, got {seeds} and {layouts}")
    config = config or with_sensors(SimConfig(), specs[0].sensors)
    start = time.perf_counter()
    localizers = [
        make_localizer(s.localizer, params=s.params, map=map_path, sensors=s.sensors or "thesis")
        if map_path is not None
        else make_localizer(s.localizer, s.world, params=s.params, sensors=s.sensors)
        for s in specs
    ]
    read_aside: dict[str, int] = {}  # messages the reader set aside (a value not finite), by kind
    steps = read_steps(Path(bag), topics or BagTopics(), config.lidar2d, config.lidar3d, read_aside)
    bag_env = BagEnv(steps, config)
    env: Any = bag_env
    recorders = []
    for spec, localizer in zip(specs, localizers, strict=True):
        env = LocalizationRecorder(env, localizer, spec.start)
        recorders.append(env)
    if any(spec.start == "known" for spec in specs):  # from the first true pose: the steps before it are passed
        skipped = bag_env.skip_to_truth()  # over (said in the results' record), the localizers start there
        if bag_env.done:
            raise ExperimentError(f"{bag}: a known start needs a true pose; no step of the bag has one")
        for recorder in recorders:
            recorder.passed_over = skipped
    env.reset(seed=specs[0].seed)
    idle = np.zeros(2, dtype=np.float32)
    while not bag_env.done:
        if bag_env.next_is_kidnap:
            env.reset(options={"kidnap": True})
        else:
            env.step(idle)
    wall = time.perf_counter() - start
    results = []
    for spec, recorder in zip(specs, recorders, strict=True):
        log = recorder.trial_log()
        for kind, count in read_aside.items():  # counted with what each localizer's guard set aside
            log.set_aside[kind] = log.set_aside.get(kind, 0) + count
        if bag_env.has_truth:  # scored on the rows with a true pose; the others are counted, not dropped whole
            log, untrue = with_truth(log)
            if untrue:
                log.set_aside["no_truth_rows"] = untrue
        results.append(TrialResult(spec, log, metrics_of(log), wall, True))
    return results, bag_env.has_truth


def replay_specs(
    bag: Path,
    localizers: Sequence[str],
    params: dict[str, dict],
    seed: int,
    world: str,
    sensors: str | None = None,
    topics: Any = None,
    folder: Path | None = None,
    start: str = "global",
    trial: int = 0,
) -> list[TrialSpec]:
    """One spec per localizer, named after the scenario the bag's record file gives (else the bag's name). The
    LiDAR layouts: ``sensors`` if given, else the sensors file recorded with the bag (else its record file's
    presets), else read from the bag's first scan and cloud into ``folder``/sensors.yaml
    (``pimm_env/bags/layout.py``)."""
    from pimm_env.bags.record import SENSORS_FILE

    scenario, recorded = Path(bag).name, None
    record = bag_record(bag)
    if record is not None:
        scenario, recorded = str(record.get("scenario", scenario)), str(record.get("sensors", "thesis"))
        if (Path(bag) / SENSORS_FILE).is_file():  # the whole layouts, mount poses included
            recorded = str(Path(bag) / SENSORS_FILE)
    chosen = sensors or recorded or layouts_file(Path(bag), topics, folder)
    return [
        replace(TrialSpec(scenario, name, trial, seed, world), params=params.get(name, {}), sensors=chosen, start=start)
        for name in localizers
    ]


def bag_record(bag: Path) -> dict[str, Any] | None:
    """What ``record`` wrote beside a bag (world, scenario, seed, sensors), or None for a bag made elsewhere."""
    from pimm_env.bags.record import RECORD_FILE

    record_file = Path(bag) / RECORD_FILE
    if not record_file.is_file():
        return None
    import yaml

    return yaml.safe_load(record_file.read_text()) or {}


def recorded_seed(bag: Path) -> int:
    """The seed a bag was recorded with (its record file), else 0: replayed with it, a recorded trial gives the
    live trial's results."""
    return int((bag_record(bag) or {}).get("seed", 0))


def layouts_file(bag: Path, topics: Any, folder: Path | None) -> str:
    """The bag's LiDAR layouts, read from its messages and written as a sensors file in ``folder``; its path."""
    from pimm_env.bags.layout import layouts_from_bag
    from pimm_env.bags.read import BagTopics
    from pimm_env.sim.sensors import write_sensors_file

    if folder is None:
        raise ExperimentError(f"{bag}: no record file says its LiDARs; give sensors, or a folder for the layouts read")
    topics = topics or BagTopics()
    lidar3d, lidar2d = layouts_from_bag(bag, topics.scan, topics.points)
    note = f"LiDAR layouts read from the first messages of {bag} ({topics.scan}, {topics.points})"
    return str(write_sensors_file(Path(folder) / "sensors.yaml", lidar3d, lidar2d, note))


@dataclass
class Replay:
    """A finished replay: its results folder, every localizer's result, and whether the bag had ground truth
    (without it only the estimates are written, as TUM files, and ``summary`` is empty)."""

    folder: Path
    results: list[TrialResult]
    has_truth: bool
    summary: dict[str, Any]


def run_replay(
    bag: Path,
    localizers: dict[str, dict[str, Any]],
    out: Path,
    seed: int | None = None,
    world: str = "iilab",
    map_path: Path | None = None,
    sensors: str | None = None,
    topics: Any = None,
    start: str = "global",
    trials: int = 1,
    command: str | None = None,
) -> Replay:
    """Feed ``bag`` to every localizer (``{name: resolved params}``) ``trials`` times, trial i with seed ``seed`` +
    i (``seed`` None: the seed the bag was recorded with, else 0), from a ``start`` of ``global`` or ``known``,
    and write the results folder under ``out`` (no folder is left behind when the bag or map is unusable)."""
    import shutil

    from pimm_agents.experiments.experiment import new_folder
    from pimm_agents.params import write_params_file
    from pimm_agents.results.folder import write_results, write_run_record
    from pimm_agents.results.tum import write_tum
    from pimm_env.bags.read import BagTopics
    from pimm_env.mapping.derived_maps import ensure_derived_maps
    from pimm_env.mapping.map_server import load_map_server
    from pimm_env.sim.sensors import sensor_layouts
    from pimm_env.world.files import load_world

    topics = topics or BagTopics()
    if sensors is not None:
        sensor_layouts(sensors)
    if trials < 1:
        raise ExperimentError(f"trials must be at least 1, got {trials}")
    seed = recorded_seed(bag) if seed is None else seed
    folder = new_folder(out, "replay")
    try:
        if map_path is not None:
            occupancy, corners = load_map_server(map_path), None
        else:
            maps = ensure_derived_maps(load_world(world))
            occupancy, corners = maps.occupancy, maps.corners.xy
        results, has_truth, specs = [], True, []
        for trial in range(trials):
            specs = replay_specs(
                bag, list(localizers), localizers, seed + trial, world, sensors, topics, folder, start, trial
            )
            done, truth = replay_bag(bag, specs, map_path, topics)
            results += done
            has_truth = has_truth and truth
    except BaseException:  # any failure (a bug, Ctrl-C too) leaves no half-made results folder
        shutil.rmtree(folder, ignore_errors=True)
        raise
    write_params_file(folder / "config.yaml", localizers)
    record = {"command": command, "bag": str(bag), "world": None if map_path else world,
              "map": str(map_path) if map_path else None, "localizers": list(localizers), "seed": seed,
              "trials": trials, "start": start, "ground_truth": has_truth,
              "sensors": specs[0].sensors if specs else sensors}  # fmt: skip
    if not has_truth:
        write_run_record(folder, record)
        for result in results:
            name = result.spec.localizer if trials == 1 else f"{result.spec.localizer}/trial{result.spec.trial:02d}"
            write_tum(folder / "tum" / name / "est.tum", result.log.time, result.log.estimate)
        return Replay(folder, results, False, {})
    return Replay(folder, results, True, write_results(folder, results, record, occupancy, corners))
