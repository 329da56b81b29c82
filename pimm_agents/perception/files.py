"""Where a world's trained perception lives: ``maps/<world>/pointnet.pt`` and ``maps/<world>/fingerprints.npz``."""

from __future__ import annotations

from pathlib import Path

from pimm_agents.perception.fingerprint_map import FingerprintConfig, FingerprintMap
from pimm_agents.perception.segmenter import Segmenter
from pimm_env.world.files import World, load_world, world_dir


def _world(world: str | World) -> World:
    return world if isinstance(world, World) else load_world(world)


def checkpoint_path(world: str | World) -> Path:
    return world_dir(_world(world)) / "pointnet.pt"


def fingerprint_path(world: str | World) -> Path:
    return world_dir(_world(world)) / "fingerprints.npz"


def load_perception(
    world: str | World, fingerprints: FingerprintConfig = FingerprintConfig()
) -> tuple[Segmenter, FingerprintMap]:
    """The world's segmenter and fingerprint map; their descriptor sizes must agree."""
    segmenter = Segmenter(checkpoint_path(world))
    fmap = FingerprintMap.load(fingerprint_path(world), fingerprints)
    if fmap.dim != segmenter.descriptor_dim:
        raise ValueError(
            f"{fmap.source}: descriptors have {fmap.dim} dimensions but {segmenter.checkpoint} makes "
            f"{segmenter.descriptor_dim}; rebuild the map with `python -m training fingerprints`"
        )
    return segmenter, fmap
