"""What the map says a robot would see from a place, and where going would tell look-alike places apart.

A robot knows its map. When its belief holds several places (a look-alike twin one bay down the corridor, a
mirror image), each hypothesis predicts what the robot would see if it drove to a given offset from where it
believes it is: the map's walls, ray-cast from that offset placed at each hypothesis. Where the predictions
differ, going there settles which hypothesis is right; where they agree, going there tells nothing.
:class:`ViewPredictor` answers three questions on that footing: the path to the place that tells a pose apart
from the most of its twins (:meth:`~ViewPredictor.telling_path`, the guide's far plan), the nearby place whose
views best tell weighted hypotheses apart (:meth:`~ViewPredictor.best_waypoint`, its near search), and how far
the nearest place that tells a pose from all its twins lies (:meth:`~ViewPredictor.nearest_telling`, the active
bound). The guide that turns these into the env's observation is guide.py.

Paths keep to the middle of corridors and doorways (``cost_centred``), so that a robot that turns in 45 deg
steps meets a door square on; the bound's lengths are plain path lengths. The ray casting and the path search
are compiled (numba): a near search scores a few hundred candidate places for up to six hypotheses at 36
bearings, about 40 ms on a 2-core AMD EPYC; a far plan, about a second on a 2-core Intel Xeon.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from pimm_env.mapping.free_graph import geodesic_from
from pimm_env.mapping.occupancy import OccupancyGrid


@dataclass(frozen=True)
class ViewConfig:
    """Ours (chosen on the policy's development buildings, docs/environment.md#active-localization)."""

    beams: int = 36  # bearings of each predicted view (every 10 deg)
    view_range_m: float = 10.0  # a predicted range is capped here (walls further off weigh little)
    range_gap_m: float = 1.0  # two views differ at a bearing whose ranges differ by more than this
    clearance_m: float = 0.35  # a candidate or path cell keeps this far from the map's obstacles
    reach_m: float = 10.0  # candidates within this geodesic distance of the estimate
    spacing_m: float = 0.5  # candidate places on a lattice of this spacing
    distance_cost: float = 0.01  # disagreement (0..1) a candidate loses per metre of path
    min_gain: float = 0.02  # a place must tell the hypotheses apart by this much more than where the robot is
    waypoint_m: float = 1.0  # the policy heads for the path's point this far along it, when no farther one is in sight
    #: or for the farthest point up to ``lookahead_m`` along the path that it sees down a lane of ``lane_m`` either
    #: side (its body's 0.25 m radius and 5 cm): a point along a path that bends through a doorway, taken blind,
    #: has the robot head for the doorway's jamb and stand at it
    lookahead_m: float = 3.0
    lane_m: float = 0.3
    back_radius_m: float = 2.0  # a path through the half disc this wide behind the robot leaves backwards
    min_weight: float = 0.2  # every hypothesis counts with at least this share of the heaviest one's weight
    min_move_m: float = 1.0  # a place this near is where the robot already is: it shows nothing new
    plausible_misfit: float = 0.1  # a hypothesis whose view fits the scan worse than the estimate's by this is left out
    #: the guide's paths keep to the middle of corridors and doorways: a cell nearer than ``centre_m`` to the map's
    #: obstacles costs up to ``centre_cost`` more per metre (at ``clearance_m``), so that a robot turning in 45 deg
    #: steps, whose forward guard stops 0.5 m short of anything ahead, meets a doorway square on
    centre_m: float = 0.75
    centre_cost: float = 4.0


def place(base: np.ndarray, offset: np.ndarray) -> np.ndarray:
    """``offset`` (N, 2), in the frame of pose ``base`` (x, y, theta), in the map frame."""
    c, s = math.cos(base[2]), math.sin(base[2])
    return np.column_stack(
        [base[0] + c * offset[:, 0] - s * offset[:, 1], base[1] + s * offset[:, 0] + c * offset[:, 1]]
    )


def in_frame(base: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Map points (N, 2) in the frame of pose ``base`` (x, y, theta): ``place``'s inverse."""
    c, s = math.cos(base[2]), math.sin(base[2])
    d = np.asarray(points, dtype=float) - np.asarray(base, dtype=float)[:2]
    return np.column_stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]])


def point_along(path: np.ndarray, start: int, metres: float) -> np.ndarray:
    """The point of ``path`` (N, 2) about ``metres`` along it from its point ``start`` (its last point when the
    path is shorter)."""
    along = np.cumsum(np.r_[0.0, np.hypot(*np.diff(path, axis=0).T)])
    return path[min(int(np.searchsorted(along, along[start] + metres)), len(path) - 1)]


@njit(cache=True, nogil=True)
def cast_ranges(
    origins: np.ndarray,
    headings: np.ndarray,
    bearings: np.ndarray,
    blocked: np.ndarray,
    origin_x: float,
    origin_y: float,
    resolution: float,
    max_range: float,
) -> np.ndarray:
    """Ranges (N, B) from each origin (N, 2) at heading + each bearing until a ``blocked`` cell (or off the
    map), marched in steps of one cell, capped at ``max_range``."""
    n, b = origins.shape[0], bearings.shape[0]
    rows, cols = blocked.shape
    out = np.empty((n, b))
    steps = int(max_range / resolution)
    for i in range(n):
        for j in range(b):
            a = headings[i] + bearings[j]
            dx, dy = math.cos(a) * resolution, math.sin(a) * resolution
            x, y = origins[i, 0], origins[i, 1]
            t = 0
            while t < steps:
                col = math.floor((x - origin_x) / resolution)
                row = math.floor((y - origin_y) / resolution)
                if not (0 <= row < rows and 0 <= col < cols) or blocked[row, col]:
                    break
                x += dx
                y += dy
                t += 1
            out[i, j] = t * resolution
    return out


def differing(a: np.ndarray, b: np.ndarray, gap: float) -> np.ndarray:
    """Per row of views ``a`` and ``b`` (..., B), the share of bearings whose ranges differ by more than ``gap``,
    each bearing of ``a`` compared with ``b``'s at it and its two neighbours (a ray that grazes a door jamb in one
    view and passes it in the other is not a difference)."""
    nearest = np.min(np.stack([np.abs(a - np.roll(b, k, axis=-1)) for k in (-1, 0, 1)]), axis=0)
    return np.mean(nearest > gap, axis=-1)


def disagreement(views: np.ndarray, weights: np.ndarray, gap: float) -> np.ndarray:
    """How differently the hypotheses see each candidate: views (H, N, B) ranges, weights (H,); per candidate
    the weighted mean over hypothesis pairs of the share of bearings that differ (``differing``), 0..1."""
    total, pairs = np.zeros(views.shape[1]), 0.0
    for i in range(len(views)):
        for j in range(i + 1, len(views)):
            w = weights[i] * weights[j]
            total += w * differing(views[i], views[j], gap)
            pairs += w
    return total / pairs if pairs > 0 else total


class ViewPredictor:
    """The map's predicted views, and the place whose views best tell a belief's hypotheses apart."""

    def __init__(self, occupancy: OccupancyGrid, config: ViewConfig | None = None) -> None:
        self.config = c = config or ViewConfig()
        self.grid = occupancy.grid
        self.blocked = np.ascontiguousarray(occupancy.occupied | ~occupancy.free)
        self.clearance = clearance = occupancy.distance_to_occupied()
        self.passable = np.ascontiguousarray(occupancy.free & (clearance >= c.clearance_m))
        near = np.clip((c.centre_m - clearance) / max(c.centre_m - c.clearance_m, 1e-9), 0.0, 1.0)
        self.cost_centred = np.ascontiguousarray(1.0 + c.centre_cost * near)
        self.cost_plain = np.ones_like(self.cost_centred)
        self.bearings = np.linspace(-np.pi, np.pi, c.beams, endpoint=False)

    def views(self, poses: np.ndarray, bearings: np.ndarray | None = None) -> np.ndarray:
        """Predicted ranges (N, B) from poses (N, 3) at ``bearings`` (robot frame; the config's beams when
        None)."""
        g = self.grid
        poses = np.asarray(poses, dtype=float).reshape(-1, 3)
        return cast_ranges(
            np.ascontiguousarray(poses[:, :2]),
            np.ascontiguousarray(poses[:, 2]),
            self.bearings if bearings is None else np.ascontiguousarray(bearings, dtype=float),
            self.blocked,
            g.origin[0],
            g.origin[1],
            g.resolution,
            self.config.view_range_m,
        )

    def misfit(self, poses: np.ndarray, ranges: np.ndarray, bearings: np.ndarray) -> np.ndarray:
        """How far each pose's predicted view is from a seen one (``ranges`` at ``bearings``, robot frame),
        ranges capped at the view range: the share of bearings that differ by more than ``range_gap_m``."""
        c = self.config
        seen = np.minimum(np.asarray(ranges, dtype=float), c.view_range_m)
        predicted = self.views(poses, bearings)
        return np.mean(np.abs(predicted - seen[None, :]) > c.range_gap_m, axis=1)

    def best_waypoint(
        self,
        estimate: np.ndarray,
        hypotheses: np.ndarray,
        weights: np.ndarray,
        keep: np.ndarray | None = None,
        min_move: float = 0.0,
    ) -> tuple[np.ndarray, np.ndarray, float] | None:
        """The waypoint toward the reachable place whose views best tell ``hypotheses`` (H, 3, map frame, with
        ``weights``) apart, as the robot believes it is at ``estimate``: (waypoint offset in the estimate's
        frame, the place's offset in it, how much better it tells them apart than where the robot is), or None
        when no reachable place tells them apart better by ``min_gain``. ``keep`` (offset in
        the estimate's frame) is the place chosen before: a candidate within 1.5 m of it scores 0.1 more, so
        that the policy does not switch between places of about equal worth at every step. Places within
        ``min_move`` of the estimate are not candidates."""
        c, g = self.config, self.grid
        found = self._candidates(estimate, c.reach_m, self.cost_centred)
        if found is None:
            return None
        dist, cand_r, cand_c, offsets = found
        w = np.maximum(np.asarray(weights, dtype=float), c.min_weight * float(np.max(weights)))
        offsets = np.vstack([np.zeros((1, 2)), offsets])  # where the robot is, first
        views = np.stack(
            [self.views(np.column_stack([place(h, offsets), np.full(len(offsets), h[2])])) for h in hypotheses]
        )
        told = disagreement(views, w, c.range_gap_m)
        offsets, gain = offsets[1:], told[1:] - told[0]
        score = gain - c.distance_cost * dist[cand_r, cand_c] * g.resolution
        score[gain < c.min_gain] = -np.inf
        score[np.hypot(offsets[:, 0], offsets[:, 1]) < min_move] = -np.inf
        if keep is not None:
            score = score + 0.1 * (np.hypot(offsets[:, 0] - keep[0], offsets[:, 1] - keep[1]) <= 1.5)
        best = int(np.argmax(score))
        if not np.isfinite(score[best]):
            return None
        path = self._path(dist, int(cand_r[best]), int(cand_c[best]))
        waypoint = in_frame(estimate, self.steer(path, 0, estimate)[None, :])[0]
        return waypoint, offsets[best], float(gain[best])

    def steer(self, path: np.ndarray, start: int, pose: np.ndarray) -> np.ndarray:
        """The point of ``path`` (map points) to head for from ``pose``, its point ``start`` the nearest: the
        farthest up to ``lookahead_m`` along it whose straight way from the pose keeps ``lane_m`` from the map's
        obstacles (past the body's own first 0.25 m), else the point ``waypoint_m`` along it."""
        c, g = self.config, self.grid
        along = np.cumsum(np.r_[0.0, np.hypot(*np.diff(path[start:], axis=0).T)])
        ahead = path[start:][along <= c.lookahead_m]
        for point in ahead[::-1]:
            gap = np.hypot(*(point - pose[:2]))
            steps = np.arange(min(0.25, gap), gap + 1e-9, g.resolution / 2)
            if len(steps) == 0:
                continue
            direction = (point - pose[:2]) / max(gap, 1e-9)
            rows, cols, inside = g.cells_of(pose[:2] + steps[:, None] * direction)
            if inside.all() and np.all(self.clearance[rows, cols] >= c.lane_m):
                return point
        return point_along(path, start, c.waypoint_m)

    def nearest_telling(self, pose: np.ndarray, twins: np.ndarray, reach_m: float, min_share: float) -> float | None:
        """Path length (m) from ``pose`` to the nearest place (on the candidates' lattice) whose view differs
        from the view at the same offset from every one of ``twins`` (K, 3) in at least ``min_share`` of the
        bearings (each compared with the other's at it and its neighbours), or where a twin's place is not
        passable; 0 with no twins; None when no place within ``reach_m`` does."""
        twins = np.asarray(twins, dtype=float).reshape(-1, 3)
        if len(twins) == 0:
            return 0.0
        found = self._told(pose, twins, reach_m, min_share, self.cost_plain)
        if found is None:
            return None
        dist, cand_r, cand_c, _, count = found
        told = count == len(twins)
        if not told.any():
            return None
        return float(np.min(dist[cand_r[told], cand_c[told]]) * self.grid.resolution)

    def telling_path(
        self,
        pose: np.ndarray,
        twins: np.ndarray,
        reach_m: float,
        min_share: float,
        min_move: float,
        back_m: float = 0.0,
    ) -> tuple[np.ndarray, float] | None:
        """The path (map points, from ``pose``) to the nearest place within ``reach_m`` of path (at least
        ``min_move`` from ``pose``) of those that tell ``pose`` apart from the most of ``twins`` (K, 3) (as
        ``nearest_telling`` tells them), and the share of the twins it tells apart; None when no such place tells
        any twin apart. The localizer can be sure only once every twin has fallen, so a place that tells all of
        them apart is worth the way to it (measured against a trade of share for distance on the development
        buildings, docs/environment.md#active-localization). A path that leaves backwards (through the half
        disc of ``back_radius_m`` behind the pose) counts ``back_m`` longer: a robot that turns back to the
        nearer end of a corridor after driving half of it loses all it drove."""
        twins = np.asarray(twins, dtype=float).reshape(-1, 3)
        if len(twins) == 0:
            return None
        found = self._told(pose, twins, reach_m, min_share, self.cost_centred)
        if found is None:
            return None
        dist, cand_r, cand_c, offsets, count = found
        count[np.hypot(offsets[:, 0], offsets[:, 1]) < min_move] = 0
        if count.max() == 0:
            return None
        best = np.flatnonzero(count == count.max())
        cost = dist[cand_r[best], cand_c[best]]
        onward = self._onward(pose, reach_m) if back_m > 0 else None
        if onward is not None:
            ahead = onward[cand_r[best], cand_c[best]]
            back = cost + back_m / self.grid.resolution
            pick = int(np.argmin(np.minimum(ahead, back)))
            field = onward if ahead[pick] <= back[pick] else dist
        else:
            pick, field = int(np.argmin(cost)), dist
        place_ = int(best[pick])
        return self._path(field, int(cand_r[place_]), int(cand_c[place_])), float(count[place_]) / len(twins)

    def _onward(self, pose: np.ndarray, reach_m: float) -> np.ndarray | None:
        """The path cost field from ``pose`` with the half disc of ``back_radius_m`` behind it closed; None when
        the pose is not on a passable cell."""
        g, radius = self.grid, self.config.back_radius_m
        rows, cols, valid = g.cells_of(np.asarray(pose, dtype=float)[None, :2])
        if not valid[0] or not self.passable[rows[0], cols[0]]:
            return None
        span = int(np.ceil(radius / g.resolution))
        r0, r1 = max(0, rows[0] - span), min(g.shape[0], rows[0] + span + 1)
        c0, c1 = max(0, cols[0] - span), min(g.shape[1], cols[0] + span + 1)
        rr, cc = np.mgrid[r0:r1, c0:c1]
        dx = g.origin[0] + (cc + 0.5) * g.resolution - pose[0]
        dy = g.origin[1] + (rr + 0.5) * g.resolution - pose[1]
        behind = (np.hypot(dx, dy) <= radius) & (dx * np.cos(pose[2]) + dy * np.sin(pose[2]) < -g.resolution)
        passable = self.passable.copy()
        passable[r0:r1, c0:c1] &= ~behind
        return geodesic_from(passable, int(rows[0]), int(cols[0]), reach_m / g.resolution, self.cost_centred)

    def _told(
        self, pose: np.ndarray, twins: np.ndarray, reach_m: float, min_share: float, cost: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None:
        """``_candidates``' places reachable from ``pose`` (paths costed by ``cost``) and, per place, how many of
        ``twins`` its view tells ``pose`` apart from (``nearest_telling``'s test); None when nothing is
        reachable."""
        g = self.grid
        found = self._candidates(pose, reach_m, cost)
        if found is None:
            return None
        dist, cand_r, cand_c, offsets = found
        here = self.views(np.column_stack([place(pose, offsets), np.full(len(offsets), pose[2])]))
        count = np.zeros(len(offsets), dtype=int)
        for twin in twins:
            places = place(twin, offsets)
            r, q, inside = g.cells_of(places)
            open_there = inside & self.passable[np.where(inside, r, 0), np.where(inside, q, 0)]
            there = self.views(np.column_stack([places, np.full(len(places), twin[2])]))
            count += ~open_there | (differing(here, there, self.config.range_gap_m) >= min_share)
        return dist, cand_r, cand_c, offsets, count

    def open_along(self, points: np.ndarray) -> bool:
        """Whether every one of ``points`` (map frame) lies on the map's free cells (not blocked, not unknown)."""
        rows, cols, inside = self.grid.cells_of(np.asarray(points, dtype=float).reshape(-1, 2))
        return bool(inside.all() and not self.blocked[rows, cols].any())

    def _candidates(
        self, pose: np.ndarray, reach_m: float, cost: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None:
        """The places reachable from ``pose`` within ``reach_m`` of path (costed by ``cost``: ``cost_plain`` gives
        lengths, ``cost_centred`` keeps to the middle), on a lattice of ``spacing_m`` through its cell: the path
        cost field (cells), the places' rows and columns, and their offsets in the pose's frame; None when the
        pose is not on a passable cell or nothing is reachable."""
        g = self.grid
        rows, cols, valid = g.cells_of(np.asarray(pose, dtype=float)[None, :2])
        if not valid[0] or not self.passable[rows[0], cols[0]]:
            return None
        dist = geodesic_from(self.passable, int(rows[0]), int(cols[0]), reach_m / g.resolution, cost)
        stride = max(1, round(self.config.spacing_m / g.resolution))
        lattice = np.zeros_like(self.passable)
        lattice[rows[0] % stride :: stride, cols[0] % stride :: stride] = True
        cand_r, cand_c = np.nonzero(lattice & np.isfinite(dist))
        if len(cand_r) == 0:
            return None
        xy = np.column_stack([g.origin[0] + (cand_c + 0.5) * g.resolution, g.origin[1] + (cand_r + 0.5) * g.resolution])
        return dist, cand_r, cand_c, in_frame(pose, xy)

    def _path(self, dist: np.ndarray, row: int, col: int) -> np.ndarray:
        """The cells (as map points) from the geodesic field's source to (row, col), by steepest descent."""
        g = self.grid
        cells = [(row, col)]
        rows, cols = dist.shape
        while dist[row, col] > 0:
            best = (row, col)
            for dr in (-1, 0, 1):
                for dc in (-1, 0, 1):
                    r, cc = row + dr, col + dc
                    if 0 <= r < rows and 0 <= cc < cols and dist[r, cc] < dist[best]:
                        best = (r, cc)
            if best == (row, col):
                break
            row, col = best
            cells.append(best)
        cells.reverse()
        arr = np.array(cells, dtype=float)
        return np.column_stack(
            [g.origin[0] + (arr[:, 1] + 0.5) * g.resolution, g.origin[1] + (arr[:, 0] + 0.5) * g.resolution]
        )
