"""The covariance a consumer reading no status is shown: the chosen mode's while localized, wide enough to cover
every live place otherwise, never zero."""

import numpy as np
import pytest

from pimm_agents.localizer import PUBLISHED_FLOOR, UNSURE_FLOOR, Hypothesis, PoseEstimate, published_covariance
from pimm_agents.scoring.honesty import honesty_metrics
from pimm_agents.scoring.trial_log import TrialLog

TIGHT = np.diag([0.0004, 0.0004, 0.0001])


def estimate(status: str, hypotheses=(), particles=None, cov=TIGHT) -> PoseEstimate:
    inside = {} if particles is None else {"particles": np.asarray(particles, dtype=float)}
    return PoseEstimate(2.0, 3.0, 0.1, covariance=cov, status=status, hypotheses=hypotheses, inside=inside)


def test_localized_keeps_its_own_covariance_with_a_floor() -> None:
    assert published_covariance(estimate("localized")) == pytest.approx(TIGHT)
    zero = published_covariance(estimate("localized", cov=np.zeros((3, 3))))
    assert np.diag(zero) == pytest.approx(PUBLISHED_FLOOR**2)


def test_ambiguous_covers_the_twin() -> None:
    here = Hypothesis(2.0, 3.0, 0.1, 0.7, TIGHT)
    twin = Hypothesis(2.0, 9.0, 0.1 + 2 * np.pi - 0.2, 0.3, TIGHT)  # 6 m north, its heading wrapped
    cov = published_covariance(estimate("ambiguous", (here, twin)))
    assert cov[1, 1] == pytest.approx(0.3 * 36 + 0.0004)  # the mixture about the published pose
    assert cov[2, 2] == pytest.approx(UNSURE_FLOOR[2] ** 2)  # 0.3 * 0.2^2 (not (2 pi - 0.2)^2), under 10 deg
    assert np.all(np.linalg.eigvalsh(cov) > 0)


def test_a_doubted_place_is_never_shown_a_small_ellipse() -> None:
    """Particles collapsed onto one place the localizer does not yet call localized: at least 1 m, 10 deg."""
    collapsed = np.tile([2.0, 3.0, 0.1], (50, 1))
    cov = published_covariance(estimate("ambiguous", (Hypothesis(2.0, 3.0, 0.1, 1.0, TIGHT),), collapsed))
    assert np.all(np.sqrt(np.diag(cov)) >= UNSURE_FLOOR - 1e-12)


def test_lost_covers_the_particles_when_they_spread_wider() -> None:
    rng = np.random.default_rng(0)
    particles = np.column_stack([rng.uniform(-20, 20, 400), rng.uniform(-5, 5, 400), rng.uniform(-3, 3, 400)])
    cov = published_covariance(estimate("lost", (Hypothesis(2.0, 3.0, 0.1, 1.0, TIGHT),), particles))
    assert np.sqrt(cov[0, 0]) > 10.0  # about +-20 m of particles: no small ellipse


def test_overconfident_rows_are_counted_by_either_covariance() -> None:
    n = 4
    true = np.zeros((n, 3))
    est = np.array([[0.1, 0, 0], [5.0, 0, 0], [5.0, 0, 0], [0.0, 0, 0]])  # rows 1 and 2 are 5 m off
    cov = np.tile([0.01, 0.01, 0.001], (n, 1))  # tight everywhere
    published = np.array([[0.01, 0.01, 0.001, 0.0], [30.0, 30.0, 1.0, 0.0], [0.01, 0.01, 0.001, 0.0],
                          [0.01, 0.01, 0.001, 0.0]])  # fmt: skip
    log = TrialLog(np.arange(n, dtype=float), np.arange(n, dtype=float), true, est, cov, published=published)
    honesty = honesty_metrics(log, None)
    assert (honesty.rows, honesty.overconfident_rows, honesty.published_overconfident_rows) == (4, 2, 1)
