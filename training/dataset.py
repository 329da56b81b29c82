"""Labelled 3D scans from the simulator (thesis 3.2.1): random free poses, per-point classes, the pose.

A dataset is one compressed ``.npz``: the organized ranges as float16 (the cloud is the ray directions times
the range, so nothing else is needed), the labels as int8 (-1 for no return), the true poses and the areas.
The thesis labelled its Webots scans with a Kd-tree over class meshes; the simulator here knows the class of
every surface a ray hits, so the labels are exact.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pimm_env.errors import PerceptionError

#: Seed offsets that keep the training, validation and evaluation poses apart for one base seed.
VALIDATION_SEED_OFFSET = 1_000_003
FORMAT = "pimm-scans/1"


@dataclass(frozen=True)
class ScanSet:
    """Scans in scan order: ``ranges`` (n, layers, points) with NaN for no return, ``labels`` likewise -1."""

    ranges: np.ndarray
    labels: np.ndarray
    poses: np.ndarray
    areas: np.ndarray
    world: str

    def __len__(self) -> int:
        return len(self.poses)

    def subset(self, index: np.ndarray) -> ScanSet:
        return ScanSet(self.ranges[index], self.labels[index], self.poses[index], self.areas[index], self.world)

    def require_lidar(self, layers: int, points_per_layer: int) -> None:
        """Raise if the scans were not taken by a ``layers`` x ``points_per_layer`` LiDAR."""
        if self.ranges.shape[1:] != (layers, points_per_layer):
            raise PerceptionError(f"scans are {self.ranges.shape[1:]}, the LiDAR is {layers} x {points_per_layer}")

    def cloud(self, i: int, directions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Scan ``i`` as the env gives it: the (N, 3) sensor-frame cloud (0 where no return) and its mask."""
        ranges = self.ranges[i].reshape(-1).astype(np.float32)
        mask = np.isfinite(ranges)
        return np.where(mask[:, None], directions * np.where(mask, ranges, 0)[:, None], 0).astype(np.float32), mask


def generate(
    world: str,
    count: int,
    seed: int,
    progress: bool = True,
    workers: int = 1,
    backend: str = "local",
    address: str | None = None,
) -> ScanSet:
    """``count`` scans at random free poses of ``world`` (uniform over free space, random heading), seeded.
    With ``workers`` > 1 or ``backend="ray"`` they are taken in chunks by ``pimm_agents.experiments.engines``; each scan
    keeps its own seed, so the set is the same however it was split."""
    from tqdm import tqdm

    from pimm_agents.experiments.engines import run_jobs

    if count < 1:
        raise PerceptionError(f"scan count must be at least 1, got {count}")
    seeds = np.random.SeedSequence(seed).generate_state(count)
    serial = workers <= 1 and backend == "local"
    chunks = [seeds] if serial else [c for c in np.array_split(seeds, 4 * max(1, workers)) if len(c)]
    jobs = [(world, chunk, progress and serial) for chunk in chunks]
    with tqdm(total=count, desc=f"scans of {world}", disable=not progress or serial, unit="scan") as bar:
        parts = run_jobs(_scans, jobs, workers, backend, address, lambda i, _: bar.update(len(jobs[i][1])))
    return ScanSet(
        np.concatenate([p.ranges for p in parts]),
        np.concatenate([p.labels for p in parts]),
        np.concatenate([p.poses for p in parts]),
        np.concatenate([p.areas for p in parts]),
        parts[0].world,
    )


def _scans(job: tuple[str, np.ndarray, bool]) -> ScanSet:
    """One scan per seed at a random free pose (one job of a data set)."""
    from tqdm import tqdm

    from pimm_env.envs.iilab_env import IILabEnv

    world, seeds, progress = job
    count = len(seeds)
    env = IILabEnv(world=world)
    l3 = env.config.lidar3d
    ranges = np.full((count, l3.layers, l3.points_per_layer), np.nan, dtype=np.float16)
    labels = np.full((count, l3.layers, l3.points_per_layer), -1, dtype=np.int8)
    poses = np.zeros((count, 3))
    areas = np.empty(count, dtype="<U8")
    try:
        for i in tqdm(range(count), desc=f"scans of {env.world.name}", disable=not progress, unit="scan"):
            obs, info = env.reset(seed=int(seeds[i]))
            mask = obs["cloud_mask"].astype(bool)
            r = np.linalg.norm(obs["cloud"], axis=1)
            ranges[i] = np.where(mask, r, np.nan).reshape(l3.layers, l3.points_per_layer)
            labels[i] = info["labels"].reshape(l3.layers, l3.points_per_layer)
            poses[i] = info["true_pose"]
            areas[i] = info["area"] or ""
    finally:
        env.close()
    return ScanSet(ranges, labels, poses, areas, env.world.name)


def save(scans: ScanSet, path: Path) -> None:
    from pimm_env.mapping.npz_file import write_npz

    arrays = {"ranges": scans.ranges, "labels": scans.labels, "poses": scans.poses, "areas": scans.areas}
    write_npz(path, FORMAT, world=np.str_(scans.world), **arrays)


def load(path: Path) -> ScanSet:
    """Read a dataset written by :func:`save`; a missing file or field is named in the error."""
    from pimm_env.mapping.npz_file import read_npz

    fields = ("world", "ranges", "labels", "poses", "areas")
    data = read_npz(path, "dataset", fields, FORMAT, "make one with `python -m training dataset`")
    scans = ScanSet(data["ranges"], data["labels"], data["poses"], data["areas"], str(data["world"]))
    if scans.ranges.shape != scans.labels.shape or len(scans.poses) != len(scans.ranges):
        raise PerceptionError(f"{path}: ranges {scans.ranges.shape}, labels {scans.labels.shape} and poses disagree")
    return scans


#: Positions of the n-th world's scans are shifted by n times this (m) when worlds are pooled, so that scans
#: of different buildings are never within the contrastive loss's positive radius of each other.
WORLD_OFFSET_M = 10_000.0


def pool(sets: list[ScanSet]) -> ScanSet:
    """Scans of several worlds as one set; each world's positions moved apart by ``WORLD_OFFSET_M``."""
    if not sets:
        raise PerceptionError("no scan sets to pool")
    poses = [s.poses + np.array([k * WORLD_OFFSET_M, 0.0, 0.0]) for k, s in enumerate(sets)]
    return ScanSet(
        np.concatenate([s.ranges for s in sets]),
        np.concatenate([s.labels for s in sets]),
        np.concatenate(poses),
        np.concatenate([s.areas for s in sets]),
        "+".join(s.world for s in sets) if len(sets) < 4 else f"{len(sets)} worlds",
    )


def split(scans: ScanSet, train_fraction: float, rng: np.random.Generator) -> tuple[ScanSet, ScanSet]:
    """A random split (the thesis's 80/20 with ``train_fraction`` 0.8)."""
    if not 0 < train_fraction < 1:
        raise PerceptionError(f"train_fraction must be in (0, 1), got {train_fraction}")
    order = rng.permutation(len(scans))
    cut = round(train_fraction * len(scans))
    return scans.subset(np.sort(order[:cut])), scans.subset(np.sort(order[cut:]))
