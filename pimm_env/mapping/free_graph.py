"""The free space as a graph: nodes on a coarse grid of the places that keep a clearance from every obstacle
and unknown cell (the largest connected region), 8-connected, each step's cost raised near obstacles so that
shortest paths keep to the middle of corridors. Routes (``driving/routes.py``) and walking people
(``sim/movers.py``) plan on it; ``geodesic_from`` gives path costs over a grid's passable cells."""

from __future__ import annotations

import heapq
import math
from dataclasses import dataclass

import numpy as np
from numba import njit
from scipy import ndimage
from scipy.sparse import coo_matrix

from pimm_env.errors import NoFreeRegionError
from pimm_env.mapping.occupancy import OccupancyGrid


@dataclass(frozen=True)
class FreeGraph:
    xy: np.ndarray  # (N, 2) node positions
    clearance: np.ndarray  # (N,) metres
    matrix: object  # sparse (N, N) step costs
    cell_clearance: np.ndarray  # metres, every cell of the occupancy grid


def free_graph(occupancy: OccupancyGrid, clearance_m: float, step_m: float) -> FreeGraph:
    grid = occupancy.grid
    clearance = ndimage.distance_transform_edt(occupancy.free) * grid.resolution
    stride = max(1, round(step_m / grid.resolution))
    sub = clearance[::stride, ::stride]
    ok = sub >= clearance_m
    labels, count = ndimage.label(ok, structure=np.ones((3, 3)))
    if count == 0:
        raise NoFreeRegionError(f"no free place keeps {clearance_m} m from every obstacle")
    largest = np.argmax(np.bincount(labels.ravel())[1:]) + 1
    rows, cols = np.nonzero(labels == largest)
    index = -np.ones(sub.shape, dtype=np.int64)
    index[rows, cols] = np.arange(len(rows))
    xy = np.column_stack(
        [
            grid.origin[0] + (cols * stride + 0.5) * grid.resolution,
            grid.origin[1] + (rows * stride + 0.5) * grid.resolution,
        ]
    )
    node_clearance = sub[rows, cols]
    sources, targets, costs = [], [], []
    step = stride * grid.resolution
    for dr, dc in ((0, 1), (1, 0), (1, 1), (1, -1)):
        r2, c2 = rows + dr, cols + dc
        inside = (r2 >= 0) & (r2 < sub.shape[0]) & (c2 >= 0) & (c2 < sub.shape[1])
        j = np.full(len(rows), -1)
        j[inside] = index[r2[inside], c2[inside]]
        linked = j >= 0
        i = np.nonzero(linked)[0]
        length = step * np.hypot(dr, dc)
        cost = length * (1 + 1.0 / np.minimum(node_clearance[i], node_clearance[j[linked]]))
        sources += [i, j[linked]]
        targets += [j[linked], i]
        costs += [cost, cost]
    n = len(rows)
    matrix = coo_matrix((np.concatenate(costs), (np.concatenate(sources), np.concatenate(targets))), shape=(n, n))
    return FreeGraph(xy, node_clearance, matrix.tocsr(), clearance)


def path_nodes(predecessors: np.ndarray, goal: int) -> list[int]:
    path = [goal]
    while predecessors[path[-1]] >= 0:
        path.append(int(predecessors[path[-1]]))
    return path[::-1]


@njit(cache=True, nogil=True)
def geodesic_from(passable: np.ndarray, row: int, col: int, limit: float, cost: np.ndarray) -> np.ndarray:
    """Path cost (8-connected) from (row, col) to every ``passable`` cell within ``limit``; infinity elsewhere. A
    step costs its length in cells times the mean of ``cost`` at its two cells (all ones: the path length in
    cells)."""
    rows, cols = passable.shape
    dist = np.full((rows, cols), np.inf)
    dist[row, col] = 0.0
    heap = [(0.0, row, col)]
    diagonal = math.sqrt(2.0)
    while heap:
        d, r, c = heapq.heappop(heap)
        if d > dist[r, c] or d > limit:
            continue
        for dr in range(-1, 2):
            for dc in range(-1, 2):
                if dr == 0 and dc == 0:
                    continue
                nr, nc = r + dr, c + dc
                if not (0 <= nr < rows and 0 <= nc < cols) or not passable[nr, nc]:
                    continue
                nd = d + (diagonal if dr != 0 and dc != 0 else 1.0) * 0.5 * (cost[r, c] + cost[nr, nc])
                if nd < dist[nr, nc]:
                    dist[nr, nc] = nd
                    heapq.heappush(heap, (nd, nr, nc))
    return dist
