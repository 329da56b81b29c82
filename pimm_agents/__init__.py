"""Localizers that consume the env's observations and report a pose: PIMM's particle filter, the AMCLs and a
3D registration baseline.

Every localizer has the surface of :class:`pimm_agents.localizer.Localizer`; build one by name with
:func:`make_localizer`. The names below load on first use, so that importing one submodule (the command line's
helpers, say) does not import every localizer. Importing the package registers the task env
``pimm/ActiveLocalization-v0`` (``pimm_agents.active``).
"""

from __future__ import annotations

from importlib import import_module
from typing import TYPE_CHECKING, Any

import pimm_agents.active  # noqa: F401  (registers pimm/ActiveLocalization-v0)

if TYPE_CHECKING:
    from pimm_agents.factory import available_localizers, make_localizer
    from pimm_agents.localizer import Hypothesis, Localizer, PoseEstimate

_HOMES = {
    "available_localizers": "pimm_agents.factory",
    "make_localizer": "pimm_agents.factory",
    "Hypothesis": "pimm_agents.localizer",
    "Localizer": "pimm_agents.localizer",
    "PoseEstimate": "pimm_agents.localizer",
}
__all__ = ["Hypothesis", "Localizer", "PoseEstimate", "available_localizers", "make_localizer"]


def __getattr__(name: str) -> Any:
    if name in _HOMES:
        return getattr(import_module(_HOMES[name]), name)
    raise AttributeError(f"module 'pimm_agents' has no attribute {name!r}")
