#!/usr/bin/env python3
"""PIMM's command line: run the experiments, measure the parts, time the stages.

    python evaluate.py                 # the main job on the default world: 3 trials of every scenario
    python evaluate.py run --scenarios area_b a_c_b --localizers amcl --trials 10 --seed 0 --out results/
    python evaluate.py score results/<run>/logs/   # files or folders
    python evaluate.py rollout --scenarios area_a area_b --seed 0 --out results/
    python evaluate.py bench [--json]

Heavy modules are imported inside the commands so that ``--help`` is instant.
"""

from __future__ import annotations

import json
import sys
from datetime import datetime
from pathlib import Path

import typer

app = typer.Typer(add_completion=False, no_args_is_help=False, help=__doc__)
DEFAULT_SCENARIOS = ["area_a", "area_b", "a_c_b", "a_c_b_kidnap"]


def _results_dir(out: Path, kind: str) -> Path:
    folder = Path(out) / f"{datetime.now():%Y-%m-%d_%H-%M-%S}_{kind}"
    folder.mkdir(parents=True, exist_ok=False)
    return folder


def _latest_run(out: Path, kind: str = "run") -> Path | None:
    """The newest ``*_KIND`` folder under ``out`` (timestamped names sort by time), if any."""
    runs = sorted(p for p in Path(out).glob(f"*_{kind}") if p.is_dir())
    return runs[-1] if runs else None


@app.callback(invoke_without_command=True)
def main(ctx: typer.Context) -> None:
    """With no command: the main job, 3 trials of every scenario with every localizer on the default world."""
    if ctx.invoked_subcommand is None:
        run(
            scenarios=DEFAULT_SCENARIOS,
            localizers=None,
            trials=3,
            seed=0,
            world="iilab",
            out=Path("results"),
            workers=0,
            params=None,
            settings=[],
            json_out=False,
            resume=False,
            video=None,
            sensors="thesis",
            start="global",
            backend="local",
            address=None,
            fault="",
            walkers=0,
            unmapped=0,
        )


@app.command()
def run(
    scenarios: list[str] | None = typer.Option(None, "--scenarios", help="scenario names (default: the world's)"),
    localizers: list[str] | None = typer.Option(
        None, "--localizers", help="names or module:factory (default: every registered one, or --params' sections)"
    ),
    trials: int = typer.Option(10, min=1, help="trials per scenario and localizer (thesis: 10)"),
    seed: int = typer.Option(0, help="trial i uses seed + i for the simulation and the localizer"),
    world: str = typer.Option("iilab", help="world name or world file"),
    out: Path = typer.Option(Path("results"), help="where the timestamped results folder goes"),
    workers: int = typer.Option(0, help="worker processes (0: one per core)"),
    params: Path | None = typer.Option(None, "--params", help="params file: one section per localizer name"),
    settings: list[str] = typer.Option([], "--set", help="NAME.KEY=VALUE, e.g. amcl.max_particles=500"),
    json_out: bool = typer.Option(False, "--json", help="print the summary as one JSON object"),
    resume: bool = typer.Option(
        False, "--resume", help="continue the newest run folder under --out: run only the trials it lacks"
    ),
    video: str | None = typer.Option(
        None, "--video", help="best | worst | all: replay those trials as animations (videos/ in the results)"
    ),
    sensors: str = typer.Option("thesis", help="LiDAR presets, comma-separated (thesis, hokuyo-utm30lx, ...)"),
    start: str = typer.Option("global", help="global (pose unknown) or known (true start, nav2's covariance)"),
    backend: str = typer.Option("local", help="local (worker processes) or ray (a local Ray, or --address)"),
    address: str | None = typer.Option(None, help="a Ray cluster to join, e.g. ray://head:10001 or auto"),
    fault: str = typer.Option(
        "", "--fault", help="faults at set times: dropout@START:DUR, slip@START:DUR, kidnap@START (comma-separated)"
    ),
    walkers: int = typer.Option(0, min=0, help="people walking about (not in the maps)"),
    unmapped: int = typer.Option(0, min=0, help="pieces of furniture along the walls that the maps do not have"),
) -> None:
    """Run localizers on scenarios: one simulation per trial feeds every localizer; trials in parallel. Prints
    the thesis's tables and writes logs and figures; each trial is saved as it finishes (see --resume)."""
    import os
    import time
    from dataclasses import replace

    from tqdm import tqdm

    from pimm_agents.experiments.runner import run_trials
    from pimm_agents.experiments.trial_store import load_stored, save_trial
    from pimm_agents.params import write_params_file
    from pimm_agents.results.folder import write_results
    from pimm_agents.results.tables import format_tables, format_timings
    from pimm_agents.scoring.trial import TrialResult, TrialSpec
    from pimm_env.driving.scenarios import load_scenarios
    from pimm_env.mapping.derived_maps import ensure_derived_maps
    from pimm_env.world.files import load_world

    loaded = load_world(world)
    maps = ensure_derived_maps(loaded)
    available = load_scenarios(loaded)
    scenarios = scenarios or list(available)
    unknown = [s for s in scenarios if s not in available]
    if unknown:
        raise typer.BadParameter(
            f"unknown scenario(s) {unknown}; valid: {', '.join(available)}", param_hint="--scenarios"
        )
    localizers, configs = _localizer_configs(localizers, params, settings)
    specs = [  # trial-major: a stopped run has every scenario's first trials
        replace(
            TrialSpec(scenario, localizer, trial, seed + trial, world, configs[localizer], sensors, start),
            faults=fault,
            walkers=walkers,
            unmapped=unmapped,
        )
        for trial in range(trials)
        for scenario in scenarios
        for localizer in localizers
    ]
    _check_sensors(sensors)
    _check_faults(fault)
    if start not in ("global", "known"):
        raise typer.BadParameter(f"expected global or known, got {start!r}", param_hint="--start")
    _check_backend(backend, address)
    if video not in (None, "best", "worst", "all"):
        raise typer.BadParameter(f"expected best, worst or all, got {video!r}", param_hint="--video")
    workers = workers or os.cpu_count() or 1
    earlier = _latest_run(out) if resume else None
    folder = earlier or _results_dir(out, "run")
    stored = load_stored(folder, specs) if earlier else {}
    todo = [spec for i, spec in enumerate(specs) if i not in stored]
    if resume and not json_out:
        where = f"{len(stored)} of {len(specs)} trials already in {folder}" if earlier else f"no run under {out}"
        typer.echo(f"resume: {where}; running {len(todo)}", err=True)
    began = time.perf_counter()

    def done(result: TrialResult) -> None:
        save_trial(folder, result)
        bar.update()

    with tqdm(total=len(todo), desc="trials", unit="trial", disable=json_out) as bar:
        fresh = iter(run_trials(todo, min(workers, max(1, len(todo))), done, backend, address))
    results = [stored[i] if i in stored else next(fresh) for i in range(len(specs))]
    write_params_file(folder / "config.yaml", configs)
    run_record = {
        "world": world,
        "scenarios": scenarios,
        "localizers": localizers,
        "trials": trials,
        "seed": seed,
        "workers": workers,
        "wall_s": round(time.perf_counter() - began, 1),
        "trials_run": len(todo),
        "trials_reused": len(stored),
        "sensors": sensors,
        "start": start,
        "backend": backend if address is None else f"ray at {address}",
        "repeat": (
            f"python evaluate.py run --params config.yaml --world {world} --scenarios {' '.join(scenarios)} "
            f"--trials {trials} --seed {seed}"
            + ("" if sensors == "thesis" else f" --sensors {sensors}")
            + ("" if start == "global" else f" --start {start}")
        ),
    }
    summary = write_results(folder, results, run_record, maps.occupancy, maps.corners.xy)
    if video is not None:
        _write_videos(folder, results, video, maps, quiet=json_out)
    if json_out:
        typer.echo(json.dumps({**summary, "folder": str(folder)}))
        return
    typer.echo(f"start: {'the true pose, nav2 initial covariance' if start == 'known' else 'global (pose unknown)'}")
    typer.echo(format_tables(summary))
    typer.echo(format_timings(summary))
    typer.echo(
        f"\n{len(todo)} trials in {run_record['wall_s']} s"
        + (f" ({len(stored)} more from the earlier run)" if stored else "")
        + f"; results: {folder}/ (summary.json, config.yaml, run.json, trials/, logs/, figures/)"
    )


def _localizer_configs(
    localizers: list[str] | None, params: Path | None, settings: list[str]
) -> tuple[list[str], dict[str, dict]]:
    """The localizers to run (default: the params file's sections, else every registered one) and each one's
    resolved settings; a bad name or setting fails here, in the main process, naming it."""
    from pimm_agents.factory import available_localizers, check_name, resolved_params
    from pimm_agents.params import merge_params, parse_settings, read_params_file
    from pimm_env.errors import ParamsError

    try:
        from_file = read_params_file(params) if params is not None else {}
    except ParamsError as error:
        raise typer.BadParameter(str(error), param_hint="--params") from None
    names = localizers or list(from_file) or available_localizers()
    for name in names:
        try:
            check_name(name)
        except ValueError as error:
            raise typer.BadParameter(str(error), param_hint="--localizers") from None
    try:
        sections = merge_params(from_file, parse_settings(settings, names))
        return names, {name: resolved_params(name, sections.get(name)) for name in names}
    except ParamsError as error:
        raise typer.BadParameter(str(error), param_hint="--params/--set") from None


def _check_backend(backend: str, address: str | None) -> None:
    from pimm_agents.experiments.engines import check_backend

    try:
        check_backend(backend, address)
    except ValueError as error:
        raise typer.BadParameter(str(error), param_hint="--backend") from None


def _check_faults(faults: str) -> None:
    from pimm_env.envs.faults import parse_faults

    try:
        parse_faults(faults)
    except ValueError as error:
        raise typer.BadParameter(str(error), param_hint="--fault") from None


def _check_sensors(sensors: str) -> None:
    from pimm_env.sim.sensors import sensor_layouts

    try:
        sensor_layouts(sensors)
    except ValueError as error:
        raise typer.BadParameter(str(error), param_hint="--sensors") from None


def _write_videos(folder: Path, results: list, which: str, maps, quiet: bool) -> None:
    """Replay the chosen trials of every scenario and localizer as animations under ``folder/videos``."""
    from tqdm import tqdm

    from pimm_agents.experiments.frames import collect_frames
    from pimm_agents.results.folder import file_safe
    from pimm_agents.results.video import chosen_trials, write_video
    from pimm_agents.scoring.metrics import best_and_worst
    from pimm_agents.scoring.summaries import grouped

    groups = grouped(results, [r.spec for r in results])
    jobs = []
    for (scenario, localizer), trials in groups.items():
        best, worst = best_and_worst([t.metrics for t in trials])
        for label, index in chosen_trials(which, best, worst, len(trials)):
            jobs.append((scenario, localizer, label, trials[index]))
    (folder / "videos").mkdir(exist_ok=True)
    for scenario, localizer, label, trial in tqdm(jobs, desc="videos", unit="video", disable=quiet):
        frames = collect_frames(trial.spec)
        title = f"{localizer}, {scenario}, {label} trial (seed {trial.spec.seed})"
        target = folder / "videos" / f"{file_safe(scenario)}_{file_safe(localizer)}_{label}"
        write_video(frames, maps.occupancy, maps.corners.xy, target, title)


@app.command()
def sweep(
    spec: Path = typer.Argument(..., help="the sweep file (worlds, scenarios, localizers, grid, trials)"),
    out: Path = typer.Option(Path("results"), help="where the timestamped results folder goes"),
    workers: int = typer.Option(0, help="worker processes or Ray CPUs (0: one per core)"),
    backend: str = typer.Option("local", help="local (worker processes) or ray (a local Ray, or --address)"),
    address: str | None = typer.Option(None, help="a Ray cluster to join"),
    resume: bool = typer.Option(False, "--resume", help="continue the newest sweep folder under --out"),
    json_out: bool = typer.Option(False, "--json", help="print the summary as one JSON object"),
) -> None:
    """Run a grid (worlds x scenarios x localizers x settings x trials) into one results folder and one table."""
    import os
    import time

    from tqdm import tqdm

    from pimm_agents.experiments.runner import run_trials
    from pimm_agents.experiments.sweep import read_sweep, sweep_specs
    from pimm_agents.experiments.trial_store import load_stored, save_trial
    from pimm_agents.results.folder import write_results
    from pimm_agents.results.tables import format_tables
    from pimm_agents.scoring.trial import TrialResult
    from pimm_env.errors import ParamsError
    from pimm_env.mapping.derived_maps import ensure_derived_maps
    from pimm_env.world.files import load_world

    _check_backend(backend, address)
    try:
        study = read_sweep(spec)
        _check_sensors(study.sensors)
        specs = sweep_specs(study)
    except (ValueError, ParamsError) as error:
        typer.echo(f"error: {error}", err=True)
        raise typer.Exit(1) from None
    earlier = _latest_run(out, "sweep") if resume else None
    folder = earlier or _results_dir(out, "sweep")
    stored = load_stored(folder, specs) if earlier else {}
    todo = [s for i, s in enumerate(specs) if i not in stored]
    began = time.perf_counter()

    def done(result: TrialResult) -> None:
        save_trial(folder, result)
        bar.update()

    with tqdm(total=len(todo), desc="sweep", unit="trial", disable=json_out) as bar:
        fresh = iter(run_trials(todo, min(workers or os.cpu_count() or 1, max(1, len(todo))), done, backend, address))
    results = [stored[i] if i in stored else next(fresh) for i in range(len(specs))]
    (folder / "sweep.yaml").write_text(Path(spec).read_text())
    record = {"sweep": str(spec), "trials_run": len(todo), "trials_reused": len(stored), "backend": backend}
    record.update(wall_s=round(time.perf_counter() - began, 1), repeat=f"python evaluate.py sweep {folder}/sweep.yaml")
    one_world = len(study.worlds) == 1
    occupancy = ensure_derived_maps(load_world(study.worlds[0])).occupancy if one_world else None
    summary = write_results(folder, results, record, occupancy)
    if json_out:
        typer.echo(json.dumps({**summary, "folder": str(folder)}))
        return
    typer.echo(format_tables(summary))
    typer.echo(f"\n{len(todo)} trials in {record['wall_s']} s; results: {folder}/")


@app.command()
def record(
    scenario: str = typer.Option(..., help="the scenario to drive"),
    world: str = typer.Option("iilab", help="world name or world file"),
    seed: int = typer.Option(0, help="seed of the simulation's noise (a run's trial i uses seed + i)"),
    out: Path = typer.Option(..., help="the rosbag2 folder to write (must not exist)"),
    sensors: str = typer.Option("thesis", help="LiDAR presets, comma-separated (thesis, hokuyo-utm30lx, ...)"),
    clouds: bool = typer.Option(True, help="record the 3D LiDAR (--no-clouds: a 2D bag, 1 % of the size)"),
) -> None:
    """Drive a scenario and write it as a rosbag2: /points, /scan, /odom, /ground_truth, /events (kidnap)."""
    from pimm_env.bags.record import record_scenario

    _check_sensors(sensors)
    try:
        path = record_scenario(scenario, out, world, seed, sensors, clouds)
    except (FileExistsError, ValueError) as error:
        typer.echo(f"error: {error}", err=True)
        raise typer.Exit(1) from None
    typer.echo(f"wrote {path} (python evaluate.py replay {path} --world {world} --seed {seed} --localizers ...)")


@app.command()
def replay(
    bag: Path = typer.Argument(..., help="a rosbag2 folder or a ROS 1 .bag"),
    localizers: list[str] = typer.Option(["amcl"], "--localizers", help="names or module:factory"),
    world: str = typer.Option("iilab", help="the prepared world the bag was recorded in"),
    map_path: Path | None = typer.Option(None, "--map", help="a map_server .yaml: map-only localizers, no world"),
    seed: int = typer.Option(0, help="the localizers' seed (a recorded bag: the seed it was recorded with)"),
    odom_topic: str = typer.Option("/odom", "--odom-topic"),
    scan_topic: str = typer.Option("/scan", "--scan-topic"),
    points_topic: str = typer.Option("/points", "--points-topic"),
    truth_topic: str = typer.Option("/ground_truth", "--truth-topic", help="nav_msgs/Odometry of the true pose"),
    params: Path | None = typer.Option(None, "--params", help="params file: one section per localizer name"),
    settings: list[str] = typer.Option([], "--set", help="NAME.KEY=VALUE"),
    out: Path = typer.Option(Path("results"), help="where the timestamped results folder goes"),
    json_out: bool = typer.Option(False, "--json", help="print the summary as one JSON object"),
    sensors: str | None = typer.Option(
        None,
        help="LiDAR presets or a sensors .yaml of the bag (default: what `record` wrote it with, else read from its "
        "first scan and cloud into the results folder's sensors.yaml)",
    ),
) -> None:
    """Feed a bag to localizers and write the same results folder as run (metrics where it has ground truth)."""
    from pimm_agents.experiments.replay import replay_bag, replay_specs
    from pimm_agents.params import write_params_file
    from pimm_agents.results.folder import write_results
    from pimm_agents.results.tables import format_tables
    from pimm_agents.results.tum import write_tum
    from pimm_env.bags.read import BagTopics
    from pimm_env.errors import BagError, MapFileError
    from pimm_env.mapping.derived_maps import ensure_derived_maps
    from pimm_env.mapping.map_server import load_map_server
    from pimm_env.world.files import load_world

    localizers, configs = _localizer_configs(localizers, params, settings)
    if sensors is not None:
        _check_sensors(sensors)
    topics = BagTopics(odom=odom_topic, scan=scan_topic, points=points_topic, truth=truth_topic)
    folder = _results_dir(out, "replay")
    try:
        specs = replay_specs(bag, localizers, configs, seed, world, sensors, topics, folder)
        if map_path is not None:
            occupancy, corners = load_map_server(map_path), None
        else:
            maps = ensure_derived_maps(load_world(world))
            occupancy, corners = maps.occupancy, maps.corners.xy
        results, has_truth = replay_bag(bag, specs, map_path, topics)
    except (BagError, MapFileError, ValueError) as error:
        import shutil

        shutil.rmtree(folder, ignore_errors=True)  # made before the layouts were read into it: no empty results
        typer.echo(f"error: {error}", err=True)
        raise typer.Exit(1) from None
    write_params_file(folder / "config.yaml", configs)
    record = {"bag": str(bag), "world": None if map_path else world, "map": str(map_path) if map_path else None,
              "localizers": localizers, "seed": seed, "ground_truth": has_truth,
              "sensors": specs[0].sensors if specs else sensors}  # fmt: skip
    if not has_truth:
        (folder / "run.json").write_text(json.dumps(record, indent=2))
        for result in results:
            write_tum(folder / "tum" / result.spec.localizer / "est.tum", result.log.time, result.log.estimate)
        typer.echo(f"{bag} has no {truth_topic}: estimates only, in {folder}/tum/<localizer>/est.tum")
        return
    summary = write_results(folder, results, record, occupancy, corners)
    if json_out:
        typer.echo(json.dumps({**summary, "folder": str(folder)}))
        return
    typer.echo(format_tables(summary))
    typer.echo(f"\nresults: {folder}/")


@app.command()
def score(
    paths: list[Path] = typer.Argument(..., help="trial logs (thesis CSV format) or folders holding them"),
    drop_repeated: bool = typer.Option(False, "--drop-repeated", help="drop rows that repeat the previous stamp"),
    drop_uninitialised: bool = typer.Option(
        False, "--drop-uninitialised", help="drop leading rows whose estimate is still (0, 0)"
    ),
    json_out: bool = typer.Option(False, "--json", help="print one JSON object"),
) -> None:
    """The thesis's metrics from trial logs made anywhere (columns timestamp_real ... cov_theta), grouped by
    scenario and localizer where the sidecars or file names say so; reports faults a recorded log may have."""
    from pimm_agents.results.scored_logs import find_logs, group_summaries, score_log

    try:
        scored = [score_log(p, drop_repeated, drop_uninitialised) for p in find_logs(paths)]
    except (ValueError, FileNotFoundError) as error:  # the message names the file and line: print it whole
        typer.echo(f"error: {error}", err=True)
        raise typer.Exit(1) from None
    groups = group_summaries(scored)
    if json_out:
        trials = {
            str(item.path): {**vars(item.metrics), "group": item.group, "faults": vars(item.faults)} for item in scored
        }
        typer.echo(json.dumps({"trials": trials, "groups": groups}))
        return
    for item in scored:
        m = item.metrics
        verdict = (
            f"converged at {m.convergence_time_s:.2f} s, error {m.position_error_m:.2f} m / {m.angle_error_deg:.1f} deg"
            if m.converged
            else "did not converge"
        )
        kidnap = " (from the kidnap)" if item.log.kidnap_index is not None else ""
        typer.echo(f"{item.path}: {verdict}{kidnap}")
        if item.faults.any:
            typer.echo(f"  warning: {item.faults.describe()}", err=True)

    def cell(value: float | None, fmt: str) -> str:
        return "-" if value is None else format(value, fmt)

    width = max(12, *(len(name) + 2 for name in groups))
    typer.echo(f"\n{'group':<{width}}{'trials':>7}{'conv. rate %':>14}{'conv. time s':>14}{'pos. err m':>12}"
               f"{'ang. err deg':>14}")  # fmt: skip
    for name, row in groups.items():
        typer.echo(
            f"{name:<{width}}{row['trials']:>7}{100 * float(row['convergence_rate']):>14.0f}"
            f"{cell(row['convergence_time_s'], '.2f'):>14}{cell(row['position_error_m'], '.2f'):>12}"
            f"{cell(row['angle_error_deg'], '.2f'):>14}"
        )
    if any(item.faults.any for item in scored) and not (drop_repeated and drop_uninitialised):
        typer.echo("(faults reported above: --drop-repeated / --drop-uninitialised leave those rows out)", err=True)


@app.command()
def rollout(
    scenarios: list[str] | None = typer.Option(None, "--scenarios", help="scenario names (default: the world's)"),
    world: str = typer.Option("iilab", help="world name or world file"),
    seed: int = typer.Option(0, help="seed of the simulation's noise"),
    out: Path = typer.Option(Path("results"), help="where the timestamped results folder goes"),
    json_out: bool = typer.Option(False, "--json", help="print one JSON object instead of a table"),
) -> None:
    """Drive each scenario's waypoints (3D LiDAR on) and report length, time and odometry drift."""
    from tqdm import tqdm

    from pimm_env.driving.plots import plot_rollouts
    from pimm_env.driving.rollout import run
    from pimm_env.driving.scenarios import load_scenarios
    from pimm_env.mapping.derived_maps import ensure_derived_maps
    from pimm_env.world.files import load_world

    loaded = load_world(world)
    occupancy = ensure_derived_maps(loaded).occupancy
    available = load_scenarios(loaded)
    scenarios = scenarios or list(available)
    unknown = [s for s in scenarios if s not in available]
    if unknown:
        raise typer.BadParameter(
            f"unknown scenario(s) {unknown}; valid: {', '.join(available)}", param_hint="--scenarios"
        )
    folder = _results_dir(out, "rollout")
    results = []
    for name in scenarios:
        scenario = available[name]
        expected_s = scenario.length * (2 if scenario.kidnap_to is not None else 1) / scenario.speed
        with tqdm(total=round(expected_s), desc=name, unit="sim s", disable=json_out, leave=False) as bar:

            def advance(obs: dict, info: dict, bar: tqdm = bar) -> None:
                bar.update(max(0, int(float(obs["time"][0])) - bar.n))

            results.append(run(scenario, world=loaded, seed=seed, on_step=advance))
    summary = {
        r.scenario: {
            "length_m": round(r.length_m, 3),
            "path_length_m": round(
                available[r.scenario].length * (2 if available[r.scenario].kidnap_to is not None else 1), 3
            ),
            "thesis_length_m": available[r.scenario].thesis_length_m,
            "duration_s": round(r.duration_s, 2),
            "thesis_duration_s": available[r.scenario].thesis_duration_s,
            "odometry_drift_m": None if r.final_drift_m != r.final_drift_m else round(r.final_drift_m, 3),
            "odometry_drift_percent": None if r.drift_percent != r.drift_percent else round(r.drift_percent, 2),
            "collided": r.collided,
            "completed": r.completed,
            "realtime_factor": round(r.realtime_factor, 2),
        }
        for r in results
    }
    (folder / "rollouts.json").write_text(json.dumps({"world": world, "seed": seed, "rollouts": summary}, indent=2))
    picture = plot_rollouts(occupancy, results, folder / "rollouts.png")
    if json_out:
        typer.echo(json.dumps({"world": world, "seed": seed, "rollouts": summary, "folder": str(folder)}))
        return
    header = (
        f"{'scenario':<14}{'length m':>10}{'thesis m':>10}{'time s':>9}{'thesis s':>10}"
        f"{'drift m':>9}{'drift %':>9}{'RTF':>6}  ok"
    )
    typer.echo(header)
    for name, row in summary.items():
        drift = "-" if row["odometry_drift_m"] is None else f"{row['odometry_drift_m']:.2f}"
        pct = "-" if row["odometry_drift_percent"] is None else f"{row['odometry_drift_percent']:.2f}"
        ok = "yes" if row["completed"] and not row["collided"] else "NO"
        typer.echo(
            f"{name:<14}{row['length_m']:>10.2f}{row['thesis_length_m'] or 0:>10.2f}{row['duration_s']:>9.1f}"
            f"{row['thesis_duration_s'] or 0:>10.2f}{drift:>9}{pct:>9}{row['realtime_factor']:>6.1f}  {ok}"
        )
    typer.echo(f"\nresults: {folder}/ (rollouts.json, {picture.name})")


@app.command()
def bench(
    json_out: bool = typer.Option(False, "--json", help="print one JSON object"),
    repeats: int = typer.Option(30, help="timed repetitions per figure"),
) -> None:
    """Time each stage on this machine (medians, ms) and the real-time factor of an area_a rollout."""
    from pimm_agents.measurement.benchmark import run_benchmarks
    from pimm_agents.results.provenance import machine
    from pimm_env.mapping.derived_maps import ensure_derived_maps
    from pimm_env.world.files import load_world

    ensure_derived_maps(load_world("iilab"))
    figures = run_benchmarks(repeats=repeats)
    if json_out:
        typer.echo(json.dumps(figures))
        return
    here = machine()
    cpu = f"{here['cpu'] or 'unknown CPU'} ({here['vector'] or 'vector unit unknown'})"
    typer.echo(f"machine: {cpu}, {here['cores']} logical cores, torch {here['torch']}")
    for key, value in figures.items():
        typer.echo(f"{key:<24}{value:>10.3f}")


@app.command()
def perception(
    world: str = typer.Option("iilab", help="world name or world file"),
    scans: int = typer.Option(50, min=1, help="fresh scans at random free poses"),
    seed: int = typer.Option(1, help="seed of the scan poses (keep it apart from training seeds)"),
    json_out: bool = typer.Option(False, "--json", help="print one JSON object"),
    figure: Path | None = typer.Option(None, help="also draw retrievals and the confusion matrix to this PNG"),
) -> None:
    """Measure perception on fresh scans no training or map used: segmentation IoU, fingerprint retrieval,
    and the corner detector on true and on predicted labels (parts whose trained files are missing are left out)."""
    from pimm_agents.measurement.corner_quality import collect_scans
    from pimm_agents.measurement.perception_quality import perception_report
    from pimm_agents.perception.files import checkpoint_path, fingerprint_path, load_perception
    from pimm_agents.perception.segmenter import Segmenter
    from pimm_agents.results.tables import format_perception
    from pimm_env.mapping.derived_maps import ensure_derived_maps
    from pimm_env.world.files import load_world

    loaded = load_world(world)
    maps = ensure_derived_maps(loaded)
    segmenter = fingerprints = None
    if not checkpoint_path(loaded).exists():
        typer.echo(
            f"{checkpoint_path(loaded)} is missing: only the corner detector on true labels is measured", err=True
        )
    elif not fingerprint_path(loaded).exists():
        typer.echo(
            f"{fingerprint_path(loaded)} is missing (python evaluate.py world prepare {world}): retrieval is left out",
            err=True,
        )
        segmenter = Segmenter(checkpoint_path(loaded))
    else:
        segmenter, fingerprints = load_perception(loaded)
    collected = collect_scans(world, scans, seed)
    result = perception_report(
        collected, maps.corners, segmenter, fingerprints, figure=figure, occupancy=maps.occupancy
    )
    typer.echo(json.dumps(result) if json_out else format_perception(result))


world_app = typer.Typer(add_completion=False, help="Bring your own building: import a ROS map or a mesh, prepare it.")
app.add_typer(world_app, name="world")


@world_app.command("import")
def world_import(
    source: Path = typer.Argument(..., help="a map_server .yaml (+ .pgm/.png) or a mesh (.obj .ply .stl .glb ...)"),
    name: str = typer.Option(..., help="the world's name: it is written to maps/NAME/"),
    ceiling_height: float = typer.Option(3.0, help="ceiling height (m) of a floor plan"),
    ceilings: Path | None = typer.Option(None, help="YAML of areas with other ceiling heights"),
    furnish: int = typer.Option(0, min=0, help="mapped furniture pieces to add to a floor plan"),
    seed: int = typer.Option(0, help="seed of the furniture, the routes and the fingerprint headings"),
    up_axis: str = typer.Option("z", help="a mesh's up axis: z, or y (the map point of (x, y, z) is (x, -z, y))"),
    routes: int = typer.Option(4, min=1, help="routes to generate"),
    maps_dir: Path | None = typer.Option(None, help="where worlds live (default: the project's maps/)"),
    prepare: bool = typer.Option(True, help="also prepare the world (maps, fingerprints, routes)"),
) -> None:
    """Write maps/NAME/world.yaml from a ROS map or a mesh, then prepare it."""
    from pimm_env.errors import MapFileError, WorldFileError
    from pimm_env.importers.world_import import import_world
    from pimm_env.world.files import MAPS_DIR

    try:
        path = import_world(
            source, name, maps_dir or MAPS_DIR, ceiling_height, ceilings, furnish, seed, up_axis=up_axis
        )
    except (MapFileError, WorldFileError) as error:
        typer.echo(f"error: {error}", err=True)
        raise typer.Exit(1) from None
    typer.echo(f"wrote {path}")
    if prepare:
        world_prepare(name=str(path), routes=routes, seed=seed, spacing=0.5, new_routes=True)


@world_app.command("prepare")
def world_prepare(
    name: str = typer.Argument(..., help="world name under maps/ or a world file"),
    routes: int = typer.Option(4, min=1, help="routes to generate when the world has no scenarios.yaml"),
    seed: int = typer.Option(0, help="seed of the routes and the fingerprint headings"),
    spacing: float = typer.Option(0.5, min=0.1, help="fingerprint grid spacing (m)"),
    new_routes: bool = typer.Option(False, help="replace an existing scenarios.yaml with generated routes"),
) -> None:
    """Rebuild a world's derived maps and fingerprint map; generate routes if it has no scenarios."""
    from pimm_agents.preparation.prepare import prepare_world
    from pimm_env.driving.routes import RouteConfig
    from pimm_env.errors import RoutePlanningError

    try:
        done = prepare_world(name, RouteConfig(count=routes), seed, spacing, new_routes)
    except RoutePlanningError as error:
        typer.echo(f"error: {name}: {error}", err=True)
        raise typer.Exit(1) from None
    total = sum(done.seconds.values())
    steps = ", ".join(f"{k} {v:.1f} s" for k, v in done.seconds.items())
    typer.echo(
        f"{done.world}: {done.free_m2:.0f} m^2 free, {done.corners} corners, {done.fingerprints} fingerprints, "
        f"scenarios {', '.join(done.scenarios)}{' (generated)' if done.routes_written else ''}; "
        f"prepared in {total:.1f} s ({steps}) -> {done.folder}"
    )
    typer.echo(f"next: python evaluate.py run --world {done.folder / 'world.yaml'}")


#: Options that take several values after one flag (``--scenarios a b c``), as ARCHITECTURE.md writes them.
LIST_OPTIONS = ("--scenarios", "--localizers")


def expand_list_options(argv: list[str]) -> list[str]:
    """Rewrite ``--scenarios a b`` as ``--scenarios a --scenarios b``, the form click parses."""
    out: list[str] = []
    current = None
    for token in argv:
        if token.startswith("-"):
            current = token if token in LIST_OPTIONS else None
            out.append(token)
        elif current is not None and out[-1] != current:
            out += [current, token]
        else:
            out.append(token)
    return out


def cli() -> int:
    """The command line, with a user's mistakes (a missing file, a bad world file, stale maps) reported as one
    line naming the file instead of a traceback; set PIMM_DEBUG=1 for the traceback."""
    import os

    try:
        return app(args=expand_list_options(sys.argv[1:]))
    except Exception as error:
        from pimm_env.errors import PimmError  # here, so that --help stays instant

        if os.environ.get("PIMM_DEBUG") or not isinstance(error, PimmError):
            raise
        typer.echo(f"error: {error}", err=True)
        return 1


if __name__ == "__main__":
    sys.exit(cli())
