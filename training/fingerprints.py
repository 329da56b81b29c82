"""Building a world's fingerprint map: descriptors of scans on a grid of free positions, random headings."""

from __future__ import annotations

import numpy as np

from pimm_agents.perception.fingerprint_map import FingerprintMap
from pimm_agents.perception.segmenter import Segmenter
from pimm_env.world.model import World


def build_fingerprint_map(
    world: str | World, segmenter: Segmenter, spacing: float = 0.5, seed: int = 0, progress: bool = True
) -> FingerprintMap:
    """Scan at every ``spacing`` grid position where the robot fits, with a random heading (seeded)."""
    from tqdm import tqdm

    from pimm_env.envs.iilab_env import IILabEnv

    env = IILabEnv(world=world)
    rng = np.random.default_rng(seed)
    try:
        positions = env.start_positions(spacing)
        if len(positions) < 3:
            raise ValueError(f"world {env.world.name!r} has {len(positions)} free grid positions at {spacing} m")
        headings = rng.uniform(-np.pi, np.pi, len(positions))
        noise_seeds = rng.integers(0, 2**31, len(positions))
        descriptors = np.empty((len(positions), segmenter.descriptor_dim), dtype=np.float32)
        for i in tqdm(range(len(positions)), desc="fingerprints", disable=not progress, unit="scan"):
            pose = [positions[i, 0], positions[i, 1], headings[i]]
            obs, _ = env.reset(seed=int(noise_seeds[i]), options={"pose": pose})
            descriptors[i] = segmenter.segment(obs["cloud"], obs["cloud_mask"]).descriptor
    finally:
        env.close()
    return FingerprintMap(descriptors, positions, headings, source=f"fingerprint map of {env.world.name}")
