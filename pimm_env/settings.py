"""Settings laid over frozen config dataclasses, as params files and sensors files give them: each key must be
a field (nested dataclasses take nested mappings) and each value of the field's type, and an error names
where (file, section, key) and what was wrong. Shared by the localizers' params (``pimm_agents/params.py``)
and the LiDARs' sensors files (``sim/sensors.py``).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

import numpy as np

from pimm_env.errors import ParamsError


def apply_params(config: Any, params: Mapping[str, Any], where: str) -> Any:
    """``config`` with the fields named in ``params`` replaced; nested dataclasses take nested mappings.

    ``where`` names the section in errors (``pimm.corners``).
    """
    if not isinstance(params, Mapping):
        raise ParamsError(f"{where}: expected a mapping of settings, got {params!r}")
    fields = {f.name: f for f in dataclasses.fields(config)}
    changes: dict[str, Any] = {}
    for key, value in params.items():
        if key not in fields:
            raise ParamsError(f"{where}: unknown key {key!r}; valid keys: {', '.join(sorted(fields))}")
        current = getattr(config, key)
        if dataclasses.is_dataclass(current):
            changes[key] = apply_params(current, value, f"{where}.{key}")
        else:
            changes[key] = _coerce(value, current, f"{where}.{key}")
    try:
        return dataclasses.replace(config, **changes)
    except (ValueError, TypeError) as error:
        raise ParamsError(f"{where}: {error}") from None


def _coerce(value: Any, current: Any, where: str) -> Any:
    """``value`` as the type of the field's current value; a mismatch names the key, the value and the type."""
    if isinstance(current, bool):
        if isinstance(value, bool):
            return value
    elif isinstance(current, (int, np.integer)):
        if isinstance(value, (int, np.integer)) and not isinstance(value, bool):
            return int(value)
        if isinstance(value, float) and value.is_integer():
            return int(value)
    elif isinstance(current, (float, np.floating)):
        if isinstance(value, (int, float, np.number)) and not isinstance(value, bool):
            return float(value)
    elif isinstance(current, str):
        if isinstance(value, str):
            return value
    elif isinstance(current, tuple):
        if isinstance(value, (list, tuple)):
            return tuple(value)
    elif current is None:
        return value
    raise ParamsError(f"{where}: expected a {type(current).__name__}, got {value!r}")
