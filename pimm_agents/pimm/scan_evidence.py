"""The rival check's inner loop, compiled: the summed log-likelihood of kept scans for many candidate poses.

For each pose (K), each kept scan (S) is placed where the robot was when it was seen (the pose carried back by
that scan's odometry motion), each of the scan's wall points (P in all) is looked up in the map's per-cell
log-likelihood, and the lookups are summed; a scan whose robot pose falls off the free space costs a fixed
penalty. The same arithmetic as the NumPy expression it replaced (the test compares the two), fused into one
pass: in NumPy the K x P intermediate arrays made this 0.67 ms a call on a typical stack (25 000 pose-points),
40 % of an active-localization step (``evaluate.py bench`` times both: ``rival_evidence_ms`` and
``rival_evidence_numpy_ms``). The loop runs point by point with every candidate inside: the candidates are
mostly a few places and their refinement steps, so one point's lookups fall in nearby cells, which stay in the
cache (the iiLab's table, 2.6 MB, is larger than a core's cache here). Each candidate's sum still runs in point
order, so the figures are those of the pose-by-pose loop to the bit; ``rival_evidence_ms`` went from 0.18 to 0.13-0.15
in back-to-back bench runs (docs/benchmarks.md#speed).

``scan_by_scan_evidence`` is the same arithmetic with each scan's sum kept apart: the rival check compares two
places scan by scan when it decides whether the scans tell them apart (``kept_scans.MAP_ERROR_CELLS``). Both carry
the poses by one helper (``carried_scans``); their point loops stay written out in each: with the lookup as a
shared inlined function both ran 2-3 times slower (the same values to the bit), so the six lines are kept twice.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def carried_scans(
    poses: np.ndarray, motions: np.ndarray, free: np.ndarray, origin_x: float, origin_y: float, resolution: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Each scan's robot pose for every candidate pose (K, 3) carried back by the scans' ``motions`` (S, 3),
    scan-major (S, K) so that the candidates of one point are read together: x, y, cos and sin of the heading,
    and whether it falls off the ``free`` cells (or off the map)."""
    k, s = poses.shape[0], motions.shape[0]
    rows, cols = free.shape
    tx = np.empty((s, k))
    ty = np.empty((s, k))
    ca = np.empty((s, k))
    sa = np.empty((s, k))
    off = np.zeros((s, k), dtype=np.bool_)
    for i in range(k):
        c, sn = math.cos(poses[i, 2]), math.sin(poses[i, 2])
        for j in range(s):
            tx[j, i] = poses[i, 0] + c * motions[j, 0] - sn * motions[j, 1]
            ty[j, i] = poses[i, 1] + sn * motions[j, 0] + c * motions[j, 1]
            heading = poses[i, 2] + motions[j, 2]
            ca[j, i], sa[j, i] = math.cos(heading), math.sin(heading)
            col = math.floor((tx[j, i] - origin_x) / resolution)
            row = math.floor((ty[j, i] - origin_y) / resolution)
            off[j, i] = not (0 <= row < rows and 0 <= col < cols and free[int(row), int(col)])
    return tx, ty, ca, sa, off


@njit(cache=True, nogil=True)
def summed_scan_evidence(
    poses: np.ndarray,
    motions: np.ndarray,
    scan_of: np.ndarray,
    points: np.ndarray,
    log_pz: np.ndarray,
    log_pz_off: float,
    free: np.ndarray,
    origin_x: float,
    origin_y: float,
    resolution: float,
    temperature: float,
    off_free: float,
) -> np.ndarray:
    """Per pose (K, 3): ``temperature`` x the summed ``log_pz`` (rows, cols) of every point (P, 2; robot frame at
    its scan ``scan_of``) placed from the pose carried back by its scan's ``motions`` (S, 3), a point off the map
    scoring ``log_pz_off``; plus ``off_free`` per scan whose carried pose is not on a ``free`` cell."""
    k, s, p = poses.shape[0], motions.shape[0], points.shape[0]
    rows, cols = log_pz.shape
    tx, ty, ca, sa, off = carried_scans(poses, motions, free, origin_x, origin_y, resolution)
    penalty = np.zeros(k)
    for i in range(k):
        for j in range(s):
            if off[j, i]:
                penalty[i] += off_free
    # point by point, every candidate in turn: nearby candidates (a place and its refinement steps) look up
    # nearby cells one after another, which the cache keeps; each candidate's sum runs in point order as before
    total = np.zeros(k)
    for q in range(p):
        j = scan_of[q]
        px, py = points[q, 0], points[q, 1]
        for i in range(k):
            x = tx[j, i] + ca[j, i] * px - sa[j, i] * py
            y = ty[j, i] + sa[j, i] * px + ca[j, i] * py
            col = math.floor((x - origin_x) / resolution)
            row = math.floor((y - origin_y) / resolution)
            if 0 <= row < rows and 0 <= col < cols:
                total[i] += log_pz[int(row), int(col)]
            else:
                total[i] += log_pz_off
    return temperature * total + penalty


@njit(cache=True, nogil=True)
def scan_by_scan_evidence(
    poses: np.ndarray,
    motions: np.ndarray,
    scan_of: np.ndarray,
    points: np.ndarray,
    log_pz: np.ndarray,
    log_pz_off: float,
    free: np.ndarray,
    origin_x: float,
    origin_y: float,
    resolution: float,
    temperature: float,
    off_free: float,
) -> np.ndarray:
    """``summed_scan_evidence`` per pose and scan (K, S): each scan's tempered summed ``log_pz`` over its points,
    plus ``off_free`` where its carried pose is not on a ``free`` cell. Its rows sum to that function's values
    (up to the order of the additions)."""
    k, s, p = poses.shape[0], motions.shape[0], points.shape[0]
    rows, cols = log_pz.shape
    tx, ty, ca, sa, off = carried_scans(poses, motions, free, origin_x, origin_y, resolution)
    out = np.zeros((k, s))
    penalty = np.where(off.T, off_free, 0.0)
    for q in range(p):
        j = scan_of[q]
        px, py = points[q, 0], points[q, 1]
        for i in range(k):
            x = tx[j, i] + ca[j, i] * px - sa[j, i] * py
            y = ty[j, i] + sa[j, i] * px + ca[j, i] * py
            col = math.floor((x - origin_x) / resolution)
            row = math.floor((y - origin_y) / resolution)
            if 0 <= row < rows and 0 <= col < cols:
                out[i, j] += log_pz[int(row), int(col)]
            else:
                out[i, j] += log_pz_off
    return temperature * out + penalty
