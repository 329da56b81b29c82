"""Localizers that consume the env's observations and report a pose: PIMM's particle filter and AMCL.

Every localizer has the surface of :class:`pimm_agents.localizer.Localizer`; build one by name with
:func:`make_localizer`.
"""

from pimm_agents.factory import available_localizers, make_localizer
from pimm_agents.localizer import Localizer, PoseEstimate

__all__ = ["Localizer", "PoseEstimate", "available_localizers", "make_localizer"]
