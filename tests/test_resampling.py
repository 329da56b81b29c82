import numpy as np
import pytest

from pimm_agents.particles.resampling import (
    effective_sample_size,
    multinomial_resample,
    residual_resample,
    systematic_resample,
)

WEIGHTS = np.array([0.42, 0.27, 0.16, 0.1, 0.05])


def copies(indices: np.ndarray, n: int) -> np.ndarray:
    return np.bincount(indices, minlength=n)


@pytest.mark.parametrize("seed", range(20))
def test_systematic_copies_each_particle_floor_or_ceil_of_n_w(seed):
    n = 10
    counts = copies(systematic_resample(WEIGHTS, np.random.default_rng(seed), n), len(WEIGHTS))
    assert counts.sum() == n
    assert np.all(counts >= np.floor(n * WEIGHTS)) and np.all(counts <= np.ceil(n * WEIGHTS))


@pytest.mark.parametrize("seed", range(20))
def test_residual_keeps_the_integer_part_of_n_w_and_draws_the_rest(seed):
    # With weights 0.42..0.05 and n = 10 the deterministic copies are 4, 2, 1, 1, 0 (8 of 10); the two left
    # are drawn on the residuals 0.2, 0.7, 0.6, 0.0, 0.5. filterpy's version subtracts the copies from the
    # raw weights instead, which would make the residual of particle 3 (w = 0.1, one copy) negative.
    n = 10
    counts = copies(residual_resample(WEIGHTS, np.random.default_rng(seed), n), len(WEIGHTS))
    assert counts.sum() == n
    assert np.all(counts >= [4, 2, 1, 1, 0])
    assert counts[3] == 1  # its residual is zero: never drawn again


def test_residual_draws_follow_the_residuals():
    rng = np.random.default_rng(0)
    total = sum(copies(residual_resample(WEIGHTS, rng, 10), 5) for _ in range(4000))
    expected = 4000 * (np.array([4, 2, 1, 1, 0]) + 2 * np.array([0.2, 0.7, 0.6, 0.0, 0.5]) / 2.0)
    np.testing.assert_allclose(total, expected, rtol=0.03)


@pytest.mark.parametrize("resample", [multinomial_resample, systematic_resample, residual_resample])
def test_every_scheme_is_unbiased_and_seeded(resample):
    totals = sum(copies(resample(WEIGHTS, np.random.default_rng(s), 50), 5) for s in range(400))
    np.testing.assert_allclose(totals / (400 * 50), WEIGHTS, atol=0.01)
    a = resample(WEIGHTS, np.random.default_rng(7), 50)
    b = resample(WEIGHTS, np.random.default_rng(7), 50)
    np.testing.assert_array_equal(a, b)


def test_unnormalized_weights_are_normalized_and_bad_ones_rejected():
    rng = np.random.default_rng(0)
    counts = copies(systematic_resample(WEIGHTS * 7.0, rng, 100), 5)
    np.testing.assert_allclose(counts, 100 * WEIGHTS, atol=1)
    for bad in ([], [0.0, 0.0], [0.5, np.nan], [0.5, -0.1]):
        with pytest.raises(ValueError, match="weights"):
            residual_resample(np.array(bad), rng)


def test_effective_sample_size():
    assert effective_sample_size(np.ones(10)) == pytest.approx(10)
    assert effective_sample_size(np.array([1.0, 0, 0, 0])) == pytest.approx(1)
