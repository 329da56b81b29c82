"""What PIMM's two command lines (``evaluate.py``, ``python -m training``) share: a user's mistake (a
``PimmError``, which names the file, field or value) reported as one line, and list options written as the docs
write them (``--localizers pimm amcl``). Imports nothing heavy, so that ``--help`` stays instant."""

from __future__ import annotations

import functools
import os
import sys
from collections.abc import Callable
from typing import Any

import typer


def command(group: typer.Typer, name: str | None = None) -> Callable[[Callable[..., Any]], Any]:
    """Register a command of ``group`` that reports a PimmError as one line and exits with 1; any other error
    shows its traceback (``PIMM_DEBUG=1``: a PimmError's too)."""
    return lambda fn: group.command(name)(functools.wraps(fn)(functools.partial(_reporting_errors, fn)))


def _reporting_errors(fn: Callable[..., Any], *args: Any, **kwargs: Any) -> Any:
    from pimm_env.errors import PimmError

    try:
        return fn(*args, **kwargs)
    except PimmError as error:
        if os.environ.get("PIMM_DEBUG"):
            raise
        typer.echo(f"error: {error}", err=True)
        raise typer.Exit(1) from None


def expand_list_options(argv: list[str], lists: tuple[str, ...]) -> list[str]:
    """Rewrite ``--scenarios a b`` as ``--scenarios a --scenarios b`` (for each option of ``lists``), the form
    click parses."""
    out: list[str] = []
    current = None
    for token in argv:
        if token.startswith("-"):
            current = token if token in lists else None
            out.append(token)
        elif current is not None and out[-1] != current:
            out += [current, token]
        else:
            out.append(token)
    return out


def run_app(app: typer.Typer, lists: tuple[str, ...]) -> int:
    """Run ``app`` on this process's arguments, the options of ``lists`` expanded."""
    return app(args=expand_list_options(sys.argv[1:], lists))
