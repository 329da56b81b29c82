#!/usr/bin/env python3
"""PIMM's command line: run the experiments, measure the parts, time the stages.

    python evaluate.py                 # the main job on the default world (quick)
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


@app.callback(invoke_without_command=True)
def main(ctx: typer.Context) -> None:
    """With no command: the main job, a rollout of every scenario on the default world."""
    if ctx.invoked_subcommand is None:
        rollout(scenarios=DEFAULT_SCENARIOS, world="iilab", seed=0, out=Path("results"), json_out=False)


@app.command()
def rollout(
    scenarios: list[str] = typer.Option(DEFAULT_SCENARIOS, "--scenarios", help="scenario names"),
    world: str = typer.Option("iilab", help="world name or world file"),
    seed: int = typer.Option(0, help="seed of the simulation's noise"),
    out: Path = typer.Option(Path("results"), help="where the timestamped results folder goes"),
    json_out: bool = typer.Option(False, "--json", help="print one JSON object instead of a table"),
) -> None:
    """Drive each scenario's waypoints (3D LiDAR on) and report length, time and odometry drift."""
    from pimm_env.plots import plot_rollouts
    from pimm_env.rollout import run
    from pimm_env.scenarios import load_scenarios

    available = load_scenarios(world)
    unknown = [s for s in scenarios if s not in available]
    if unknown:
        raise typer.BadParameter(
            f"unknown scenario(s) {unknown}; valid: {', '.join(available)}", param_hint="--scenarios"
        )
    folder = _results_dir(out, "rollout")
    results = []
    for name in scenarios:
        if not json_out:
            typer.echo(f"rolling out {name} ...", err=True)
        results.append(run(available[name], world=world, seed=seed))
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
    picture = plot_rollouts(world, results, folder / "rollouts.png")
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
    from pimm_env.benchmark import run_benchmarks

    figures = run_benchmarks(repeats=repeats)
    if json_out:
        typer.echo(json.dumps(figures))
        return
    for key, value in figures.items():
        typer.echo(f"{key:<24}{value:>10.3f}")


if __name__ == "__main__":
    sys.exit(app())
