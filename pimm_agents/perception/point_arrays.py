"""Row tests and column statistics of (N, 3) point arrays, without numpy's slow reductions over a short axis.

``np.isfinite(points).all(axis=1)`` takes about 0.36 ms on a 14 400-point cloud and ``points.mean(axis=0)``
40 us on 1 400 points, where a pass per column or one matrix product takes a tenth of that. These run several
times per scan (segmentation, corners, every plane fit), so they are written once here.
"""

from __future__ import annotations

import numpy as np

from pimm_env.errors import ObservationError


def finite_rows(points: np.ndarray) -> np.ndarray:
    """(N,) bool: whether every coordinate of each row is finite (same as ``np.isfinite(p).all(axis=1)``)."""
    points = np.asarray(points)
    finite = np.ones(len(points), dtype=bool)
    for column in range(points.shape[1]):
        finite &= np.isfinite(points[:, column])
    return finite


def column_mean(points: np.ndarray) -> np.ndarray:
    """Mean of each column, as one matrix product (equal to ``points.mean(axis=0)`` to rounding)."""
    if len(points) == 0:
        raise ObservationError("column_mean of an empty array")
    return np.ones(len(points)) @ points / len(points)


def column_bounds(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Minimum and maximum of each column (exactly ``points.min(axis=0), points.max(axis=0)``)."""
    by_column = np.ascontiguousarray(np.asarray(points).T)
    return by_column.min(axis=1), by_column.max(axis=1)
