"""Resampling schemes for particle filters: each maps normalized weights to the indices of the particles kept
(``mode_draws``: mode by mode, with a floor per mode).

All take the random generator as an argument; none touches numpy's global state.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from pimm_env.errors import LocalizerError

if TYPE_CHECKING:
    from pimm_agents.particles.belief import Belief


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


def mode_draws(
    weights: np.ndarray, belief: Belief, n: int, min_particles: int, keep_ratio: float, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """``n`` residual draws (indices, and their weights) that give each kept mode of ``belief`` (weighing at least
    ``keep_ratio`` of the heaviest) max(``min_particles``, its share of n) particles and the rest of the set the
    remainder; each group's particles share its weight, so the belief's modes weigh what they weighed (PIMM's
    per-mode budgets: a look-alike place is not starved of particles while the evidence cannot yet tell it)."""
    modes, of = belief.modes, belief.particle_mode
    kept = [k for k, m in enumerate(modes) if m.weight >= keep_ratio * modes[0].weight and m.weight > 0]
    mode_weights = np.array([modes[k].weight for k in kept])
    rest = np.flatnonzero(~np.isin(of, kept))
    rest_weight = float(weights[rest].sum()) if len(rest) else 0.0
    counts = np.maximum(min_particles, np.rint(n * mode_weights)).astype(int)
    rest_count = int(np.rint(n * rest_weight)) if rest_weight > 0 else 0
    heaviest = int(np.argmax(mode_weights))
    counts[heaviest] -= counts.sum() + rest_count - n  # the heaviest mode gives the floors their particles
    if counts[heaviest] < min_particles:  # more kept modes than n can give their floor: share by weight
        shares = np.append(mode_weights, rest_weight)
        all_counts = np.maximum(1, np.floor(n * shares / shares.sum())).astype(int)
        counts, rest_count = all_counts[:-1], int(all_counts[-1]) if rest_weight > 0 else 0
    groups = [(np.flatnonzero(of == k), counts[i]) for i, k in enumerate(kept)]
    if rest_count > 0:
        groups.append((rest, rest_count))
    index, drawn = [], []
    for members, count in groups:
        w = weights[members]
        index.append(members[residual_resample(w, rng, int(count))])
        drawn.append(np.full(int(count), w.sum() / count))
    all_weights = np.concatenate(drawn)
    return np.concatenate(index), all_weights / all_weights.sum()
