"""Where a world's perception lives: the network's weights and the world's fingerprint map.

Every world uses the shipped weights (``pimm_agents/perception/weights/pointnet.pt``, with ``pointnet.json``
saying how they were made) unless it has its own ``maps/<world>/pointnet.pt``; the fingerprint map is always
the world's own, ``maps/<world>/fingerprints.npz``, built by ``evaluate.py world prepare``. Each file has its
record beside it (``.json``: checksum, what made it); one without, or that does not match, is refused
(``records.py``), and a fingerprint map made with other weights than the world uses is refused too.
"""

from __future__ import annotations

from pathlib import Path

from pimm_agents.perception.fingerprint_map import FingerprintConfig, FingerprintMap
from pimm_agents.perception.records import record_path
from pimm_agents.perception.segmenter import CloudSegmenter, Segmenter, load_segmenter
from pimm_env.errors import PerceptionError
from pimm_env.world.files import World, load_world, world_dir


def _world(world: str | World) -> World:
    return world if isinstance(world, World) else load_world(world)


SHIPPED_WEIGHTS = Path(__file__).resolve().parent / "weights" / "pointnet.pt"
#: the layout-free network (``cloud`` inputs) that ``evaluate.py segment`` reads any scan with
SHIPPED_CLOUD_WEIGHTS = Path(__file__).resolve().parent / "weights" / "pointnet-cloud.pt"


def own_checkpoint_path(world: str | World) -> Path:
    """Where weights trained for this world go (``python -m training train``)."""
    return world_dir(_world(world)) / "pointnet.pt"


def checkpoint_path(world: str | World) -> Path:
    """The weights the world uses: its own if it has them, else the shipped ones."""
    own = own_checkpoint_path(world)
    return own if own.is_file() else SHIPPED_WEIGHTS


def fingerprint_path(world: str | World) -> Path:
    return world_dir(_world(world)) / "fingerprints.npz"


def fingerprints_match_weights(world: str | World) -> bool:
    """Whether the world's fingerprint map has a record naming the weights the world now uses (no file is
    read beyond the two records: the full checks run on load)."""
    import json

    records = [record_path(fingerprint_path(world)), record_path(checkpoint_path(world))]
    if not all(path.is_file() for path in records):
        return False
    try:
        made_with, weights = (json.loads(path.read_text()) for path in records)
    except json.JSONDecodeError:
        return False
    return (
        isinstance(made_with, dict)
        and isinstance(weights, dict)
        and made_with.get("weights_sha256") == weights.get("sha256")
    )


def load_perception(
    world: str | World, fingerprints: FingerprintConfig = FingerprintConfig()
) -> tuple[Segmenter | CloudSegmenter, FingerprintMap]:
    """The world's segmenter (of either kind of weights) and fingerprint map; their descriptor sizes must
    agree."""
    segmenter = load_segmenter(checkpoint_path(world))
    fmap = FingerprintMap.load(fingerprint_path(world), fingerprints, segmenter.weights_sha256)
    if fmap.dim != segmenter.descriptor_dim:
        raise PerceptionError(
            f"{fmap.source}: descriptors have {fmap.dim} dimensions but {segmenter.checkpoint} makes "
            f"{segmenter.descriptor_dim}; rebuild the map with `python -m training fingerprints`"
        )
    return segmenter, fmap
