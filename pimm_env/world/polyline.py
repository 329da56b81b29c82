"""Polylines: simplification shared by the map importer (straight walls) and the route planner (waypoints), and
the nearest point of a path, shared by the driver and the kidnap fault."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np


def douglas_peucker(
    points: np.ndarray, tolerance: float, accept: Callable[[int, int], bool] | None = None
) -> list[int]:
    """Indices of ``points`` (N, 2), an open polyline, kept by Douglas-Peucker: a stretch i..j becomes one
    segment when no point of it lies farther than ``tolerance`` from the chord and ``accept(i, j)`` (if given)
    allows it. Both ends are kept."""
    keep = {0, len(points) - 1}
    stack = [(0, len(points) - 1)]
    while stack:
        i, j = stack.pop()
        if j <= i + 1:
            continue
        a, b = points[i], points[j]
        ab = b - a
        length = float(np.hypot(*ab))
        rel = points[i + 1 : j] - a
        dist = np.abs(ab[0] * rel[:, 1] - ab[1] * rel[:, 0]) / length if length > 0 else np.hypot(*rel.T)
        k = int(np.argmax(dist))
        if dist[k] <= tolerance and (accept is None or accept(i, j)):
            continue
        keep.add(i + 1 + k)
        stack += [(i, i + 1 + k), (i + 1 + k, j)]
    return sorted(keep)


def nearest_on_path(path: np.ndarray, xy: np.ndarray) -> tuple[int, np.ndarray, float]:
    """The segment of the polyline ``path`` (K, 2) nearest ``xy``, the nearest point on it, and how far along
    the whole path that point lies (m)."""
    a, ab = path[:-1], np.diff(path, axis=0)
    lengths = np.hypot(ab[:, 0], ab[:, 1])
    t = np.clip(np.einsum("ij,ij->i", xy[:2] - a, ab) / np.maximum(lengths**2, 1e-12), 0, 1)
    points = a + t[:, None] * ab
    j = int(np.argmin(np.hypot(*(points - xy[:2]).T)))
    return j, points[j], float(lengths[:j].sum() + t[j] * lengths[j])
