"""Trials as standard trajectory files (TUM) and the field's trajectory errors (APE, RPE) computed with evo.

A TUM file has one pose per line, ``t x y z qx qy qz qw``; our poses are planar, so z = 0 and the
quaternion turns about z only. ``evo_ape tum gt.tum est.tum -a`` reads the pair a trial writes.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from pimm_agents.evaluation.trial_log import TrialLog

#: RPE compares the estimate's motion with the truth's over steps of this length (m) along the true path.
RPE_DELTA_M = 1.0


def write_tum(path: Path, times: np.ndarray, poses: np.ndarray) -> Path:
    """Planar poses (N, 3) at ``times`` (N,) as a TUM trajectory file."""
    times, poses = np.asarray(times, dtype=float), np.asarray(poses, dtype=float)
    if poses.ndim != 2 or poses.shape[1] != 3 or len(times) != len(poses):
        raise ValueError(f"{path}: need (N,) times and (N, 3) poses, got {times.shape} and {poses.shape}")
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
        raise FileNotFoundError(f"{path}: no such trajectory file")
    try:
        table = np.loadtxt(path, comments="#", ndmin=2)
    except ValueError as error:
        raise ValueError(f"{path}: not a TUM trajectory ({error})") from None
    if table.shape[1] != 8:
        raise ValueError(f"{path}: a TUM line has 8 fields (t x y z qx qy qz qw), found {table.shape[1]}")
    qx, qy, qz, qw = table[:, 4:8].T
    yaw = np.arctan2(2 * (qw * qz + qx * qy), 1 - 2 * (qy**2 + qz**2))
    return table[:, 0], np.column_stack([table[:, 1], table[:, 2], yaw])


def write_trial_tum(folder: Path, log: TrialLog) -> tuple[Path, Path]:
    """``folder/gt.tum`` (the truth) and ``folder/est.tum`` (the estimate), stamped with the sim time."""
    return write_tum(Path(folder) / "gt.tum", log.time, log.true), write_tum(
        Path(folder) / "est.tum", log.time, log.estimate
    )


def _evo_trajectory(times: np.ndarray, poses: np.ndarray):  # -> evo PoseTrajectory3D
    from evo.core.trajectory import PoseTrajectory3D

    half = poses[:, 2] / 2
    zeros = np.zeros(len(poses))
    xyz = np.column_stack([poses[:, 0], poses[:, 1], zeros])
    wxyz = np.column_stack([np.cos(half), zeros, zeros, np.sin(half)])  # evo's quaternions are w first
    return PoseTrajectory3D(positions_xyz=xyz, orientations_quat_wxyz=wxyz, timestamps=np.asarray(times, float))


def trajectory_errors(log: TrialLog) -> dict[str, dict[str, float] | None]:
    """APE (translation, m) of the estimate against the truth, and RPE (translation, m) per ``RPE_DELTA_M`` of
    true path, each as evo's statistics (rmse, mean, median, std, min, max), over the log's rows (no
    alignment: both are in the map frame). RPE is None when the true path is shorter than one step."""
    from evo.core import metrics
    from evo.core.metrics import PoseRelation, Unit

    if len(log) < 2:
        return {"ape": None, "rpe": None}
    truth, estimate = _evo_trajectory(log.time, log.true), _evo_trajectory(log.time, log.estimate)
    ape = metrics.APE(PoseRelation.translation_part)
    ape.process_data((truth, estimate))
    keys = ("rmse", "mean", "median", "std", "min", "max")
    out: dict[str, dict[str, float] | None] = {
        "ape": {k: float(v) for k, v in ape.get_all_statistics().items() if k in keys}
    }
    if truth.path_length < RPE_DELTA_M:
        out["rpe"] = None
        return out
    rpe = metrics.RPE(PoseRelation.translation_part, delta=RPE_DELTA_M, delta_unit=Unit.meters, all_pairs=False)
    try:
        rpe.process_data((truth, estimate))
    except metrics.MetricsException:  # no pair of poses 1 m apart along the path
        out["rpe"] = None
        return out
    out["rpe"] = {k: float(v) for k, v in rpe.get_all_statistics().items() if k in keys}
    return out
