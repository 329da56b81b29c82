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
    workers: int = typer.Option(0, help="worker processes per run (0: one per core)"),
    worlds: Path = typer.Option(Path("build/worlds"), help="folder of the generated worlds"),
    out: Path = typer.Option(Path("results/suites"), help="where each suite's results and table go"),
) -> None:
    """Run a benchmark suite of training/suites/suites.yaml and write its table (command, commit, machine)."""
    import subprocess

    from pimm_agents.experiments.run_plan import resolve_localizers
    from training.heldout import run_buildings
    from training.suites import suite as named
    from training.suites import suites

    if not name:
        for entry in suites().values():
            typer.echo(f"{entry.name:24} {entry.kind:12} {entry.purpose}")
        return
    chosen = named(name)
    if chosen.seeds:
        resolved = resolve_localizers(list(chosen.localizers))
        made = "python -m training " + shlex.join(sys.argv[1:])
        run_buildings(
            list(chosen.seeds), resolved, chosen.trials, 30, workers, worlds, out / name, [], made, typer.echo
        )
        return
    root = Path(__file__).resolve().parent.parent
    for args in chosen.commands:  # the commands it is made of, in order, as a user would type them
        typer.echo(f"$ python evaluate.py {shlex.join(args)}", err=True)
        extra = ["--out", str(out / name)] if args[0] in ("run", "sweep", "replay") else []
        if subprocess.run([sys.executable, str(root / "evaluate.py"), *args, *extra], cwd=root).returncode:
            raise typer.Exit(1)


def _seed_list(text: str) -> list[int]:
    """``--seeds``: 'A-B', 'A,B,C' or both ('100-103,110')."""
    from training.suites import SuiteError, parse_seeds

    try:
        return list(parse_seeds(text.split(","), "--seeds"))
    except SuiteError as error:
        raise typer.BadParameter(f"expected 'A-B' or 'A,B,C', got {text!r}", param_hint="--seeds") from error
