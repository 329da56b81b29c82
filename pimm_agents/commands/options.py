"""The options the commands of ``evaluate.py`` share, and how they print."""

from __future__ import annotations

import json
import shlex
import sys
from pathlib import Path
from typing import Any

import typer

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


def as_json(record: dict[str, Any], folder: Path) -> str:
    """One JSON object: ``record`` and the results folder."""
    return json.dumps({**record, "folder": str(folder)})


def this_command() -> str:
    """The command line this process was started with, as a user would type it."""
    return shlex.join(["python", "evaluate.py", *sys.argv[1:]])
