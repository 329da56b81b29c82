"""The robot's own path through its point-cloud map (cloud_map.py): where the SLAM trajectory drove, nothing stood.

A person who walked along with the robot, or stood where it later drove, leaves clutter on the path whose floor
the map did not see clear of them often enough for the ghost rule (cloud_ghosts.py). The trajectory the map was
made along (a TUM file: ``t x y z qx qy qz qw`` a line, in the map's frame; ``evo_traj --save_as_tum`` converts
others to it) says where the robot's body was: clutter up to a person's height within ``CLEAR_M`` of it is set
aside and counted. Walls are not touched: a wall on the path is the map's or the trajectory's error, not a ghost.
"""

from __future__ import annotations

import itertools
from pathlib import Path
from typing import Any

import numpy as np

from pimm_env.errors import MapFileError

#: clutter this near the trajectory in the plane (m) stood where the robot drove (ours: a small indoor robot's
#: half-width; the trajectory is its LiDAR's, near the robot's middle)
CLEAR_M = 0.2
#: a step between two poses longer than this (m) is a jump (a relocalization, a new session), not driven
JUMP_M = 1.0
#: at least this share of the poses must lie within the map's extent, or the trajectory is in another frame
INSIDE_SHARE = 0.5


def read_path(path: Path) -> np.ndarray:
    """The positions (N, 3) of a TUM trajectory file (evo's reader); errors name the file (and the pose, the value)."""
    from evo.tools import file_interface

    path = Path(path)
    if not path.is_file():
        raise MapFileError(f"{path}: no such trajectory file")
    try:
        positions = np.asarray(file_interface.read_tum_trajectory_file(str(path)).positions_xyz, dtype=float)
    except Exception as error:  # evo raises its own FileInterfaceException, numpy a ValueError
        raise MapFileError(f"{path}: not a TUM trajectory (t x y z qx qy qz qw a line): {error}") from None
    bad = np.flatnonzero(~np.isfinite(positions).all(axis=1))
    if len(bad):
        raise MapFileError(f"{path}: pose {bad[0] + 1} is not finite ({positions[bad[0]].tolist()})")
    if len(positions) < 2:
        raise MapFileError(f"{path}: a trajectory needs at least 2 poses, found {len(positions)}")
    return positions


def _driven(positions: np.ndarray, step_m: float) -> np.ndarray:
    """The plane points (K, 2) along the trajectory every ``step_m`` or less, jumps (``JUMP_M``) left out."""
    xy = np.asarray(positions, dtype=float)[:, :2]
    parts = [xy[:1]]
    for a, b in itertools.pairwise(xy):
        length = float(np.hypot(*(b - a)))
        if length > JUMP_M:
            parts.append(b[None, :])
            continue
        steps = max(1, int(np.ceil(length / step_m)))
        parts.append(a + (b - a) * (np.arange(1, steps + 1) / steps)[:, None])
    return np.vstack(parts)


def on_path(voxels: np.ndarray, clutter: np.ndarray, path: np.ndarray, config: Any, source: Path | str) -> np.ndarray:
    """Which ``voxels`` (V, 3 indices, levelled frame) are ``clutter`` up to ``config.person_m`` high whose centre
    lies within ``CLEAR_M`` of the driven ``path`` (N, 3, levelled frame) in the plane; a path from another frame
    (``_check_frame``) is refused naming ``source``. ``config``: cloud_map.CloudMapConfig."""
    from scipy.spatial import cKDTree

    path = np.asarray(path, dtype=float)
    _check_frame(path, voxels, config.voxel_m, source)
    centres = (voxels + 0.5) * config.voxel_m
    candidate = np.flatnonzero(clutter & (centres[:, 2] <= config.person_m))
    out = np.zeros(len(voxels), dtype=bool)
    if not len(candidate):
        return out
    tree = cKDTree(_driven(path, config.voxel_m / 2))
    distance, _ = tree.query(centres[candidate, :2], distance_upper_bound=CLEAR_M)
    out[candidate[distance <= CLEAR_M]] = True
    return out


def _check_frame(path: np.ndarray, voxels: np.ndarray, voxel_m: float, source: Path | str) -> None:
    """Refuse a trajectory most of whose poses lie outside the map's extent in the plane (another frame)."""
    lo, hi = voxels[:, :2].min(axis=0) * voxel_m, (voxels[:, :2].max(axis=0) + 1) * voxel_m
    inside = np.all((path[:, :2] >= lo) & (path[:, :2] <= hi), axis=1)
    if inside.mean() < INSIDE_SHARE:
        raise MapFileError(
            f"{source}: {len(path) - int(inside.sum())} of {len(path)} poses of the trajectory lie outside the map"
            f" (x {lo[0]:.1f} to {hi[0]:.1f} m, y {lo[1]:.1f} to {hi[1]:.1f} m): is it in the map's frame?"
        )
