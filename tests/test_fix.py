import numpy as np

from pimm_agents.scoring.fix import FixMetrics, fix_metrics, fix_summary
from pimm_agents.scoring.trial_log import TrialLog


def log_of(errors_m: np.ndarray, dt: float = 1.0) -> TrialLog:
    """A log along x, one row every ``dt`` s, the estimate ``errors_m`` ahead of the truth."""
    t = np.arange(len(errors_m)) * dt
    true = np.column_stack([t, np.zeros_like(t), np.zeros_like(t)])
    estimate = true + np.column_stack([errors_m, np.zeros_like(t), np.zeros_like(t)])
    return TrialLog(t, t, true, estimate, np.full((len(t), 3), 0.01))


def test_the_fix_is_the_first_spell_held_for_ten_seconds_and_the_share_counts_the_time_after():
    errors = np.full(100, 0.1)
    errors[:20] = 5.0  # searching
    errors[25:30] = 5.0  # a short spell right (20-24 s), then wrong again: not a fix
    errors[80:90] = 3.0  # after the fix (30 s), 10 s wrong out of 70
    fix = fix_metrics(log_of(errors))
    assert fix.time_to_fix_s == 30.0
    assert np.isclose(fix.localized_share, 59 / 69)  # rows 30-98 timed, the last row has no duration
    # one bad row late in a long run moves the thesis's convergence time to its end, not the fix
    late = np.full(3000, 0.1)
    late[2990] = 4.0
    assert fix_metrics(log_of(late)).time_to_fix_s == 0.0


def test_never_held_for_ten_seconds_is_no_fix_and_the_summary_says_how_many_were_fixed():
    flicker = np.tile([0.1] * 9 + [2.0], 10)  # right for 9 s at a time
    assert fix_metrics(log_of(flicker)) == FixMetrics(None, None)
    summary = fix_summary([FixMetrics(None, None), FixMetrics(4.0, 1.0), FixMetrics(8.0, 0.5)])
    assert summary == {"time_to_fix_s": 6.0, "localized_share": 0.75, "fixed_share": 2 / 3}
