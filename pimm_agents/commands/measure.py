"""Measure PIMM's parts on this machine: speed, perception, corners, and the bounds of what any localizer could do.

Commands of ``evaluate.py``; each imports what it needs inside (``--help`` stays instant)."""

from __future__ import annotations

import json
from pathlib import Path

import typer

from pimm_agents.command_line import command
from pimm_agents.commands.options import ADDRESS, BACKEND, JSON, MARKDOWN, OUT, WORLD, as_json, this_command

app = typer.Typer(add_completion=False)


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
    typer.echo(as_json(record, folder) if json_out else text)


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
    text = bench_markdown(figures, this_command()) if markdown else format_bench(figures, machine())
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
    text = perception_markdown(result, this_command()) if markdown else format_perception(result)
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
    typer.echo(json.dumps(table) if json_out else perception_table_markdown(table, this_command()))


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
