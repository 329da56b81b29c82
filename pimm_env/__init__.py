"""PIMM's simulated world: any building (the iiLab, an imported map or mesh, a generated one), a diff-drive
robot with a 3D and a 2D LiDAR, as a Gymnasium env.

``import pimm_env`` registers ``pimm/IILab-v1`` (see ``IILabEnv``'s Version History; v0 is retired: this code
no longer reproduces its observations, and ``gym.make("pimm/IILab-v0")`` says to use v1). The task env
``pimm/ActiveLocalization-v0``, which drives this simulator with a localizer in the loop, lives with the
localizers and is registered by ``import pimm_agents``.
"""

from gymnasium.envs.registration import register

from pimm_env.envs.sim_config import SimConfig
from pimm_env.errors import PimmError
from pimm_env.world.semantics import SemanticClass

register(id="pimm/IILab-v1", entry_point="pimm_env.envs.iilab_env:IILabEnv", max_episode_steps=20_000)

__all__ = ["PimmError", "SemanticClass", "SimConfig"]
