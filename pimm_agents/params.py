"""Localizer settings as data: a params file in the spirit of nav2's, one section per localizer name.

A params file (YAML)::

    amcl:
      max_particles: 500
    pimm:
      filter: {num_particles: 5000}
      corners:
        planes: {method: open3d}

Each section is nested as the localizer's config dataclass is. :func:`apply_params` sets those fields on a
config object, refusing an unknown key with the valid keys at that level; :func:`config_to_params` writes a
config back in the same form, so a run's ``config.yaml`` read back gives the very same configs.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from pimm_env.errors import ParamsError
from pimm_env.settings import apply_params

Params = dict[str, Any]
__all__ = ["Params", "ParamsError", "apply_params", "config_to_params", "merge_params"]


def config_to_params(config: Any) -> Params:
    """A config dataclass as nested plain data (dicts, lists, Python numbers and strings)."""
    return {f.name: _plain(getattr(config, f.name)) for f in dataclasses.fields(config)}


def _plain(value: Any) -> Any:
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return config_to_params(value)
    if isinstance(value, (tuple, list)):
        return [_plain(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    return value


def merge_params(base: Mapping[str, Any], extra: Mapping[str, Any]) -> Params:
    """``base`` with ``extra`` laid over it, nested mappings merged key by key."""
    out: Params = dict(base)
    for key, value in extra.items():
        if isinstance(value, Mapping) and isinstance(out.get(key), Mapping):
            out[key] = merge_params(out[key], value)
        else:
            out[key] = value
    return out


def read_params_file(path: Path) -> dict[str, Params]:
    """A params file: ``{localizer name: section}``; errors name the file and the section."""
    from pimm_env.yaml_file import read_yaml_mapping

    data = read_yaml_mapping(path, "params file", ParamsError, empty_ok=True)
    for name, section in data.items():
        if not isinstance(section, Mapping) and section is not None:
            raise ParamsError(f"{path}: section {name!r}: expected a mapping of settings, got {section!r}")
    return {str(name): dict(section or {}) for name, section in data.items()}


def write_params_file(path: Path, params: Mapping[str, Params]) -> Path:
    """Write ``{localizer name: section}`` as YAML that :func:`read_params_file` reads back unchanged."""
    import yaml

    Path(path).write_text(yaml.safe_dump(dict(params), sort_keys=False, default_flow_style=False))
    return Path(path)


def parse_settings(settings: Iterable[str], localizers: Iterable[str]) -> dict[str, Params]:
    """``NAME.KEY[.KEY...]=VALUE`` strings as params sections; NAME is one of ``localizers``.

    Values are read as YAML scalars (``500``, ``0.2``, ``true``, ``open3d``).
    """
    import yaml

    names = sorted(localizers, key=len, reverse=True)  # "amcl-recovery" before "amcl"
    out: dict[str, Params] = {}
    for item in settings:
        key, sep, raw = item.partition("=")
        if not sep or not key:
            raise ParamsError(f"--set {item!r}: expected NAME.KEY=VALUE, e.g. amcl.max_particles=500")
        name = next((n for n in names if key.startswith(n + ".")), None)
        if name is None:
            raise ParamsError(
                f"--set {item!r}: the key must start with a localizer being run and a dot; "
                f"localizers: {', '.join(sorted(names))}"
            )
        path = key[len(name) + 1 :].split(".")
        if not all(path):
            raise ParamsError(f"--set {item!r}: empty key in {key!r}")
        try:
            value = yaml.safe_load(raw)
        except yaml.YAMLError:
            value = raw
        nested: Any = value
        for part in reversed(path):
            nested = {part: nested}
        out[name] = merge_params(out.get(name, {}), nested)
    return out
