"""The field's trajectory errors (APE, RPE) of a trial, computed with evo from its arrays (no files)."""

from __future__ import annotations

import numpy as np

from pimm_agents.scoring.trial_log import TrialLog


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
    from evo.core import filters, metrics
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
    except (metrics.MetricsException, filters.FilterException):  # no pair 1 m apart along the path, or times
        # that do not advance (a log whose stamps go back): no RPE, the other metrics stand
        out["rpe"] = None
        return out
    out["rpe"] = {k: float(v) for k, v in rpe.get_all_statistics().items() if k in keys}
    return out


#: RPE compares the estimate's motion with the truth's over steps of this length (m) along the true path.
RPE_DELTA_M = 1.0
