"""Reading a YAML file that must hold a mapping, with errors that name the file (params, sweep, run and map files)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from pimm_env.errors import MissingFileError, PimmError


def read_yaml_mapping(path: Path, what: str, error: type[PimmError], empty_ok: bool = False) -> dict[str, Any]:
    """The mapping in the YAML file ``path`` (a ``what``: "params file", "sweep file", ...). A missing file raises
    ``MissingFileError``; a file that is not YAML, or holds anything but a mapping, raises ``error`` naming the
    file. ``empty_ok`` reads an empty file as an empty mapping."""
    import yaml

    path = Path(path)
    if not path.is_file():
        raise MissingFileError(f"{path}: no such {what}")
    try:
        data = yaml.safe_load(path.read_text())
    except yaml.YAMLError as problem:
        raise error(f"{path}: not valid YAML: {yaml_problem(problem)}") from None
    if data is None and empty_ok:
        return {}
    if not isinstance(data, dict):
        raise error(f"{path}: a {what} holds a mapping, got {type(data).__name__}")
    return data


def yaml_problem(problem: Exception) -> str:
    """A YAML parser's error in one line, with the line and column it names."""
    mark = getattr(problem, "problem_mark", None)
    what = getattr(problem, "problem", None) or " ".join(str(problem).split())
    return f"{what} (line {mark.line + 1}, column {mark.column + 1})" if mark is not None else str(what)
