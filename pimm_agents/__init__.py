"""Localizers that consume the env's observations and report a pose: PIMM's particle filter and AMCL.

Every localizer has the surface of :class:`pimm_agents.estimate.Localizer`; build one by name with
:func:`make_localizer`.
"""

from pimm_agents.estimate import Localizer, PoseEstimate
from pimm_agents.factory import available_localizers, make_localizer

__all__ = ["Localizer", "PoseEstimate", "available_localizers", "make_localizer"]
