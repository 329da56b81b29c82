"""Resampling schemes for particle filters: each maps normalized weights to the indices of the particles kept.

All take the random generator as an argument; none touches numpy's global state.
"""

from __future__ import annotations

import numpy as np

from pimm_env.errors import LocalizerError


def _checked(weights: np.ndarray) -> np.ndarray:
    weights = np.asarray(weights, dtype=float)
    if weights.ndim != 1 or weights.size == 0:
        raise LocalizerError(f"weights must be a non-empty 1-D array, got shape {weights.shape}")
    total = weights.sum()
    if not np.isfinite(total) or total <= 0 or np.any(weights < 0):
        raise LocalizerError(f"weights must be finite, non-negative and not all zero (sum {total})")
    return weights / total


def _draw_from_cdf(weights: np.ndarray, positions: np.ndarray) -> np.ndarray:
    cumulative = np.cumsum(weights)
    cumulative[-1] = 1.0  # rounding must never leave a position past the last bin
    return np.searchsorted(cumulative, positions, side="right")


def multinomial_resample(weights: np.ndarray, rng: np.random.Generator, n: int | None = None) -> np.ndarray:
    """``n`` independent draws (default: as many as there are weights), in draw order."""
    weights = _checked(weights)
    return _draw_from_cdf(weights, rng.random(weights.size if n is None else n))


def systematic_resample(weights: np.ndarray, rng: np.random.Generator, n: int | None = None) -> np.ndarray:
    """One random offset, then ``n`` evenly spaced positions: particle i is copied floor or ceil of n w_i times."""
    weights = _checked(weights)
    n = weights.size if n is None else n
    positions = (rng.random() + np.arange(n)) / n
    return _draw_from_cdf(weights, positions)


def residual_resample(weights: np.ndarray, rng: np.random.Generator, n: int | None = None) -> np.ndarray:
    """Copy particle i floor(n w_i) times, then fill the rest by multinomial draws on the residuals n w_i - copies."""
    weights = _checked(weights)
    n = weights.size if n is None else n
    scaled = n * weights
    copies = np.floor(scaled).astype(int)
    indices = np.repeat(np.arange(weights.size), copies)
    remaining = n - indices.size
    if remaining > 0:
        residual = scaled - copies
        indices = np.concatenate([indices, _draw_from_cdf(residual / residual.sum(), rng.random(remaining))])
    return indices


def effective_sample_size(weights: np.ndarray) -> float:
    """1 / sum(w^2) of the normalized weights (thesis eq. 3.17)."""
    weights = _checked(weights)
    return float(1.0 / np.sum(weights**2))
