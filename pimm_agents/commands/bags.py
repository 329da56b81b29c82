"""Recorded and users' data: write a bag, convert a log, map from a bag, replay one, score trial logs.

Commands of ``evaluate.py``; each imports what it needs inside (``--help`` stays instant)."""

from __future__ import annotations

import json
from pathlib import Path

import typer

from pimm_agents.command_line import command
from pimm_agents.commands.options import JSON, OUT, PARAMS, SENSORS, SETTINGS, WORLD, as_json, this_command
from pimm_env.errors import PimmError

app = typer.Typer(add_completion=False)
convert_app = typer.Typer(add_completion=False, help="Turn logs in other formats into bags that replay reads.")


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
    resets = f"{counts['resets']} odometry resets left out" if counts["kind"] == "corrected" else "no reset lines"
    aside = f"; {counts['non_finite']} line(s) with a value not finite set aside" if counts["non_finite"] else ""
    typer.echo(
        f"wrote {out}: {counts['odom']} odometry, {counts['scan']} scans, {counts['truth']} true poses"
        f" (a {counts['kind']} log: {resets}{aside}); then: python evaluate.py map"
        f" --from-bag {out} --out MAP.yaml; python evaluate.py replay {out} --map MAP.yaml --localizers amcl"
    )


@command(app, "map")
def map_command(
    from_bag: Path = typer.Option(..., "--from-bag", help="a bag with 2D scans (or 3D clouds) and true poses"),
    out: Path | None = typer.Option(None, help="the map_server .yaml to write (its .pgm beside it)"),
    cloud: Path | None = typer.Option(
        None,
        help="a point-cloud map (.pcd) to write from the bag's 3D clouds, as SLAM writes one (its trajectory"
        " beside it: .tum)",
    ),
    resolution: float = typer.Option(0.05, min=0.01, help="cell size (m); the point-cloud map's voxel"),
    scan_topic: str = typer.Option("/scan", "--scan-topic"),
    points_topic: str = typer.Option("/points", "--points-topic"),
    truth_topic: str = typer.Option("/ground_truth", "--truth-topic"),
    odom_topic: str = typer.Option("/odom", "--odom-topic"),
) -> None:
    """A map_server map from a bag's scans, or a point-cloud map from its clouds, laid at its true poses (either
    flatters a localizer replaying that bag)."""
    from pimm_env.bags.layout import layouts_from_bag
    from pimm_env.bags.read import BagTopics

    if out is None and cloud is None:
        raise PimmError("map: give --out MAP.yaml (an occupancy map), --cloud MAP.pcd (a point-cloud map) or both")
    if cloud is not None:
        from pimm_agents.results.tum import write_tum
        from pimm_env.bags.cloud_map import cloud_map_from_bag
        from pimm_env.clouds.pcd import write_pcd

        if cloud.suffix.lower() != ".pcd":
            raise PimmError(f"--cloud {cloud}: a point-cloud map is written as .pcd")
        topics = BagTopics(odom=odom_topic, scan=None, points=points_topic, truth=truth_topic, events=None)
        lidar3d, lidar2d = layouts_from_bag(from_bag, None, points_topic)
        if lidar3d is None:
            raise PimmError(f"{from_bag}: no 3D clouds on {points_topic!r} (--points-topic) to build a point-cloud map")
        points, times, poses = cloud_map_from_bag(from_bag, topics, lidar2d, lidar3d, resolution)
        cloud.parent.mkdir(parents=True, exist_ok=True)
        write_pcd(cloud, points)
        path = write_tum(cloud.with_suffix(".tum"), times, poses)
        typer.echo(
            f"wrote {cloud}: {len(points)} points ({resolution} m voxels) from {len(poses)} clouds, and the"
            f" trajectory they were laid along, {path}; then: python evaluate.py world import {cloud} --name NAME"
            f" --trajectory {path}"
        )
    if out is not None:
        _occupancy_map(from_bag, out, resolution, BagTopics(odom_topic, scan_topic, None, truth_topic, None))


def _occupancy_map(from_bag: Path, out: Path, resolution: float, topics) -> None:
    from pimm_env.bags.layout import layouts_from_bag
    from pimm_env.bags.scan_map import map_from_bag
    from pimm_env.mapping.from_scans import SPARSE_SCAN_SPACING_M, ScanMapConfig, scan_spacing_m
    from pimm_env.mapping.occupancy import save_map_server

    _, lidar2d = layouts_from_bag(from_bag, topics.scan, None)
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
    stamps: str = typer.Option(
        "header",
        help="header (their stamps), receive (when the bag received them) or order (the stamps, each run of equal "
        "ones spread up to the next: coarse stamps)",
    ),
) -> None:
    """Feed a bag to localizers and write the same results folder as run (metrics where it has ground truth)."""
    from pimm_agents.experiments.replay import run_replay
    from pimm_agents.experiments.run_plan import resolve_localizers
    from pimm_agents.results.tables import format_replay
    from pimm_env.bags.read import BagTopics

    topics = BagTopics(odom=odom_topic, scan=scan_topic, points=points_topic, truth=truth_topic, stamps=stamps)
    chosen = resolve_localizers(localizers, params, settings)
    done = run_replay(bag, chosen, out, seed, world, map_path, sensors, topics, start, trials, this_command())
    if json_out:  # without ground truth there are no metrics: the record says so, and where the estimates are
        record = done.summary if done.has_truth else {"ground_truth": False, "estimates": f"{done.folder}/tum"}
        typer.echo(as_json(record, done.folder))
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
