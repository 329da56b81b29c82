import numpy as np
import pytest

from pimm_agents.results.tum import read_tum, write_trial_tum
from pimm_agents.scoring.trajectory_errors import trajectory_errors
from pimm_agents.scoring.trial_log import TrialLog


def _log(offset: float = 0.0) -> TrialLog:
    t = np.arange(0.0, 20.0, 0.1)
    true = np.column_stack([0.5 * t, np.sin(t / 3), np.arctan2(np.cos(t / 3) / 3, 0.5)])
    estimate = true + np.array([offset, 0.0, 0.0])
    return TrialLog(t, t, true, estimate, np.zeros_like(true))


def test_tum_files_round_trip_and_evo_reads_them(tmp_path):
    from evo.core import metrics, sync
    from evo.tools import file_interface

    log = _log(0.3)
    gt, est = write_trial_tum(tmp_path, log)
    assert (gt.name, est.name) == ("gt.tum", "est.tum")
    times, poses = read_tum(est)
    assert np.allclose(times, log.time) and np.allclose(poses, log.estimate, atol=1e-5)
    first = gt.read_text().splitlines()[1].split()
    assert len(first) == 8 and float(first[3]) == 0.0  # t x y z qx qy qz qw, planar
    ref, ours = file_interface.read_tum_trajectory_file(gt), file_interface.read_tum_trajectory_file(est)
    ref, ours = sync.associate_trajectories(ref, ours)
    ape = metrics.APE(metrics.PoseRelation.translation_part)
    ape.process_data((ref, ours))
    assert ape.get_statistic(metrics.StatisticsType.rmse) == pytest.approx(0.3, abs=1e-5)


def test_ape_and_rpe_measure_a_constant_offset():
    errors = trajectory_errors(_log(0.3))
    assert errors["ape"]["rmse"] == pytest.approx(0.3, abs=1e-9) and errors["ape"]["max"] == pytest.approx(0.3)
    assert errors["rpe"]["max"] < 1e-9  # a constant offset does not change the relative motion
    drifting = _log()
    drifting.estimate[:, 0] *= 1.1  # 10 % too far: 0.1 m per metre along x
    assert trajectory_errors(drifting)["rpe"]["mean"] == pytest.approx(0.1, abs=0.02)
    short = TrialLog(np.zeros(1), np.zeros(1), np.zeros((1, 3)), np.zeros((1, 3)), np.zeros((1, 3)))
    assert trajectory_errors(short) == {"ape": None, "rpe": None}


def test_bad_tum_files_are_named(tmp_path):
    bad = tmp_path / "est.tum"
    bad.write_text("0 1 2 3\n")
    with pytest.raises(ValueError, match="est.tum: a TUM line has 8 fields"):
        read_tum(bad)
    with pytest.raises(FileNotFoundError, match="nope.tum"):
        read_tum(tmp_path / "nope.tum")
