"""Trials as standard trajectory files (TUM) and the field's trajectory errors (APE, RPE) computed with evo.

A TUM file has one pose per line, ``t x y z qx qy qz qw``; our poses are planar, so z = 0 and the
quaternion turns about z only. ``evo_ape tum gt.tum est.tum -a`` reads the pair a trial writes.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from pimm_agents.scoring.trial_log import TrialLog
from pimm_env.errors import MissingFileError, ResultsError


def write_tum(path: Path, times: np.ndarray, poses: np.ndarray) -> Path:
    """Planar poses (N, 3) at ``times`` (N,) as a TUM trajectory file."""
    times, poses = np.asarray(times, dtype=float), np.asarray(poses, dtype=float)
    if poses.ndim != 2 or poses.shape[1] != 3 or len(times) != len(poses):
        raise ResultsError(f"{path}: need (N,) times and (N, 3) poses, got {times.shape} and {poses.shape}")
    half = poses[:, 2] / 2
    zeros = np.zeros(len(poses))
    table = np.column_stack([times, poses[:, 0], poses[:, 1], zeros, zeros, zeros, np.sin(half), np.cos(half)])
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savetxt(path, table, fmt="%.6f", header="timestamp x y z qx qy qz qw", comments="# ")
    return path


def read_tum(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Times (N,) and planar poses (N, 3) from a TUM file (the yaw of each quaternion); errors name the file."""
    path = Path(path)
    if not path.is_file():
        raise MissingFileError(f"{path}: no such trajectory file")
    try:
        table = np.loadtxt(path, comments="#", ndmin=2)
    except ValueError as error:
        raise ResultsError(f"{path}: not a TUM trajectory ({error})") from None
    if table.shape[1] != 8:
        raise ResultsError(f"{path}: a TUM line has 8 fields (t x y z qx qy qz qw), found {table.shape[1]}")
    qx, qy, qz, qw = table[:, 4:8].T
    yaw = np.arctan2(2 * (qw * qz + qx * qy), 1 - 2 * (qy**2 + qz**2))
    return table[:, 0], np.column_stack([table[:, 1], table[:, 2], yaw])


def write_trial_tum(folder: Path, log: TrialLog) -> tuple[Path, Path]:
    """``folder/gt.tum`` (the truth) and ``folder/est.tum`` (the estimate), stamped with the sim time."""
    return write_tum(Path(folder) / "gt.tum", log.time, log.true), write_tum(
        Path(folder) / "est.tum", log.time, log.estimate
    )
