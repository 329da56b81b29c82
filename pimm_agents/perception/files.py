"""Where a world's perception lives: the network's weights and the world's fingerprint map.

Every world uses the shipped weights (``pimm_agents/perception/weights/pointnet.pt``, with ``pointnet.json``
saying how they were made) unless it has its own ``maps/<world>/pointnet.pt``; the fingerprint map is always
the world's own, ``maps/<world>/fingerprints.npz``, built by ``evaluate.py world prepare``.
"""

from __future__ import annotations

from pathlib import Path

from pimm_agents.perception.fingerprint_map import FingerprintConfig, FingerprintMap
from pimm_agents.perception.segmenter import Segmenter
from pimm_env.errors import PerceptionError
from pimm_env.world.files import World, load_world, world_dir


def _world(world: str | World) -> World:
    return world if isinstance(world, World) else load_world(world)


SHIPPED_WEIGHTS = Path(__file__).resolve().parent / "weights" / "pointnet.pt"


def own_checkpoint_path(world: str | World) -> Path:
    """Where weights trained for this world go (``python -m training train``)."""
    return world_dir(_world(world)) / "pointnet.pt"


def checkpoint_path(world: str | World) -> Path:
    """The weights the world uses: its own if it has them, else the shipped ones."""
    own = own_checkpoint_path(world)
    return own if own.is_file() else SHIPPED_WEIGHTS


def fingerprint_path(world: str | World) -> Path:
    return world_dir(_world(world)) / "fingerprints.npz"


def load_perception(
    world: str | World, fingerprints: FingerprintConfig = FingerprintConfig()
) -> tuple[Segmenter, FingerprintMap]:
    """The world's segmenter and fingerprint map; their descriptor sizes must agree."""
    segmenter = Segmenter(checkpoint_path(world))
    fmap = FingerprintMap.load(fingerprint_path(world), fingerprints)
    if fmap.dim != segmenter.descriptor_dim:
        raise PerceptionError(
            f"{fmap.source}: descriptors have {fmap.dim} dimensions but {segmenter.checkpoint} makes "
            f"{segmenter.descriptor_dim}; rebuild the map with `python -m training fingerprints`"
        )
    return segmenter, fmap
