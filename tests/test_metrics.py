import numpy as np
import pytest

from pimm_agents.results.log_files import CSV_COLUMNS, read_csv, write_csv
from pimm_agents.scoring.metrics import best_and_worst, summarize, timing_summary, trial_metrics
from pimm_agents.scoring.trial_log import TrialLog


def make_log(position_errors, angle_errors_deg=None, dt=0.5, kidnap_index=None) -> TrialLog:
    """A straight drive along x with the estimate offset in y by the given errors."""
    pos = np.asarray(position_errors, dtype=float)
    ang = np.radians(np.zeros_like(pos) if angle_errors_deg is None else np.asarray(angle_errors_deg, float))
    t = np.arange(len(pos)) * dt
    true = np.column_stack([t, np.zeros_like(t), np.zeros_like(t)])
    est = true + np.column_stack([np.zeros_like(t), pos, ang])
    return TrialLog(t, t, true, est, np.full((len(t), 3), 0.01), kidnap_index)


def test_never_converged():
    m = trial_metrics(make_log([5.0, 4.0, 3.5, 3.2]))
    assert not m.converged and m.convergence_time_s is None and m.position_error_m is None


def test_converged_at_the_last_crossing_below_both_thresholds():
    # under 3 m at 1.0 s but the angle is off until 1.5 s; then both stay under
    m = trial_metrics(make_log([5.0, 4.0, 2.0, 1.0, 0.5, 0.5], [90, 90, 90, 10, 5, 5]))
    assert m.converged
    assert m.convergence_time_s == pytest.approx(1.5)
    assert m.position_error_m == pytest.approx(np.mean([1.0, 0.5, 0.5]))
    assert m.angle_error_deg == pytest.approx(np.mean([10, 5, 5]))


def test_converged_then_lost_is_not_converged():
    assert not trial_metrics(make_log([0.1, 0.1, 0.1, 4.0])).converged
    assert not trial_metrics(make_log([0.1, 0.1, 0.1, 0.1], [0, 0, 0, 31])).converged


def test_angle_errors_wrap():
    m = trial_metrics(make_log([0.1, 0.1], [359.0, -359.0]))
    assert m.converged and m.angle_error_deg == pytest.approx(1.0)


def test_kidnap_is_scored_from_the_kidnap_on():
    log = make_log([0.1, 0.1, 20.0, 20.0, 1.0, 0.5], kidnap_index=2)
    after = log.after_kidnap()
    m = trial_metrics(after)
    assert m.converged and m.convergence_time_s == pytest.approx(1.0)  # from the first estimate after it
    assert trial_metrics(make_log([0.1, 0.1, 20.0, 20.0], kidnap_index=2).after_kidnap()).converged is False


def test_summary_best_and_worst():
    trials = [
        trial_metrics(make_log([5.0, 1.0, 1.0])),  # converged at 0.5 s, error 1.0
        trial_metrics(make_log([5.0, 5.0, 0.2, 0.2])),  # converged at 1.0 s, error 0.2
        trial_metrics(make_log([5.0, 5.0])),  # never
    ]
    s = summarize(trials)
    assert s["trials"] == 3 and s["convergence_rate"] == pytest.approx(2 / 3)
    assert s["convergence_time_s"] == pytest.approx(0.75)
    assert s["position_error_m"] == pytest.approx(0.6)
    assert best_and_worst(trials) == (0, 2)
    assert best_and_worst(trials[:2]) == (0, 0)
    assert summarize([trials[2]])["convergence_time_s"] is None


def test_timing_summary():
    t = timing_summary([{"sensor": 1.0, "total": 2.0}, {"sensor": 3.0, "total": 4.0}, {}])
    assert t == {
        "sensor": {"mean": 2.0, "max": 3.0, "seconds": 0.004},
        "total": {"mean": 3.0, "max": 4.0, "seconds": 0.006},
    }


def test_csv_round_trip_and_malformed_files_name_the_line(tmp_path):
    log = make_log([2.0, 1.0, 0.5])
    path = tmp_path / "trial.csv"
    write_csv(log, path)
    assert path.read_text().splitlines()[0] == ",".join(CSV_COLUMNS)
    back = read_csv(path)
    np.testing.assert_allclose(back.estimate, log.estimate, atol=1e-6)
    assert trial_metrics(back) == trial_metrics(log)
    lines = path.read_text().splitlines()
    fields = lines[2].split(",")
    fields[5] = "abc"
    lines[2] = ",".join(fields)
    path.write_text("\n".join(lines))
    with pytest.raises(ValueError, match=r"line 3: est_x is not a number"):
        read_csv(path)
    path.write_text("a,b\n1,2\n")
    with pytest.raises(ValueError, match="line 1: header lacks"):
        read_csv(path)
    path.write_text(",".join(CSV_COLUMNS) + "\n1,2,3\n")
    with pytest.raises(ValueError, match="line 2: 3 fields"):
        read_csv(path)


def test_excursions_count_leaving_after_first_convergence():
    from pimm_agents.scoring.metrics import excursions
    from pimm_agents.scoring.trial_log import TrialLog

    t = np.arange(10.0)
    errors = np.array([9, 9, 0.5, 0.5, 6, 7, 0.5, 0.5, 5, 0.5])  # far, then found, lost twice
    true = np.zeros((10, 3))
    estimate = np.column_stack([errors, np.zeros(10), np.zeros(10)])
    log = TrialLog(t, t, true, estimate, np.zeros((10, 3)), None, [])
    assert excursions(log) == (2, 3.0)
    assert excursions(log, held_s=1.0) == (2, 3.0)  # found at t=2 and held to t=3
    assert excursions(log, held_s=2.0) == (0, 0.0)  # never held 2 s: nothing found, nothing lost
    flash = TrialLog(t, t, true, np.column_stack([[0.5, 9, 9, 0.5, 0.5, 0.5, 4, 0.5, 0.5, 0.5], t * 0, t * 0]),
                     np.zeros((10, 3)), None, [])  # fmt: skip
    assert excursions(flash) == (2, 3.0) and excursions(flash, held_s=2.0) == (1, 1.0)
