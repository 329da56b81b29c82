"""Active localization: a task env in which a policy drives so that a localizer becomes right and sure quickly
(``pimm/ActiveLocalization-v0``, registered here: ``import pimm_agents`` is enough), and its motion primitives."""

from gymnasium.envs.registration import register

register(id="pimm/ActiveLocalization-v0", entry_point="pimm_agents.active.env:ActiveLocalizationEnv")
