import numpy as np
import pytest

from pimm_agents.perception.point_arrays import column_bounds, column_mean, finite_rows


def test_finite_rows_flags_a_non_finite_value_in_any_column():
    points = np.random.default_rng(0).normal(size=(50, 3))
    points[3, 0], points[7, 1], points[11, 2], points[13] = np.nan, np.inf, -np.inf, np.nan
    expected = np.isfinite(points).all(axis=1)
    assert np.array_equal(finite_rows(points), expected) and expected.sum() == 46
    assert finite_rows(np.zeros((0, 3))).shape == (0,)


def test_column_statistics_match_numpys():
    points = np.random.default_rng(1).normal(size=(1401, 3)) * [3.0, 0.02, 2.0] + [-20.0, 10.0, 1.0]
    assert np.allclose(column_mean(points), points.mean(axis=0), rtol=0, atol=1e-12)
    lower, upper = column_bounds(points)
    assert np.array_equal(lower, points.min(axis=0)) and np.array_equal(upper, points.max(axis=0))
    with pytest.raises(ValueError, match="empty"):
        column_mean(np.zeros((0, 3)))
