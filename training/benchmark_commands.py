"""The benchmark commands of ``python -m training``: write generated buildings, measure localizers on them, and
run a named suite (training/suites/suites.yaml)."""

from __future__ import annotations

import shlex
import sys
from pathlib import Path

import typer

from pimm_agents import command_line

app = typer.Typer(add_completion=False)


@command_line.command(app)
def buildings(
    seeds: str = typer.Option(
        "100-129",
        help="building seeds: 'A-B' or 'A,B,C' (furnished: 130-159; held out: training.buildings.NEVER_TRAIN_SEEDS,"
        " noted when given; never train on them)",
    ),
    out: Path = typer.Option(Path("build/worlds"), help="folder of the generated worlds"),
) -> None:
    """Write procedural buildings (training/buildings.py) as worlds out/gen-SEED/, with their derived maps."""
    from tqdm import tqdm

    from pimm_env.mapping.derived_maps import ensure_derived_maps
    from pimm_env.world.files import load_world
    from training.buildings import NEVER_TRAIN_SEEDS, write_building

    chosen = _seed_list(seeds)
    held = sorted(set(chosen) & set(NEVER_TRAIN_SEEDS))
    if held:
        typer.echo(f"note: seeds {held} are the held-out buildings: evaluate on them, never train on them", err=True)
    for seed in tqdm(chosen, desc="buildings", unit="building"):
        ensure_derived_maps(load_world(write_building(seed, out)))
    typer.echo(f"wrote {len(chosen)} buildings to {out}/gen-<seed>/")


@command_line.command(app)
def heldout(
    localizers: list[str] = typer.Option(["pimm", "amcl"], "--localizers", help="localizers to run"),
    trials: int = typer.Option(3, min=1, help="trials per route"),
    scans: int = typer.Option(30, min=1, help="fresh scans for the perception figures"),
    seeds: str = typer.Option("920-929", help="building seeds (the suites: training/suites/suites.yaml)"),
    workers: int = typer.Option(0, help="worker processes per run (0: one per core)"),
    worlds: Path = typer.Option(Path("build/worlds"), help="folder of the generated worlds"),
    out: Path = typer.Option(Path("results/heldout"), help="where results and the table go"),
    settings: list[str] = typer.Option([], "--set", help="NAME.KEY=VALUE for a localizer, as evaluate.py run"),
) -> None:
    """The generalization benchmark: buildings no training used, prepared with the weights the worlds use.

    Runs in passes, one trial per route more each pass over all buildings, and writes the table after each
    pass; every trial is kept as it finishes, so running the command again continues where it stopped.
    """
    from pimm_agents.experiments.run_plan import resolve_localizers
    from training.heldout import run_buildings
    from training.suites import seeds_of, suite

    chosen = _seed_list(seeds)
    resolved = resolve_localizers(localizers, None, settings)
    held_out = tuple(s for s in seeds_of("held-out") if s not in suite("network-held-out").seeds)
    outside = sorted(set(chosen) - set(held_out))
    if outside:
        typer.echo(f"note: seeds {outside} are not among the held-out buildings {held_out}", err=True)
    looked_at = seeds_of("development") + suite("network-held-out").seeds
    if set(chosen) & set(looked_at):
        typer.echo(
            f"note: seeds {sorted(set(chosen) & set(looked_at))} were looked at while tuning: not a held-out result",
            err=True,
        )
    made = "python -m training " + shlex.join(sys.argv[1:])
    run_buildings(chosen, resolved, trials, scans, workers, worlds, out, settings, made, typer.echo)


@command_line.command(app)
def suite(
    name: str = typer.Argument("", help="the suite (none: list them)"),
    seeds: str = typer.Option("", help="only these of a suite's buildings ('A-B' or 'A,B,C'; the table says so)"),
    workers: int = typer.Option(0, help="worker processes per run (0: one per core)"),
    worlds: Path = typer.Option(Path("build/worlds"), help="folder of the generated worlds"),
    out: Path = typer.Option(Path("results/suites"), help="where each suite's results and table go"),
) -> None:
    """Run a benchmark suite of training/suites/suites.yaml and write its table (command, commit, machine)."""
    from pimm_agents.experiments.run_plan import resolve_localizers
    from training.heldout import run_buildings
    from training.suites import SuiteError, subset, suites
    from training.suites import suite as named

    if not name:
        for entry in suites().values():
            typer.echo(f"{entry.name:24} {entry.kind:12} {entry.purpose}")
        return
    chosen = named(name)
    made = "python -m training " + shlex.join(sys.argv[1:])
    if chosen.seeds:
        try:
            buildings = subset(chosen, _seed_list(seeds) if seeds else None)
        except SuiteError as error:
            raise typer.BadParameter(str(error), param_hint="--seeds") from None
        if chosen.benchmark == "cloud-maps":
            from training.cloud_maps import run_cloud_maps

            run_cloud_maps(list(buildings), chosen.trials, workers, worlds, out / name, made, typer.echo)
            return
        resolved = resolve_localizers(list(chosen.localizers))
        run_buildings(list(buildings), resolved, chosen.trials, 30, workers, worlds, out / name, [], made, typer.echo)
        return
    if seeds:
        raise typer.BadParameter(f"suite {name!r} is made of commands, not buildings", param_hint="--seeds")
    _run_commands(chosen.commands, workers, out / name, made)


def _run_commands(commands: tuple[tuple[str, ...], ...], workers: int, out: Path, made: str) -> None:
    """A command suite's ``evaluate.py`` commands in order, as a user would type them; then ``out/table.md``: each
    results folder's Markdown report (and each ``--markdown`` command's output), under the suite's command."""
    import subprocess

    from pimm_agents.results.markdown import markdown_report, provenance_here

    root = Path(__file__).resolve().parent.parent
    tables = [provenance_here(made)]
    for args in commands:
        typer.echo(f"$ python evaluate.py {shlex.join(args)}", err=True)
        writes_results = args[0] in ("run", "sweep", "replay")
        extra = ["--out", str(out)] if writes_results else []
        extra += ["--workers", str(workers)] if args[0] in ("run", "sweep") else []
        before = set(out.glob("*/summary.json"))
        done = subprocess.run(
            [sys.executable, str(root / "evaluate.py"), *args, *extra],
            cwd=root,
            stdout=subprocess.PIPE if "--markdown" in args else None,
            text=True,
        )
        if done.returncode:
            raise typer.Exit(1)
        if "--markdown" in args:
            typer.echo(done.stdout, nl=False)
            tables.append(done.stdout)
        for summary in sorted(set(out.glob("*/summary.json")) - before):
            tables.append(markdown_report(summary.parent, thesis=True))
    out.mkdir(parents=True, exist_ok=True)
    (out / "table.md").write_text("\n".join(tables))
    typer.echo(f"table: {out / 'table.md'}")


@command_line.command(app, "cloud-maps")
def cloud_maps(
    seeds: str = typer.Option("1300-1303,1320", help="building seeds (suites cloud-maps-development, -held-out)"),
    trials: int = typer.Option(3, min=0, help="PIMM trials per route with each map (0: the maps' figures only)"),
    workers: int = typer.Option(0, help="worker processes per run (0: one per core)"),
    worlds: Path = typer.Option(Path("build/worlds"), help="folder of the generated worlds (and the imports)"),
    out: Path = typer.Option(Path("results/cloud_maps"), help="where the maps, runs and the table go"),
    trajectory: bool = typer.Option(True, help="import each map with the trajectory it was made along, as SLAM writes"),
) -> None:
    """SLAM-like point-cloud maps of generated buildings, imported and scored against the buildings' own maps;
    PIMM localizing in each building with the imported maps beside its own (training/cloud_maps.py)."""
    from training.cloud_maps import run_cloud_maps

    made = "python -m training " + shlex.join(sys.argv[1:])
    run_cloud_maps(_seed_list(seeds), trials, workers, worlds, out, made, typer.echo, trajectory)


def _seed_list(text: str) -> list[int]:
    """``--seeds``: 'A-B', 'A,B,C' or both ('100-103,110')."""
    from training.suites import SuiteError, parse_seeds

    try:
        return list(parse_seeds(text.split(","), "--seeds"))
    except SuiteError as error:
        raise typer.BadParameter(f"expected 'A-B' or 'A,B,C', got {text!r}", param_hint="--seeds") from error
