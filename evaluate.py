#!/usr/bin/env python3
"""PIMM's command line: options plus one call into the library per command (docs/command-line.md).
A PimmError (a user's mistake) prints as one line; any other error shows its traceback (PIMM_DEBUG=1: both)."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import typer

from pimm_agents import command_line
from pimm_agents.commands import bags, measure, robot, worlds
from pimm_agents.commands.options import (
    ADDRESS,
    BACKEND,
    JSON,
    MARKDOWN,
    OUT,
    PARAMS,
    SENSORS,
    SETTINGS,
    WORKERS,
    WORLD,
    as_json,
    this_command,
)

command = command_line.command
app = typer.Typer(add_completion=False, no_args_is_help=False, help=__doc__)


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
    fault: str = typer.Option(
        "", "--fault", help="dropout@START:DUR, slip@START:DUR, kidnap@START[:anywhere] (comma-separated)"
    ),
    kidnaps: int = typer.Option(
        0, min=0, help="N: N kidnap trials per route in place of --trials, each kidnapped once to a seeded place"
    ),
    walkers: int = typer.Option(0, min=0, help="people walking about (not in the maps)"),
    unmapped: int = typer.Option(0, min=0, help="pieces of furniture along the walls that the maps do not have"),
    driver: str = typer.Option(
        "route", help="route (the waypoints) or policy:NAME (random, greedy, trained or a policy's .zip)"
    ),
    maps: str = typer.Option("", help="a world whose maps the localizers take (default: --world's own)"),
) -> None:
    """Run localizers on scenarios (one simulation per trial feeds them all) into a resumable results folder."""
    from pimm_agents.experiments import Execution, RunPlan, read_plan, resolve_localizers

    plan = read_plan(from_file) if from_file else None
    if plan is None:
        chosen = resolve_localizers(localizers, params, settings)
        plan = RunPlan(
            world, chosen, tuple(scenarios or ()), trials, seed, sensors, start, fault, walkers, unmapped, driver,
            kidnaps, maps,
        )  # fmt: skip
    _run_plan(plan, Execution(workers, backend, address, progress=not json_out), out, resume, video)


def _run_plan(plan: Any, execution: Any, out: Path, resume: bool = False, video: str | None = None) -> None:
    """Run ``plan`` (``run`` and the main job); print its tables, or its JSON when there is no progress bar."""
    from pimm_agents.experiments import Experiment, write_videos
    from pimm_agents.results.tables import format_run

    outcome = Experiment.of_plan(plan, execution).run(out, resume, this_command())
    if video is not None:
        write_videos(outcome, video, progress=execution.progress)
    typer.echo(format_run(outcome) if execution.progress else as_json(outcome.summary, outcome.folder))


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
    outcome = experiment.run(out, resume, this_command())
    text = f"{format_tables(outcome.summary)}\n\n{outcome.trials_run} trials in {outcome.wall_s} s"
    typer.echo(as_json(outcome.summary, outcome.folder) if json_out else f"{text}; results: {outcome.folder}/")


@command(app)
def report(
    folder: Path = typer.Argument(..., help="a results folder of run, sweep or replay"),
    markdown: bool = MARKDOWN,
    thesis: bool = typer.Option(True, help="the thesis's rows beside PIMM's and AMCL's"),
) -> None:
    """Print a results folder's tables again, as text or as Markdown naming the command, commit and machine."""
    from pimm_agents.results.markdown import markdown_report, text_report

    typer.echo(markdown_report(folder, thesis) if markdown else text_report(folder), nl=False)


for group in (bags, measure, robot):  # their commands are evaluate.py's own
    app.registered_commands += group.app.registered_commands
app.add_typer(worlds.world_app, name="world")
app.add_typer(bags.convert_app, name="convert")


#: Options that take several values after one flag (``--scenarios a b c``), as the docs write them.
LIST_OPTIONS = ("--scenarios", "--localizers", "--policy")


def expand_list_options(argv: list[str]) -> list[str]:
    return command_line.expand_list_options(argv, LIST_OPTIONS)


def cli() -> int:
    return command_line.run_app(app, LIST_OPTIONS)


if __name__ == "__main__":
    sys.exit(cli())
