#!/usr/bin/env python3
"""PIMM's command line: options plus one call into the library per command (docs/command-line.md).
A PimmError (a user's mistake) prints as one line; any other error shows its traceback (PIMM_DEBUG=1: both)."""

from __future__ import annotations

import json
import shlex
import sys
from pathlib import Path
from typing import Any

import typer

from pimm_agents import command_line

command = command_line.command
app = typer.Typer(add_completion=False, no_args_is_help=False, help=__doc__)
world_app = typer.Typer(add_completion=False, help="Bring your own building: import a ROS map or a mesh, prepare it.")
app.add_typer(world_app, name="world")
convert_app = typer.Typer(add_completion=False, help="Turn logs in other formats into bags that replay reads.")
app.add_typer(convert_app, name="convert")

WORLD = typer.Option("iilab", help="world name or world file")
OUT = typer.Option(Path("results"), help="where the timestamped results folder goes")
JSON = typer.Option(False, "--json", help="print one JSON object")
#: the policy ``--policy trained`` means (``python -m training policy --out`` writes it)
PARAMS = typer.Option(None, "--params", help="params file: one section per localizer name")
SETTINGS = typer.Option([], "--set", help="NAME.KEY=VALUE, e.g. amcl.max_particles=500")
SENSORS = typer.Option("thesis", help="LiDAR presets, comma-separated (thesis, hokuyo-utm30lx, ...), or a .yaml")
BACKEND = typer.Option("local", help="local (worker processes) or ray (a local Ray, or --address)")
ADDRESS = typer.Option(None, help="a Ray cluster to join, e.g. ray://head:10001 or auto")
WORKERS = typer.Option(0, help="worker processes or Ray CPUs (0: one per core)")
MARKDOWN = typer.Option(False, "--markdown", help="Markdown tables headed by the command, commit and machine")


def _json(record: dict[str, Any], folder: Path) -> str:
    return json.dumps({**record, "folder": str(folder)})


def _command_line() -> str:
    return shlex.join(["python", "evaluate.py", *sys.argv[1:]])


@app.callback(invoke_without_command=True)
def main(ctx: typer.Context) -> None:
    """With no command: the main job, 3 trials of every scenario with every localizer on the default world."""
    from pimm_agents.experiments import Execution, RunPlan, resolve_localizers

    if ctx.invoked_subcommand is None:
        _run_plan(RunPlan(localizers=resolve_localizers(None), trials=3), Execution(), Path("results"))


@command(app)
def run(
    from_file: Path | None = typer.Option(None, "--from", help="a results folder's run.yaml: repeat that run"),
    scenarios: list[str] | None = typer.Option(None, "--scenarios", help="scenario names (default: the world's)"),
    localizers: list[str] | None = typer.Option(None, "--localizers", help="names or module:factory (default: all)"),
    trials: int = typer.Option(10, min=1, help="trials per scenario and localizer (thesis: 10)"),
    seed: int = typer.Option(0, help="trial i uses seed + i for the simulation and the localizer"),
    world: str = WORLD,
    out: Path = OUT,
    workers: int = WORKERS,
    params: Path | None = PARAMS,
    settings: list[str] = SETTINGS,
    json_out: bool = JSON,
    resume: bool = typer.Option(False, "--resume", help="continue the newest run folder under --out"),
    video: str | None = typer.Option(None, "--video", help="best | worst | all: animations under videos/"),
    sensors: str = SENSORS,
    start: str = typer.Option("global", help="global (pose unknown) or known (true start, nav2's covariance)"),
    backend: str = BACKEND,
    address: str | None = ADDRESS,
    fault: str = typer.Option("", "--fault", help="dropout@START:DUR, slip@START:DUR, kidnap@START (comma-separated)"),
    walkers: int = typer.Option(0, min=0, help="people walking about (not in the maps)"),
    unmapped: int = typer.Option(0, min=0, help="pieces of furniture along the walls that the maps do not have"),
    driver: str = typer.Option(
        "route", help="route (the waypoints) or policy:NAME (random, greedy, trained or a policy's .zip)"
    ),
) -> None:
    """Run localizers on scenarios (one simulation per trial feeds them all) into a resumable results folder."""
    from pimm_agents.experiments import Execution, RunPlan, read_plan, resolve_localizers

    plan = read_plan(from_file) if from_file else None
    if plan is None:
        chosen = resolve_localizers(localizers, params, settings)
        plan = RunPlan(
            world, chosen, tuple(scenarios or ()), trials, seed, sensors, start, fault, walkers, unmapped, driver
        )
    _run_plan(plan, Execution(workers, backend, address, progress=not json_out), out, resume, video)


def _run_plan(plan: Any, execution: Any, out: Path, resume: bool = False, video: str | None = None) -> None:
    """Run ``plan`` (``run`` and the main job); print its tables, or its JSON when there is no progress bar."""
    from pimm_agents.experiments import Experiment, write_videos
    from pimm_agents.results.tables import format_run

    outcome = Experiment.of_plan(plan, execution).run(out, resume, _command_line())
    if video is not None:
        write_videos(outcome, video, progress=execution.progress)
    typer.echo(format_run(outcome) if execution.progress else _json(outcome.summary, outcome.folder))


@command(app)
def sweep(
    spec: Path = typer.Argument(..., help="the sweep file (worlds, scenarios, localizers, grid, trials)"),
    out: Path = OUT,
    workers: int = WORKERS,
    backend: str = BACKEND,
    address: str | None = ADDRESS,
    resume: bool = typer.Option(False, "--resume", help="continue the newest sweep folder under --out"),
    json_out: bool = JSON,
) -> None:
    """Run a grid (worlds x scenarios x localizers x settings x trials) into one results folder and one table."""
    from pimm_agents.experiments import Execution, Experiment, read_sweep
    from pimm_agents.results.tables import format_tables

    experiment = Experiment.of_sweep(read_sweep(spec), spec, Execution(workers, backend, address, not json_out))
    outcome = experiment.run(out, resume, _command_line())
    text = f"{format_tables(outcome.summary)}\n\n{outcome.trials_run} trials in {outcome.wall_s} s"
    typer.echo(_json(outcome.summary, outcome.folder) if json_out else f"{text}; results: {outcome.folder}/")


@command(app)
def record(
    scenario: str = typer.Option(..., help="the scenario to drive"),
    world: str = WORLD,
    seed: int = typer.Option(0, help="seed of the simulation's noise (a run's trial i uses seed + i)"),
    out: Path = typer.Option(..., help="the rosbag2 folder to write (must not exist)"),
    sensors: str = SENSORS,
    clouds: bool = typer.Option(True, help="record the 3D LiDAR (--no-clouds: a 2D bag, 1 % of the size)"),
) -> None:
    """Drive a scenario and write it as a rosbag2: /points, /scan, /odom, /ground_truth, /events (kidnap)."""
    from pimm_env.bags.record import record_scenario

    path = record_scenario(scenario, out, world, seed, sensors, clouds)
    typer.echo(f"wrote {path} (python evaluate.py replay {path} --world {world} --seed {seed} --localizers ...)")


@command(convert_app, "carmen")
def convert_carmen(
    log: Path = typer.Argument(..., help="a CARMEN text log (.log or .log.gz): ODOM and FLASER lines"),
    out: Path = typer.Option(..., help="the rosbag2 folder to write (must not exist)"),
    max_range: float = typer.Option(80.0, help="readings at or beyond this (m) are no return (+inf)"),
) -> None:
    """Write a CARMEN laser log as a rosbag2 (/odom, /scan, /ground_truth from its corrected poses) for replay."""
    from pimm_env.bags import carmen

    counts = carmen.convert_carmen(log, out, max_range)
    typer.echo(
        f"wrote {out}: {counts['odom']} odometry, {counts['scan']} scans, {counts['truth']} true poses"
        f" ({counts['resets']} odometry resets of the corrected log left out); then: python evaluate.py map"
        f" --from-bag {out} --out MAP.yaml; python evaluate.py replay {out} --map MAP.yaml --localizers amcl"
    )


@command(app, "map")
def map_command(
    from_bag: Path = typer.Option(..., "--from-bag", help="a bag with 2D scans and true poses"),
    out: Path = typer.Option(..., help="the map_server .yaml to write (its .pgm beside it)"),
    resolution: float = typer.Option(0.05, min=0.01, help="cell size (m)"),
    scan_topic: str = typer.Option("/scan", "--scan-topic"),
    truth_topic: str = typer.Option("/ground_truth", "--truth-topic"),
    odom_topic: str = typer.Option("/odom", "--odom-topic"),
) -> None:
    """A map_server map from a bag's scans laid at its true poses (it flatters a localizer replaying that bag)."""
    from pimm_env.bags.layout import layouts_from_bag
    from pimm_env.bags.read import BagTopics
    from pimm_env.bags.scan_map import map_from_bag
    from pimm_env.mapping.from_scans import SPARSE_SCAN_SPACING_M, ScanMapConfig, scan_spacing_m
    from pimm_env.mapping.occupancy import save_map_server

    topics = BagTopics(odom=odom_topic, scan=scan_topic, points=None, truth=truth_topic, events=None)
    _, lidar2d = layouts_from_bag(from_bag, scan_topic, None)
    occupancy, poses = map_from_bag(from_bag, topics, lidar2d, ScanMapConfig(resolution=resolution))
    out.parent.mkdir(parents=True, exist_ok=True)
    save_map_server(occupancy, out)
    rows, cols = occupancy.grid.shape
    spacing = scan_spacing_m(poses)
    kind = (
        "a sparse log: replay it with --params docs/params/amcl-sparse-logs.yaml (docs/benchmarks.md)"
        if spacing > SPARSE_SCAN_SPACING_M
        else "a dense log: nav2's defaults fit it"
    )
    typer.echo(
        f"wrote {out} ({cols} x {rows} cells of {resolution} m, {int(occupancy.occupied.sum())} occupied): built"
        f" from the bag's own scans, it flatters a localizer replaying {from_bag}\n"
        f"{len(poses)} scans, {spacing:.2f} m apart on average: {kind}"
    )


@command(app)
def replay(
    bag: Path = typer.Argument(..., help="a rosbag2 folder or a ROS 1 .bag"),
    localizers: list[str] = typer.Option(["amcl"], "--localizers", help="names or module:factory"),
    world: str = typer.Option("iilab", help="the prepared world the bag was recorded in"),
    map_path: Path | None = typer.Option(None, "--map", help="a map_server .yaml: map-only localizers, no world"),
    seed: int | None = typer.Option(
        None, help="the first trial's seed (trial i: seed + i); default: the seed the bag was recorded with, else 0"
    ),
    trials: int = typer.Option(1, min=1, help="replays of the bag, each with its own seed"),
    start: str = typer.Option("global", help="global (pose unknown) or known (the bag's first true pose)"),
    odom_topic: str = typer.Option("/odom", "--odom-topic"),
    scan_topic: str = typer.Option("/scan", "--scan-topic"),
    points_topic: str = typer.Option("/points", "--points-topic"),
    truth_topic: str = typer.Option("/ground_truth", "--truth-topic", help="true pose (Odometry, Pose*, /tf)"),
    params: Path | None = PARAMS,
    settings: list[str] = SETTINGS,
    out: Path = OUT,
    json_out: bool = JSON,
    sensors: str | None = typer.Option(None, help="LiDAR presets or .yaml (default: the bag's record, or its data)"),
    stamps: str = typer.Option("header", help="time messages by their header stamps or by when the bag received them"),
) -> None:
    """Feed a bag to localizers and write the same results folder as run (metrics where it has ground truth)."""
    from pimm_agents.experiments.replay import run_replay
    from pimm_agents.experiments.run_plan import resolve_localizers
    from pimm_agents.results.tables import format_replay
    from pimm_env.bags.read import BagTopics

    topics = BagTopics(odom=odom_topic, scan=scan_topic, points=points_topic, truth=truth_topic, stamps=stamps)
    chosen = resolve_localizers(localizers, params, settings)
    done = run_replay(bag, chosen, out, seed, world, map_path, sensors, topics, start, trials, _command_line())
    if json_out:  # without ground truth there are no metrics: the record says so, and where the estimates are
        record = done.summary if done.has_truth else {"ground_truth": False, "estimates": f"{done.folder}/tum"}
        typer.echo(_json(record, done.folder))
    else:
        typer.echo(format_replay(done, truth_topic))


@command(app)
def score(
    paths: list[Path] = typer.Argument(..., help="trial logs (thesis CSV format) or folders holding them"),
    drop_repeated: bool = typer.Option(False, "--drop-repeated", help="drop rows that repeat the previous stamp"),
    drop_uninitialised: bool = typer.Option(False, "--drop-uninitialised", help="drop leading (0, 0) estimates"),
    json_out: bool = JSON,
) -> None:
    """The thesis's metrics from trial logs in its CSV format made anywhere, with the faults recorded logs carry."""
    from pimm_agents.results.scored_logs import fault_warnings, find_logs, group_summaries, score_log, score_record
    from pimm_agents.results.tables import format_scores

    scored = [score_log(p, drop_repeated, drop_uninitialised) for p in find_logs(paths)]
    typer.echo(json.dumps(score_record(scored)) if json_out else format_scores(scored, group_summaries(scored)))
    for warning in [] if json_out else fault_warnings(scored, drop_repeated and drop_uninitialised):
        typer.echo(warning, err=True)


@command(app)
def report(
    folder: Path = typer.Argument(..., help="a results folder of run, sweep or replay"),
    markdown: bool = MARKDOWN,
    thesis: bool = typer.Option(True, help="the thesis's rows beside PIMM's and AMCL's"),
) -> None:
    """Print a results folder's tables again, as text or as Markdown naming the command, commit and machine."""
    from pimm_agents.results.markdown import markdown_report, text_report

    typer.echo(markdown_report(folder, thesis) if markdown else text_report(folder), nl=False)


@command(app)
def rollout(
    scenarios: list[str] | None = typer.Option(None, "--scenarios", help="scenario names (default: the world's)"),
    world: str = WORLD,
    seed: int = typer.Option(0, help="seed of the simulation's noise"),
    out: Path = OUT,
    json_out: bool = JSON,
) -> None:
    """Drive each scenario's waypoints (3D LiDAR on) and report length, time and odometry drift."""
    from pimm_agents.experiments.experiment import new_folder
    from pimm_agents.results.tables import format_rollouts
    from pimm_env.driving.plots import write_rollouts
    from pimm_env.driving.rollout import run_scenarios

    results, rows, occupancy = run_scenarios(world, scenarios, seed, progress=not json_out)
    folder = new_folder(out, "rollout")
    record = write_rollouts(folder, world, seed, results, rows, occupancy)
    text = f"{format_rollouts(rows)}\n\nresults: {folder}/ (rollouts.json, rollouts.png)"
    typer.echo(_json(record, folder) if json_out else text)


@command(app)
def bench(
    json_out: bool = JSON, markdown: bool = MARKDOWN, repeats: int = typer.Option(30, help="timed repetitions")
) -> None:
    """Time each stage on this machine (medians, ms) and the real-time factor of an area_a rollout."""
    from pimm_agents.measurement.benchmark import run_benchmarks
    from pimm_agents.results.markdown import bench_markdown
    from pimm_agents.results.provenance import machine
    from pimm_agents.results.tables import format_bench

    figures = run_benchmarks(repeats=repeats)
    text = bench_markdown(figures, _command_line()) if markdown else format_bench(figures, machine())
    typer.echo(json.dumps(figures) if json_out else text)


@command(app)
def perception(
    world: str = WORLD,
    scans: int = typer.Option(50, min=1, help="fresh scans at random free poses"),
    seed: int = typer.Option(1, help="seed of the scan poses (keep it apart from training seeds)"),
    json_out: bool = JSON,
    markdown: bool = MARKDOWN,
    figure: Path | None = typer.Option(None, help="also draw retrievals and the confusion matrix to this PNG"),
) -> None:
    """Segmentation IoU, fingerprint retrieval and corner quality on fresh scans no training or map used."""
    from pimm_agents.measurement.perception_quality import measure_world
    from pimm_agents.results.markdown import perception_markdown
    from pimm_agents.results.tables import format_perception

    result = measure_world(world, scans, seed, figure, warn=lambda text: typer.echo(text, err=True))
    text = perception_markdown(result, _command_line()) if markdown else format_perception(result)
    typer.echo(json.dumps(result) if json_out else text)


@command(app, "perception-table")
def perception_table_command(
    weights: Path | None = typer.Option(None, help="network weights (default: the shipped layout-free network)"),
    scans: list[Path] = typer.Option([], "--scan", help="a real scan to score against its plane-fit reference"),
    worlds: list[str] = typer.Option([], "--world", help="a world to segment fresh simulated scans of"),
    layouts_world: str | None = typer.Option(None, help="a world to segment every LiDAR layout in"),
    count: int = typer.Option(20, "--scans-per-world", min=1, help="fresh scans per world and layout"),
    seed: int = typer.Option(1, help="seed of the scan poses (keep it apart from training seeds)"),
    by_object: bool = typer.Option(False, help="also list each world's objects whose returns were labelled wrong"),
    json_out: bool = JSON,
) -> None:
    """One network's segmentation on real scans, worlds and every LiDAR layout (docs/perception.md)."""
    from pimm_agents.measurement.perception_table import perception_table
    from pimm_agents.perception.files import SHIPPED_CLOUD_WEIGHTS
    from pimm_agents.results.markdown import perception_table_markdown

    table = perception_table(weights or SHIPPED_CLOUD_WEIGHTS, scans, worlds, layouts_world, count, seed, by_object)
    typer.echo(json.dumps(table) if json_out else perception_table_markdown(table, _command_line()))


@command(app)
def segment(
    file: Path = typer.Argument(
        ..., help="a scan: .pcd (ascii, binary, binary_compressed), .ply, .las/.laz, .npy, KITTI .bin"
    ),
    sensor_height: float | None = typer.Option(None, help="the sensor's height above the floor, m (default: measured)"),
    sensors: str | None = typer.Option(
        None, help="a sensors .yaml or preset whose lidar3d mount gives height and tilt"
    ),
    weights: Path | None = typer.Option(None, help="network weights (default: the shipped layout-free network)"),
    reference: bool = typer.Option(False, "--reference", help="also score against the scan's plane-fit reference"),
    drop_invalid: bool = typer.Option(False, "--drop-invalid", help="leave out NaN points of an unorganized cloud"),
    out: Path = OUT,
    json_out: bool = JSON,
) -> None:
    """Classes and corners of one scan from any LiDAR, written with pictures (docs/perception.md#your-own-scans)."""
    from pimm_agents.measurement.cloud_file import segment_file
    from pimm_agents.perception.files import SHIPPED_CLOUD_WEIGHTS
    from pimm_agents.results.tables import format_segment
    from pimm_env.sim.sensors import sensor_layouts

    tilt = None
    if sensors is not None:
        mount = sensor_layouts(sensors)[0]
        sensor_height = mount.height if sensor_height is None else sensor_height
        tilt = (mount.mount_roll_deg, mount.mount_pitch_deg)
    record = segment_file(file, weights or SHIPPED_CLOUD_WEIGHTS, out, sensor_height, tilt, drop_invalid, reference)
    typer.echo(json.dumps(record) if json_out else "\n".join(format_segment(record)))


@command(app)
def active(
    world: list[str] = typer.Option(["iilab"], "--world", help="world names or world files (several pool)"),
    policy: list[str] = typer.Option(
        ["route", "random", "greedy"], "--policy", help="route, random, greedy, trained or a policy's .zip"
    ),
    trials: int = typer.Option(1, min=1, help="episodes per route start and policy"),
    seed: int = typer.Option(0, help="seed of the first trial (then seed + 1, ...)"),
    localizer: str = typer.Option("pimm", help="the localizer in the loop"),
    limit_s: float = typer.Option(
        60.0, min=1.0, help="an episode's time limit (s): success is a right localized by then"
    ),
    workers: int = typer.Option(1, help="worker processes or Ray CPUs (0: one per core)"),
    backend: str = BACKEND,
    address: str | None = ADDRESS,
    out: Path = OUT,
    json_out: bool = JSON,
) -> None:
    """Policies that drive to localize, on the same episodes: success, time to a right localized, distance,
    collisions and false-localized time; every episode in OUT/<date>_active/summary.json
    ([environment](docs/environment.md#active-localization))."""
    from pimm_agents.experiments.active_episodes import evaluate_active
    from pimm_agents.experiments.experiment import new_folder
    from pimm_agents.results.provenance import machine, provenance
    from pimm_agents.results.tables import format_active

    result = evaluate_active(world, policy, trials, seed, localizer, limit_s, not json_out, workers, backend, address)
    folder = new_folder(out, "active")
    record = {"worlds": world, "policies": policy, "trials": trials, "seed": seed, "localizer": localizer}
    summary = {"record": {**record, "limit_s": limit_s, **provenance(), "machine": machine()}, **result}
    (folder / "summary.json").write_text(json.dumps(summary, indent=2, default=str) + "\n")
    if json_out:
        typer.echo(json.dumps({"policies": result["policies"], "worlds": result["worlds"], "folder": str(folder)}))
    else:
        typer.echo(f"{format_active(result['policies'])}\n\nepisodes and per-world figures: {folder}/summary.json")


@command(app, "passive-bound")
def passive_bound_command(
    world: str = typer.Argument(..., help="a world name or world file"),
    scenarios: list[str] = typer.Option(["route_1"], "--scenarios", help="scenarios of that world"),
    seed: int = typer.Option(0, help="the trial's seed"),
) -> None:
    """The first time the truth led every look-alike of it (a bound for any passive localizer's time to
    localized), beside PIMM's, one JSON line per scenario ([benchmarks](docs/benchmarks.md))."""
    from dataclasses import asdict

    from pimm_agents.measurement.passive_bound import passive_bound

    for scenario in scenarios:
        typer.echo(json.dumps(asdict(passive_bound(world, scenario, seed))))


@command(app, "active-bound")
def active_bound_command(
    world: str = typer.Argument(..., help="a world name or world file"),
    scenarios: list[str] = typer.Option([], "--scenarios", help="scenarios of that world (default: every route)"),
    json_out: bool = typer.Option(False, "--json", help="print one JSON line per scenario"),
) -> None:
    """The shortest drive from each route's start to a place that tells it from every look-alike of it, and that
    over 0.5 m/s (a bound for any active-localization policy's time; [benchmarks](docs/benchmarks.md))."""
    from dataclasses import asdict

    from pimm_agents.measurement.active_bound import active_bounds

    for bound in active_bounds(world, list(scenarios) or None):
        if json_out:
            typer.echo(json.dumps(asdict(bound)))
            continue
        far = "none within 60 m" if bound.distance_m is None else f"{bound.distance_m:.1f} m, {bound.bound_s:.1f} s"
        typer.echo(f"{bound.world} {bound.scenario}: {bound.twins} twins; {far}")


@command(world_app, "import")
def world_import(
    source: Path = typer.Argument(
        ...,
        help="a map_server .yaml (+ .pgm/.png), a Gazebo world (.world .sdf) or a mesh (.obj .ply .stl .glb .dae ...)",
    ),
    name: str = typer.Option(..., help="the world's name: it is written to maps/NAME/"),
    ceiling_height: float | None = typer.Option(
        None,
        help="a floor plan's ceiling height (m; default 3); for a mesh or Gazebo world, add a flat ceiling this high",
    ),
    ceilings: Path | None = typer.Option(None, help="YAML of areas with other ceiling heights"),
    furnish: int = typer.Option(0, min=0, help="mapped furniture pieces to add to a floor plan"),
    seed: int = typer.Option(0, help="seed of the furniture, the routes and the fingerprint headings"),
    up_axis: str = typer.Option("z", help="a mesh's up axis: z, or y (the map point of (x, y, z) is (x, -z, y))"),
    rules: Path | None = typer.Option(None, help="YAML list of {match, class} name rules; they win over the defaults"),
    model_path: list[Path] = typer.Option([], help="folders of Gazebo models (model://NAME); also GAZEBO_MODEL_PATH"),
    visual: bool = typer.Option(False, help="a Gazebo world's visual geometry instead of its collision geometry"),
    wall_line: bool = typer.Option(
        True, help="class objects standing in a wall's line (windows, closed doors) wall, whatever their names say"
    ),
    routes: int = typer.Option(4, min=1, help="routes to generate"),
    maps_dir: Path | None = typer.Option(None, help="where worlds live (default: the project's maps/)"),
    prepare: bool = typer.Option(True, help="also prepare the world (maps, fingerprints, routes)"),
) -> None:
    """Write maps/NAME/world.yaml from a ROS map, a mesh or a Gazebo world, then prepare it."""
    import shutil

    from pimm_env.importers.mesh_checks import describe_world
    from pimm_env.importers.world_import import import_world, read_rules
    from pimm_env.world.files import MAPS_DIR, load_world

    folder = (maps_dir or MAPS_DIR) / name
    existed = folder.exists()
    path = import_world(
        source,
        name,
        maps_dir or MAPS_DIR,
        ceiling_height,
        ceilings,
        furnish,
        seed,
        rules=read_rules(rules) if rules else None,
        up_axis=up_axis,
        model_paths=model_path,
        geometry="visual" if visual else "collision",
        wall_line=wall_line,
    )
    typer.echo(f"wrote {path}\n{describe_world(load_world(path))}")
    if prepare:
        try:
            world_prepare(name=str(path), routes=routes, seed=seed, spacing=0.5, new_routes=True)
        except BaseException:
            if not existed:
                shutil.rmtree(folder, ignore_errors=True)
            raise


@command(world_app, "prepare")
def world_prepare(
    name: str = typer.Argument(..., help="world name under maps/ or a world file"),
    routes: int = typer.Option(4, min=1, help="routes to generate when the world has no scenarios.yaml"),
    seed: int = typer.Option(0, help="seed of the routes and the fingerprint headings"),
    spacing: float = typer.Option(0.5, min=0.1, help="fingerprint grid spacing (m)"),
    new_routes: bool = typer.Option(False, help="replace an existing scenarios.yaml with generated routes"),
) -> None:
    """Rebuild a world's derived maps and fingerprint map; generate routes if it has no scenarios."""
    from pimm_agents.preparation.prepare import describe, prepare_world
    from pimm_env.driving.routes import RouteConfig

    typer.echo(describe(prepare_world(name, RouteConfig(count=routes), seed, spacing, new_routes)))


#: Options that take several values after one flag (``--scenarios a b c``), as the docs write them.
LIST_OPTIONS = ("--scenarios", "--localizers", "--policy")


def expand_list_options(argv: list[str]) -> list[str]:
    return command_line.expand_list_options(argv, LIST_OPTIONS)


def cli() -> int:
    return command_line.run_app(app, LIST_OPTIONS)


if __name__ == "__main__":
    sys.exit(cli())
