"""Labelled scans of many LiDARs, mounts and conditions, for the layout-free network (``cloud_features.py``).

Each scan is drawn at a random free pose of a world with its own sensor and conditions (domain randomization):

- the layout: the thesis's 40 x 360 over 120 deg, an OS0-64, a 16-ring (VLP-16), a 128-ring (OS1-128) spinning
  LiDAR, or a non-repetitive pattern (a Mid-360-like field of 360 x -7..52 deg, a fresh quasi-random set of
  rays each scan);
- the mount: 0.2-1.8 m above the floor, rolled and pitched up to 5 deg;
- the range noise (sigma 0.005-0.03 m), a share of lost returns (0-20 %), and mixed pixels at depth edges
  (a return between the near and the far surface, labelled clutter, as a real one belongs to neither);
- people walking about and furniture against the walls that no map has (``walkers``, ``unmapped``: clutter).

The scan is stored levelled (the mount's roll and pitch undone, as the floor fit does it at run time) and
thinned to the network's voxels, with each voxel's majority class: ``points`` (float16, level sensor frame),
``labels``, and per scan its slice, sensor height, layout and pose. One ``.npz``, ``pimm-clouds/1``.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from pimm_agents.perception.cloud_features import CloudFeatureConfig, voxelize
from pimm_env.errors import PerceptionError
from pimm_env.sim.lidar import Lidar3DConfig, mount_rotation
from pimm_env.sim.sensors import LIDAR_3D, NON_REPETITIVE, scan_directions, scan_layout

FORMAT = "pimm-clouds/1"
SPINNING = ("thesis", "os0-64", "vlp-16", "os1-128")
LAYOUTS = (*SPINNING, NON_REPETITIVE)


@dataclass(frozen=True)
class RandomizationConfig:
    """The ranges the scans are drawn from (the issue's: mount 0.2-1.8 m, tilt up to 5 deg)."""

    layouts: tuple[str, ...] = LAYOUTS
    height_m: tuple[float, float] = (0.2, 1.8)
    tilt_deg: float = 5.0
    noise_m: tuple[float, float] = (0.005, 0.03)
    dropout: tuple[float, float] = (0.0, 0.2)
    mixed_pixel_share: float = 0.3  # of the returns at a depth edge (a jump over 0.3 m to the next in the ring)
    walkers: int = 3
    unmapped: int = 8
    non_repetitive_rays: int = 20_000


@dataclass(frozen=True)
class CloudSet:
    points: np.ndarray  # (P, 3) float16, all scans' voxels one after the other
    labels: np.ndarray  # (P,) int8
    starts: np.ndarray  # (n + 1,) scan i is points[starts[i]:starts[i + 1]]
    heights: np.ndarray  # (n,) sensor height above the floor (m)
    layouts: np.ndarray  # (n,) layout names
    poses: np.ndarray  # (n, 3) x, y, theta of the robot (m, rad), worlds moved apart as in dataset.pool
    worlds: np.ndarray  # (n,) world names

    def __len__(self) -> int:
        return len(self.heights)

    def scan(self, i: int) -> tuple[np.ndarray, np.ndarray]:
        a, b = self.starts[i], self.starts[i + 1]
        return self.points[a:b].astype(np.float64), self.labels[a:b]

    def subset(self, index: np.ndarray) -> CloudSet:
        parts = [self.scan(int(i)) for i in index]
        sizes = np.array([len(p) for p, _ in parts], dtype=np.int64)
        return CloudSet(
            np.concatenate([p for p, _ in parts]).astype(np.float16),
            np.concatenate([lab for _, lab in parts]),
            np.concatenate([[0], np.cumsum(sizes)]),
            self.heights[index],
            self.layouts[index],
            self.poses[index],
            self.worlds[index],
        )


def random_scan(
    env: object, rng: np.random.Generator, config: RandomizationConfig, voxel_m: float
) -> tuple[np.ndarray, np.ndarray, float, str]:
    """One scan from the env's current pose: level voxel points, their classes, the height and the layout."""
    name = str(rng.choice(config.layouts))
    base = scan_layout(name)
    tilt = config.tilt_deg
    mount = replace(
        base,
        height=float(rng.uniform(*config.height_m)),
        mount_roll_deg=float(rng.uniform(-tilt, tilt)),
        mount_pitch_deg=float(rng.uniform(-tilt, tilt)),
    )
    spinning = name in SPINNING
    directions = scan_directions(name, mount, rng, config.non_repetitive_rays)
    ranges, labels = env.cast_sensor_rays(directions, mount)  # type: ignore[attr-defined]
    hit = np.isfinite(ranges) & (ranges >= mount.min_range)
    ranges = np.where(hit, ranges + rng.normal(0.0, rng.uniform(*config.noise_m), len(ranges)), np.inf)
    labels = labels.astype(np.int8)
    if spinning:
        _mixed_pixels(ranges, labels, mount, config.mixed_pixel_share, rng)
    keep = np.isfinite(ranges) & (ranges > mount.min_range) & (rng.random(len(ranges)) >= rng.uniform(*config.dropout))
    level = (directions[keep] * ranges[keep, None]) @ mount_rotation(mount).T
    points, voxel_of = voxelize(level, voxel_m)
    votes = np.bincount(voxel_of * 4 + labels[keep].astype(np.int64), minlength=4 * len(points)).reshape(-1, 4)
    return points, votes.argmax(axis=1).astype(np.int8), mount.height, name


def _mixed_pixels(
    ranges: np.ndarray, labels: np.ndarray, mount: Lidar3DConfig, share: float, rng: np.random.Generator
) -> None:
    """Some returns at depth edges (along a ring) moved between the two surfaces and labelled clutter."""
    grid = ranges.reshape(mount.layers, mount.points_per_layer)
    finite = np.isfinite(grid)
    near = np.where(finite, grid, 0.0)
    ahead = np.roll(near, -1, axis=1)
    edge = finite & np.roll(finite, -1, axis=1) & (np.abs(ahead - near) > 0.3)
    chosen = edge & (rng.random(grid.shape) < share)
    mix = rng.uniform(0.1, 0.9, grid.shape)
    grid[chosen] = (near + mix * (ahead - near))[chosen]
    labels.reshape(grid.shape)[chosen] = 3  # clutter
    ranges[:] = grid.reshape(-1)


def generate(
    worlds: list[str],
    per_world: int,
    seed: int,
    config: RandomizationConfig = RandomizationConfig(),
    progress: bool = True,
) -> CloudSet:
    """``per_world`` scans of each world, every draw from ``seed``."""
    from tqdm import tqdm

    from pimm_env.envs.iilab_env import IILabEnv
    from pimm_env.envs.sim_config import SimConfig

    if per_world < 1:
        raise PerceptionError(f"scans per world must be at least 1, got {per_world}")
    voxel_m = CloudFeatureConfig().voxel_m
    sim = SimConfig(lidar3d=replace(LIDAR_3D["thesis"], enabled=False))
    points, labels, heights, layouts, poses, names = [], [], [], [], [], []
    bar = tqdm(total=per_world * len(worlds), desc="clouds", unit="scan", disable=not progress)
    for k, world in enumerate(worlds):
        rng = np.random.default_rng([seed, k])
        env = IILabEnv(world=world, config=sim, walkers=config.walkers, unmapped=config.unmapped)
        try:
            for _ in range(per_world):
                _, info = env.reset(seed=int(rng.integers(0, 1 << 31)))
                p, lab, height, name = random_scan(env, rng, config, voxel_m)
                points.append(p.astype(np.float16))
                labels.append(lab)
                heights.append(height)
                layouts.append(name)
                poses.append(np.asarray(info["true_pose"]) + np.array([k * 10_000.0, 0.0, 0.0]))
                names.append(env.world.name)
                bar.update()
        finally:
            env.close()
    bar.close()
    sizes = np.array([len(p) for p in points], dtype=np.int64)
    return CloudSet(
        np.concatenate(points),
        np.concatenate(labels),
        np.concatenate([[0], np.cumsum(sizes)]),
        np.array(heights),
        np.array(layouts),
        np.array(poses),
        np.array(names),
    )


def save(clouds: CloudSet, path: Path) -> None:
    from pimm_env.mapping.npz_file import write_npz

    fields = ("points", "labels", "starts", "heights", "layouts", "poses", "worlds")
    write_npz(path, FORMAT, **{name: getattr(clouds, name) for name in fields})


def load(path: Path) -> CloudSet:
    from pimm_env.mapping.npz_file import read_npz

    fields = ("points", "labels", "starts", "heights", "layouts", "poses", "worlds")
    data = read_npz(path, "cloud dataset", fields, FORMAT, "make one with `python -m training clouds`")
    clouds = CloudSet(**{name: data[name] for name in fields})
    if clouds.starts[-1] != len(clouds.points) or len(clouds.labels) != len(clouds.points):
        raise PerceptionError(f"{path}: scan slices, points and labels disagree")
    return clouds


def pool(sets: list[CloudSet]) -> CloudSet:
    """Several cloud sets as one (their poses are already apart when each came from other worlds)."""
    if not sets:
        raise PerceptionError("no cloud sets to pool")
    offsets = np.cumsum([0, *(len(c.points) for c in sets[:-1])])
    return CloudSet(
        np.concatenate([c.points for c in sets]),
        np.concatenate([c.labels for c in sets]),
        np.concatenate([[0], *(c.starts[1:] + o for c, o in zip(sets, offsets, strict=True))]),
        np.concatenate([c.heights for c in sets]),
        np.concatenate([c.layouts for c in sets]),
        np.concatenate([c.poses + np.array([1e6 * k, 0.0, 0.0]) for k, c in enumerate(sets)]),
        np.concatenate([c.worlds for c in sets]),
    )
