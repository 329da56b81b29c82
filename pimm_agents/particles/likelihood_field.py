"""The likelihood-field laser model of AMCL (Thrun et al., Probabilistic Robotics 6.4; nav2_amcl's default).

Each beam end point is scored by its distance to the nearest occupied cell. The per-cell score is
precomputed once, so an update is one gather per (particle, beam).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pimm_env.errors import LocalizerError
from pimm_env.mapping.occupancy import OccupancyGrid
from pimm_env.world.grid import GridSpec


def capped_distance(occupancy: OccupancyGrid, max_distance: float, surfaces_only: bool = False) -> np.ndarray:
    """Metres from every cell centre to the nearest occupied cell centre (or, with ``surfaces_only``, to the
    nearest occupied cell that touches free space), capped at ``max_distance``."""
    if max_distance <= 0:
        raise LocalizerError(f"laser_likelihood_max_dist must be positive, got {max_distance}")
    distance = occupancy.distance_to_surfaces() if surfaces_only else occupancy.distance_to_occupied()
    return np.minimum(distance, max_distance)


@dataclass(frozen=True)
class LikelihoodFieldParams:
    z_hit: float
    z_rand: float
    sigma_hit: float
    max_distance: float
    range_max: float
    #: ours (nav2: False): measure distances to the faces of obstacles that free space can see, so that an end
    #: point deep inside a solid block scores as the miss it is. With every occupied cell counting, a pose
    #: that throws a scan into a thick outer wall fits it perfectly; PIMM's wall field was pulled 12 m to such
    #: a pose in a held-out building (gen-907 route 3, development seeds), where the truth scored 2-4 nats less.
    surfaces_only: bool = False


@dataclass(frozen=True)
class BeamSkip:
    """nav2's beam skipping for ``likelihood_field_prob`` (its defaults): a beam counts only if more than
    ``threshold`` of the particles see its end point within ``distance`` of an obstacle; if ``error_threshold``
    of the beams or more would be skipped, the filter has probably converged to a wrong pose, and every beam
    counts."""

    distance: float = 0.5
    threshold: float = 0.3
    error_threshold: float = 0.9


class LikelihoodField:
    """Scores scans against an occupancy grid: a particle's weight factor is 1 + sum over beams of pz^3.

    pz = z_hit exp(-d^2 / 2 sigma_hit^2) + z_rand / range_max, with d the end point's distance to the
    nearest obstacle (``max_distance`` off the map; with ``surfaces_only``, the nearest face seen from free
    space). Summing cubes rather than multiplying is nav2's
    heuristic: it keeps single bad beams from zeroing a good particle.
    """

    def __init__(self, occupancy: OccupancyGrid, params: LikelihoodFieldParams) -> None:
        if not occupancy.occupied.any():
            raise LocalizerError("the occupancy map has no occupied cell: a likelihood field needs obstacles")
        if params.sigma_hit <= 0 or params.range_max <= 0:
            raise LocalizerError(f"sigma_hit and range_max must be positive: {params}")
        self.grid: GridSpec = occupancy.grid
        self.params = params
        self.distance = capped_distance(occupancy, params.max_distance, params.surfaces_only)
        rows, cols = self.grid.shape
        padded = np.full((rows + 2, cols + 2), params.max_distance)  # a ring of off-map cells
        padded[1:-1, 1:-1] = self.distance
        pz = params.z_hit * np.exp(-(padded**2) / (2 * params.sigma_hit**2)) + params.z_rand / params.range_max
        self._cubes = (pz**3).astype(np.float32).ravel()
        self._log_pz = np.log(pz).astype(np.float32).ravel()
        self._padded_distance = padded.astype(np.float32).ravel()
        self._cols = cols + 2
        self._limits = (np.float32(cols + 1), np.float32(rows + 1))

    def distance_at(self, points: np.ndarray) -> np.ndarray:
        """Capped distance at ``points`` (N, 2); ``max_distance`` off the map."""
        rows, cols, valid = self.grid.cells_of(np.asarray(points, dtype=float))
        out = np.full(len(points), self.params.max_distance)
        out[valid] = self.distance[rows[valid], cols[valid]]
        return out

    def weight_factors(
        self, poses: np.ndarray, ranges: np.ndarray, bearings: np.ndarray, origin: tuple[float, float] = (0.0, 0.0)
    ) -> np.ndarray:
        """1 + sum of pz^3 over the beams, for each robot pose (N, 3); beams leave ``origin`` (the sensor's
        place in the robot's frame) at ``bearings`` in the robot's frame."""
        if np.size(ranges) == 0:
            return np.ones(len(poses))
        cells = self._cells(poses, ranges, bearings, origin)
        return 1.0 + np.take(self._cubes, cells).sum(axis=1, dtype=np.float64)

    def log_likelihoods(self, poses: np.ndarray, ranges: np.ndarray, bearings: np.ndarray) -> np.ndarray:
        """Sum of log pz over the beams, for each pose (N, 3): the log of the beams' joint likelihood if they
        were independent (the textbook likelihood field; nav2 sums cubes instead)."""
        if np.size(ranges) == 0:
            return np.zeros(len(poses))
        return np.take(self._log_pz, self._cells(poses, ranges, bearings)).sum(axis=1, dtype=np.float64)

    def prob_factors(
        self,
        poses: np.ndarray,
        ranges: np.ndarray,
        bearings: np.ndarray,
        origin: tuple[float, float] = (0.0, 0.0),
        skip: BeamSkip | None = None,
    ) -> np.ndarray:
        """nav2's ``likelihood_field_prob``: the product of pz over the beams (exp of the summed logs, not the
        ``likelihood_field`` sum of cubes), for each pose (N, 3), with beam skipping when ``skip`` is given.

        Where nav2 would multiply in a beam's value left over from an earlier scan (a max-range beam, in the
        error case), the caller has already left such beams out: ``ranges`` holds only the beams to weigh.
        """
        if np.size(ranges) == 0:
            return np.ones(len(poses))
        cells = self._cells(poses, ranges, bearings, origin)
        log_pz = np.take(self._log_pz, cells)
        if skip is not None:
            near = np.take(self._padded_distance, cells) < skip.distance
            agreed = near.mean(axis=0) > skip.threshold  # per beam: the share of particles whose map it fits
            if np.count_nonzero(~agreed) < skip.error_threshold * len(agreed):
                log_pz = log_pz[:, agreed]
        return np.exp(log_pz.sum(axis=1, dtype=np.float64))

    def _cells(
        self, poses: np.ndarray, ranges: np.ndarray, bearings: np.ndarray, origin: tuple[float, float] = (0.0, 0.0)
    ) -> np.ndarray:
        """(N, B) flat indices into the padded tables of the beams' end points seen from each pose."""
        poses = np.asarray(poses, dtype=np.float32)
        ranges = np.asarray(ranges, dtype=np.float32)
        bearings = np.asarray(bearings, dtype=np.float32)
        res = np.float32(1.0 / self.grid.resolution)
        # Beam end points in cell units, shifted by the pad ring: a 2 x 2 rotation as one small matmul.
        ox, oy = np.float32(origin[0]), np.float32(origin[1])
        beams = np.stack([ox + ranges * np.cos(bearings), oy + ranges * np.sin(bearings)]) * res  # (2, B)
        c, s = np.cos(poses[:, 2]), np.sin(poses[:, 2])
        col = np.stack([c, -s], axis=1) @ beams
        col += ((poses[:, 0] - np.float32(self.grid.origin[0])) * res + np.float32(1.0))[:, None]
        row = np.stack([s, c], axis=1) @ beams
        row += ((poses[:, 1] - np.float32(self.grid.origin[1])) * res + np.float32(1.0))[:, None]
        np.clip(col, 0, self._limits[0], out=col)
        np.clip(row, 0, self._limits[1], out=row)
        flat = row.astype(np.int32)
        flat *= np.int32(self._cols)
        flat += col.astype(np.int32)
        return flat
