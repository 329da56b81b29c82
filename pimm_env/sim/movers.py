"""What the maps do not have: people walking about, and furniture brought in after the map was made.

Both are upright boxes (class clutter) that both LiDARs see: rays are cast against the world as always,
then against these boxes, and the nearer hit wins. People (0.4 x 0.3 m, 1.7 m tall) walk shortest paths
between random free places (0.4 m from walls) at 0.5-1.4 m/s each, and wait while the robot is within 1 m
ahead of them. Unmapped furniture (desks, cabinets, shelves) stands along the walls. Neither is an obstacle
to the robot's body: the robot drives through a piece in its path, so placing furniture along walls keeps it
off the routes, and people step aside by waiting.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from pimm_env.errors import EnvError
from pimm_env.mapping.occupancy import OccupancyGrid

PERSON = (0.2, 0.15, 1.7)  # half length, half width, height (m)
#: furniture the map has not seen: (half length, half width, height) ranges (m)
FURNITURE = ((0.3, 0.8), (0.2, 0.4), (0.7, 1.9))


@dataclass
class Boxes:
    """Upright boxes: centre (x, y), yaw, half sizes, height over the floor."""

    xy: np.ndarray  # (B, 2)
    yaw: np.ndarray  # (B,)
    half: np.ndarray  # (B, 2)
    height: np.ndarray  # (B,)

    def __len__(self) -> int:
        return len(self.xy)

    def as_array(self) -> np.ndarray:
        """(B, 6): x, y, yaw, length, width, height (``info`` reports them so)."""
        return np.column_stack([self.xy, self.yaw, 2 * self.half, self.height])

    @staticmethod
    def concatenate(parts: list[Boxes]) -> Boxes:
        return Boxes(
            np.vstack([p.xy for p in parts]).reshape(-1, 2),
            np.concatenate([p.yaw for p in parts]),
            np.vstack([p.half for p in parts]).reshape(-1, 2),
            np.concatenate([p.height for p in parts]),
        )


def cast_boxes(origin: np.ndarray, directions: np.ndarray, boxes: Boxes, floor_z: float) -> np.ndarray:
    """Range along each unit direction (N, 3) from ``origin`` (3,) to the nearest box; inf where none is hit."""
    best = np.full(len(directions), np.inf)
    for (cx, cy), yaw, (hx, hy), h in zip(boxes.xy, boxes.yaw, boxes.half, boxes.height, strict=True):
        c, s = np.cos(yaw), np.sin(yaw)
        ox, oy = origin[0] - cx, origin[1] - cy
        lo = np.array([c * ox + s * oy, -s * ox + c * oy, origin[2] - floor_z])  # the origin in the box's frame
        d = np.column_stack(
            [
                c * directions[:, 0] + s * directions[:, 1],
                -s * directions[:, 0] + c * directions[:, 1],
                directions[:, 2],
            ]
        )
        with np.errstate(divide="ignore", invalid="ignore"):
            t1 = (np.array([-hx, -hy, 0.0]) - lo) / d
            t2 = (np.array([hx, hy, h]) - lo) / d
        near = np.nanmax(np.minimum(t1, t2), axis=1)
        far = np.nanmin(np.maximum(t1, t2), axis=1)
        hit = (far >= np.maximum(near, 0.0)) & np.isfinite(near)
        entry = np.where(near > 0, near, far)  # from inside a box, its far side
        best = np.where(hit & (entry < best), entry, best)
    return best


def free_clearance(occupancy: OccupancyGrid) -> np.ndarray:
    """Metres from every cell to the nearest cell that is not free."""
    return ndimage.distance_transform_edt(occupancy.free) * occupancy.grid.resolution


def place_furniture(occupancy: OccupancyGrid, count: int, rng: np.random.Generator) -> Boxes:
    """``count`` pieces standing along walls, turned parallel to the nearest one."""
    if count == 0:
        return Boxes(np.zeros((0, 2)), np.zeros(0), np.zeros((0, 2)), np.zeros(0))
    clearance = free_clearance(occupancy)
    grid = occupancy.grid
    half = np.column_stack([rng.uniform(*FURNITURE[0], count), rng.uniform(*FURNITURE[1], count)])
    height = rng.uniform(*FURNITURE[2], count)
    gy, gx = np.gradient(clearance)  # points away from the nearest wall
    xy, yaw = np.zeros((count, 2)), np.zeros(count)
    for i in range(count):
        rows, cols = np.nonzero(np.abs(clearance - (half[i, 1] + 0.05)) < grid.resolution / 2)
        if len(rows) == 0:
            raise EnvError(f"no place along a wall for unmapped furniture in {occupancy.grid.shape} map")
        k = int(rng.integers(len(rows)))
        r, c = rows[k], cols[k]
        xy[i] = grid.origin + (np.array([c, r]) + 0.5) * grid.resolution
        yaw[i] = np.arctan2(gy[r, c], gx[r, c]) + np.pi / 2  # the long side along the wall
    return Boxes(xy, yaw, half, height)


class WalkGraph:
    """Where people can walk (``mapping/free_graph.py``, 0.4 m from walls) and the legs they walk."""

    def __init__(self, occupancy: OccupancyGrid, clearance_m: float = 0.4, min_leg_m: float = 5.0) -> None:
        from scipy.spatial import cKDTree

        from pimm_env.mapping.free_graph import free_graph

        self.graph = free_graph(occupancy, clearance_m, step_m=0.2)
        self.tree = cKDTree(self.graph.xy)
        self.min_leg_m = min_leg_m

    def random_place(self, rng: np.random.Generator) -> np.ndarray:
        return self.graph.xy[int(rng.integers(len(self.graph.xy)))].copy()

    def leg(self, start: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """Node positions (K, 2) of the shortest path from the node nearest ``start`` to a random node at
        least ``min_leg_m`` (path cost) away, or any other reachable node where none is that far."""
        from scipy.sparse.csgraph import dijkstra

        from pimm_env.mapping.free_graph import path_nodes

        here = int(self.tree.query(start)[1])
        costs, predecessors = dijkstra(self.graph.matrix, indices=here, return_predecessors=True)
        far = np.flatnonzero(np.isfinite(costs) & (costs >= self.min_leg_m))
        if len(far) == 0:
            far = np.flatnonzero(np.isfinite(costs) & (costs > 0))
        if len(far) == 0:
            return self.graph.xy[[here]].copy()
        return self.graph.xy[path_nodes(predecessors, int(rng.choice(far)))].copy()


class Walkers:
    """People walking between random free places; :meth:`step` moves them on."""

    def __init__(self, occupancy: OccupancyGrid, count: int, rng: np.random.Generator) -> None:
        self.rng = rng
        self.graph = WalkGraph(occupancy) if count else None
        self.speed = rng.uniform(0.5, 1.4, count)
        self.paths: list[np.ndarray] = []
        self.position = np.zeros((count, 2))
        self.heading = np.zeros(count)
        for i in range(count):
            assert self.graph is not None
            start = self.graph.random_place(rng)
            self.position[i] = start
            self.paths.append(self.graph.leg(start, rng))

    def __len__(self) -> int:
        return len(self.position)

    def step(self, dt: float, robot_xy: np.ndarray) -> None:
        """Each walks ``speed * dt`` along its path, unless the robot is within 1 m ahead of it; at the end of
        its path it sets off for another place."""
        for i in range(len(self)):
            ahead = robot_xy - self.position[i]
            facing = np.array([np.cos(self.heading[i]), np.sin(self.heading[i])])
            if np.hypot(*ahead) < 1.0 and ahead @ facing > 0.5 * np.hypot(*ahead):
                continue  # let the robot pass
            self.position[i], self.heading[i], self.paths[i] = self._advance(i, self.speed[i] * dt)

    def _advance(self, i: int, distance: float) -> tuple[np.ndarray, float, np.ndarray]:
        position, path, heading = self.position[i].copy(), self.paths[i], self.heading[i]
        while distance > 0:
            if len(path) == 0:
                assert self.graph is not None
                path = self.graph.leg(position, self.rng)
                continue
            gap = path[0] - position
            length = float(np.hypot(*gap))
            if length > 1e-9:
                heading = float(np.arctan2(gap[1], gap[0]))
            if length <= distance:
                position, distance, path = path[0].copy(), distance - length, path[1:]
            else:
                position, distance = position + gap * (distance / length), 0.0
        return position, heading, path

    def boxes(self) -> Boxes:
        n = len(self)
        return Boxes(self.position.copy(), self.heading.copy(), np.tile(PERSON[:2], (n, 1)), np.full(n, PERSON[2]))


class Movers:
    """This episode's walkers and unmapped furniture, as the env uses them: moved each step, occluding the
    LiDARs' rays, reported in ``info``."""

    def __init__(self, occupancy: OccupancyGrid, walkers: int, unmapped: int, rng: np.random.Generator) -> None:
        self.furniture = place_furniture(occupancy, unmapped, rng) if unmapped else None
        self.walkers = Walkers(occupancy, walkers, rng) if walkers else None

    def step(self, dt: float, robot_xy: np.ndarray) -> None:
        if self.walkers is not None:
            self.walkers.step(dt, robot_xy)

    def boxes(self) -> Boxes | None:
        """Every box now, or None."""
        parts = [b for b in (self.furniture, self.walkers.boxes() if self.walkers else None) if b is not None]
        return Boxes.concatenate(parts) if parts else None

    def info(self) -> dict[str, np.ndarray]:
        out = {}
        if self.walkers is not None:
            out["walkers"] = self.walkers.boxes().as_array()
        if self.furniture is not None:
            out["unmapped"] = self.furniture.as_array()
        return out

    def occlude(
        self,
        origin: np.ndarray,
        directions: np.ndarray,
        ranges: np.ndarray,
        labels: np.ndarray,
        max_range: float,
        floor_z: float,
    ) -> tuple[np.ndarray, np.ndarray]:
        """The static world's ranges and labels (flattened, along ``directions``) with the nearer hits on the
        boxes, labelled clutter."""
        from pimm_env.world.semantics import SemanticClass

        boxes = self.boxes()
        if boxes is None:
            return ranges, labels
        near = cast_boxes(origin, directions, boxes, floor_z)
        nearer = (near < ranges) & (near <= max_range)
        return np.where(nearer, near, ranges), np.where(nearer, int(SemanticClass.CLUTTER), labels).astype(labels.dtype)
