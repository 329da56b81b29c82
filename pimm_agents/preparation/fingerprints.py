"""Building a world's fingerprint map: descriptors of scans on a grid of free positions, random headings."""

from __future__ import annotations

from typing import Any

import numpy as np

from pimm_agents.perception.fingerprint_map import FingerprintMap
from pimm_agents.perception.segmenter import CloudSegmenter, Segmenter
from pimm_env.errors import PerceptionError
from pimm_env.world.model import World


def build_fingerprint_map(
    world: str | World,
    segmenter: Segmenter | CloudSegmenter,
    spacing: float = 0.5,
    seed: int = 0,
    progress: bool = True,
    workers: int = 1,
    backend: str = "local",
    address: str | None = None,
) -> FingerprintMap:
    """Scan at every ``spacing`` grid position where the robot fits, with a random heading (seeded). With
    ``workers`` > 1 or ``backend="ray"`` the positions are scanned in chunks by ``experiments.engines``; every
    position keeps its own heading and noise seed, so the map is the same however it was split."""
    from tqdm import tqdm

    from pimm_agents.experiments.engines import run_jobs
    from pimm_env.envs.iilab_env import IILabEnv

    env = IILabEnv(world=world)
    rng = np.random.default_rng(seed)
    try:
        positions = env.start_positions(spacing)
        name = env.world.name
    finally:
        env.close()
    if len(positions) < 3:
        raise PerceptionError(f"world {name!r} has {len(positions)} free grid positions at {spacing} m")
    headings = rng.uniform(-np.pi, np.pi, len(positions))
    noise_seeds = rng.integers(0, 2**31, len(positions))
    poses = np.column_stack([positions, headings])
    serial = workers <= 1 and backend == "local"
    chunks = [np.arange(len(poses))] if serial else np.array_split(np.arange(len(poses)), 4 * max(1, workers))
    jobs = [(world, segmenter, poses[c], noise_seeds[c], progress and serial) for c in chunks if len(c)]
    with tqdm(total=len(poses), desc="fingerprints", disable=not progress or serial, unit="scan") as bar:
        parts = run_jobs(_descriptors, jobs, workers, backend, address, lambda i, _: bar.update(len(jobs[i][2])))
    descriptors = np.vstack(parts)
    seen = np.isfinite(descriptors).all(axis=1)  # a place whose scan returned nothing has no fingerprint
    if not seen.all():
        import warnings

        warnings.warn(
            f"world {name!r}: {int((~seen).sum())} of {len(seen)} fingerprint places saw nothing within the LiDAR's"
            " range (no surface around them in the world) and were left out",
            stacklevel=2,
        )
    if seen.sum() < 3:
        raise PerceptionError(f"world {name!r}: only {int(seen.sum())} fingerprint places saw a surface")
    return FingerprintMap(descriptors[seen], positions[seen], headings[seen], source=f"fingerprint map of {name}")


def _descriptors(job: tuple[Any, Segmenter | CloudSegmenter, np.ndarray, np.ndarray, bool]) -> np.ndarray:
    """The descriptors of scans taken at ``poses`` with these noise seeds (one job of the map). Only the 3D
    LiDAR is cast (its noise has its own generator, so its clouds are those of the full env)."""
    from dataclasses import replace

    from tqdm import tqdm

    from pimm_env.envs.iilab_env import IILabEnv
    from pimm_env.envs.sim_config import SimConfig

    world, segmenter, poses, noise_seeds, progress = job
    config = SimConfig()
    env = IILabEnv(world=world, config=replace(config, lidar2d=replace(config.lidar2d, enabled=False)))
    out = np.empty((len(poses), segmenter.descriptor_dim), dtype=np.float32)
    try:
        for i in tqdm(range(len(poses)), desc="fingerprints", disable=not progress, unit="scan"):
            obs, _ = env.reset(seed=int(noise_seeds[i]), options={"pose": list(poses[i])})
            if not np.asarray(obs["cloud_mask"], dtype=bool).any():
                out[i] = np.nan  # nothing within range: no fingerprint here (left out by the caller, counted)
                continue
            out[i] = segmenter.describe(obs["cloud"], obs["cloud_mask"])
    finally:
        env.close()
    return out
