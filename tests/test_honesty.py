import json
from dataclasses import replace

import numpy as np
import pytest

from pimm_agents.localizer import STATUSES, PoseEstimate
from pimm_agents.results.log_files import status_changes, status_rows, write_csv
from pimm_agents.results.scored_logs import score_log
from pimm_agents.scoring.honesty import honesty_metrics, longest_spell, position_nees
from pimm_agents.scoring.trial_log import TrialLog
from pimm_env.errors import LocalizerError, ResultsError

LOST, AMBIGUOUS, LOCALIZED = (STATUSES.index(s) for s in ("lost", "ambiguous", "localized"))


def log_of(errors_m: list[float], status: list[int] | None = None, sigma: float = 0.5) -> TrialLog:
    """Rows every 0.1 s, the estimate ``errors_m`` ahead of the truth in x, covariance sigma^2 in x and y."""
    n = len(errors_m)
    t = 0.1 * np.arange(n)
    true = np.zeros((n, 3))
    estimate = true + np.column_stack([errors_m, np.zeros(n), np.zeros(n)])
    cov = np.tile([sigma**2, sigma**2, 0.01], (n, 1))
    return TrialLog(t, t, true, estimate, cov, status=None if status is None else np.array(status, dtype=np.int8))


def test_a_localizer_that_says_nothing_is_counted_localized_and_its_wrong_start_is_false():
    m = honesty_metrics(log_of([5.0] * 5 + [0.1] * 10), convergence_time_s=0.5)
    assert m.false_localized_s == pytest.approx(0.5) and m.max_false_localized_s == pytest.approx(0.5)
    assert m.time_to_localized_s == pytest.approx(0.5)
    assert m.false_localized_rate == pytest.approx(0.5 / 1.4)  # the last row lasts 0 s


def test_saying_lost_while_wrong_is_not_false_and_a_later_wrong_spell_moves_the_time_to_localized():
    honest = honesty_metrics(log_of([5.0] * 5 + [0.1] * 10, [LOST] * 5 + [LOCALIZED] * 10), 0.5)
    assert honest.false_localized_s == 0 and honest.time_to_localized_s == pytest.approx(0.5)
    errors = [0.1] * 4 + [6.0] * 3 + [0.1] * 8  # right, then a twin for 0.3 s while localized, then right again
    twin = honesty_metrics(log_of(errors), 0.0)
    assert twin.false_localized_s == pytest.approx(0.3) and twin.time_to_localized_s == pytest.approx(0.7)
    ambiguous = honesty_metrics(log_of(errors, [LOCALIZED] * 4 + [AMBIGUOUS] * 3 + [LOCALIZED] * 8), 0.0)
    assert ambiguous.false_localized_s == 0 and ambiguous.time_to_localized_s == 0.0
    assert honesty_metrics(log_of([9.0] * 5), None).time_to_localized_s is None


def test_covariance_consistency_counts_errors_inside_the_three_sigma_ellipse():
    errors = [0.1] * 10 + [1.2] * 10  # 1.2 m: inside 3 sigma of 0.5 m, outside 3 sigma of 0.1 m
    assert honesty_metrics(log_of(errors, sigma=0.5), 0.0).within_3sigma == 1.0
    assert honesty_metrics(log_of(errors, sigma=0.1), 0.0).within_3sigma == pytest.approx(0.5)
    assert position_nees(log_of([0.5], sigma=0.5))[0] == pytest.approx(1.0)
    singular = log_of([0.2, 0.0], sigma=0.0)
    assert position_nees(singular).tolist() == [np.inf, 0.0]
    correlated = log_of([1.0])
    correlated.cov_xy = np.array([0.24])  # x and y nearly one: an x-only error is far outside
    assert position_nees(correlated)[0] > 20


def test_longest_spell_adds_up_consecutive_rows():
    flags = np.array([0, 1, 1, 0, 1, 0, 1, 1, 1], bool)
    assert longest_spell(flags, np.array([1, 2, 3, 4, 5, 6, 7, 8, 0.0])) == 15.0
    assert longest_spell(np.zeros(3, bool), np.ones(3)) == 0.0


def test_the_status_travels_in_the_sidecar_and_score_reads_it(tmp_path):
    status = np.array([LOST] * 5 + [LOCALIZED] * 10, dtype=np.int8)
    assert status_changes(status) == [[0, "lost"], [5, "localized"]]
    assert np.array_equal(status_rows(status_changes(status), 15, tmp_path), status)
    path = tmp_path / "area_b_pimm_trial00.csv"
    write_csv(log_of([5.0] * 5 + [0.1] * 10), path)
    path.with_suffix(".json").write_text(json.dumps({"status": status_changes(status)}))
    assert score_log(path).log.localized.sum() == 10
    path.with_suffix(".json").write_text(json.dumps({"status": [[0, "sure"]]}))
    with pytest.raises(ResultsError, match=r"area_b_pimm_trial00.json: status\[0\]"):
        score_log(path)


def test_a_pose_estimate_names_a_bad_status():
    assert PoseEstimate(0.0, 0.0, 0.0, np.eye(3)).status == "localized"  # a localizer that says nothing
    with pytest.raises(LocalizerError, match="status 'sure'"):
        PoseEstimate(0.0, 0.0, 0.0, np.eye(3), status="sure")


class Unsure:
    """Says lost for its first half second, then localized at the origin."""

    name, sensors = "unsure", ("odom",)

    def reset(self, seed=None, initial_pose=None, initial_cov=None) -> None:
        pass

    def update(self, obs) -> PoseEstimate:
        t = float(obs["time"][0])
        cov = np.array([[0.2, 0.1, 0.0], [0.1, 0.3, 0.0], [0.0, 0.0, 0.1]])
        return PoseEstimate(0.0, 0.0, 0.0, cov, t, status="lost" if t < 0.5 else "localized")


def test_the_recorder_and_the_trial_store_keep_the_status_and_the_xy_covariance(room_file, tmp_path):
    from pimm_agents.experiments.recorder import LocalizationRecorder
    from pimm_agents.experiments.trial_store import load_trial, save_trial
    from pimm_agents.scoring.trial import TrialResult, TrialSpec, metrics_of
    from pimm_env.envs.iilab_env import IILabEnv
    from pimm_env.mapping.derived_maps import ensure_derived_maps
    from pimm_env.world.files import load_world

    ensure_derived_maps(load_world(room_file))
    env = LocalizationRecorder(IILabEnv(world=room_file), Unsure())
    env.reset(seed=0, options={"pose": [2.0, 2.0, 0.0]})
    for _ in range(40):
        env.step(np.array([0.2, 0.0], dtype=np.float32))
    log = env.trial_log()
    env.close()
    assert set(np.unique(log.status)) == {LOST, LOCALIZED} and np.all(log.cov_xy == 0.1)
    assert np.all(log.localized == (log.time >= 0.5))
    result = TrialResult(TrialSpec("s", "unsure", 0, 0, str(room_file)), log, metrics_of(log), 1.0, True)
    back = load_trial(save_trial(tmp_path, result)).log
    assert np.array_equal(back.status, log.status) and np.array_equal(back.cov_xy, log.cov_xy)
    counted = replace(log, set_aside={"too_fast": 3, "stamp_back": 1}, rebased=1)  # kept with the trial
    again = load_trial(save_trial(tmp_path, replace(result, log=counted))).log
    assert (again.set_aside, again.rebased) == ({"too_fast": 3, "stamp_back": 1}, 1)
