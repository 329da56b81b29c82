"""A results folder as Markdown for the docs (``evaluate.py report RESULTS_DIR --markdown``): one table per
scenario, headed by the command, commit and machine that made it, so a table in the docs says where it came from."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from pimm_agents.scoring.thesis import THESIS_RESULTS
from pimm_env.errors import MissingFileError, ResultsError

COLUMNS = ("trials", "conv. rate %", "conv. time s", "pos. err m", "ang. err deg")


def read_summary(folder: Path) -> dict[str, Any]:
    """A results folder's ``summary.json``; errors name the file."""
    path = Path(folder) / "summary.json"
    if not path.is_file():
        raise MissingFileError(f"{path}: no summary.json: is {folder} a results folder of run, sweep or replay?")
    try:
        summary = json.loads(path.read_text())
    except json.JSONDecodeError as error:
        raise ResultsError(f"{path}: not JSON ({error})") from None
    if not isinstance(summary, dict) or not isinstance(summary.get("scenarios"), dict):
        raise ResultsError(f"{path}: no 'scenarios' mapping: not a summary written by evaluate.py")
    return summary


def provenance_line(summary: dict[str, Any]) -> str:
    """Which command, commit and machine made the results."""
    made = summary.get("run", {})
    command = made.get("command") or made.get("repeat") or "(command not recorded)"
    machine = summary.get("machine") or {}
    cpu = machine.get("cpu") or "unknown CPU"
    cores = machine.get("cores")
    where = f"{cpu}, {cores} logical cores" if cores else cpu
    commit = summary.get("commit") or "unknown commit"
    return f"Made by `{command}` at commit `{commit}` (pimm {summary.get('version', '?')}) on {where}."


def _cell(value: float | None, fmt: str, scale: float = 1.0) -> str:
    return "-" if value is None else format(scale * value, fmt)


def scenario_table(scenario: str, rows: dict[str, Any], thesis: bool = True) -> list[str]:
    """``| localizer | trials | ... |`` for one scenario, with the thesis's row under each localizer it ran."""
    lines = [f"| {scenario} | " + " | ".join(COLUMNS) + " |", "|---|" + "---:|" * len(COLUMNS)]
    for name, row in rows.items():
        cells = (
            str(row["trials"]),
            _cell(row["convergence_rate"], ".0f", 100),
            _cell(row["convergence_time_s"], ".2f"),
            _cell(row["position_error_m"], ".2f"),
            _cell(row["angle_error_deg"], ".2f"),
        )
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
        reference = THESIS_RESULTS.get(scenario, {}).get(name) if thesis else None
        if reference is not None:
            rate, t, pos, ang = reference
            cells = ("10", _cell(rate, ".0f", 100), _cell(t, ".2f"), _cell(pos, ".2f"), _cell(ang, ".2f"))
            lines.append(f"| *{name}, thesis* | " + " | ".join(cells) + " |")
    return lines


def markdown_report(folder: Path, thesis: bool = True) -> str:
    """The folder's tables as Markdown, one per scenario, after a line naming command, commit and machine."""
    summary = read_summary(folder)
    lines = [provenance_line(summary), ""]
    for scenario, rows in summary["scenarios"].items():
        lines += [*scenario_table(scenario, rows, thesis), ""]
    return "\n".join(lines).rstrip() + "\n"


def text_report(folder: Path) -> str:
    """The folder's tables as ``evaluate.py run`` prints them, after the provenance line."""
    from pimm_agents.results.tables import format_tables

    summary = read_summary(folder)
    return f"{provenance_line(summary)}{format_tables(summary)}\n"
