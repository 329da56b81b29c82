"""nav2_amcl's beam model (``laser_model_type: beam``; Probabilistic Robotics 6.3): each beam's measured range
against the range the map gives along it from the particle.

pz = z_hit exp(-(z - z*)^2 / 2 sigma_hit^2)                      a hit, noisy
   + z_short lambda_short exp(-lambda_short z)   if z < z*      something unmapped in front
   + z_max                                       if z = max     no return
   + z_rand / range_max                          if z < max     anything

and a particle's weight factor is 1 + sum of pz^3 over the beams, as nav2 sums it. Expected ranges come from
ray casting in the map as nav2's ``map_calc_range`` does: a ray stops at the first cell that is occupied,
unknown or off the map. We march each ray by the distance to the nearest such cell (sphere tracing on its
distance transform), all particles and beams at once, instead of nav2's cell-by-cell Bresenham walk.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from pimm_env.mapping.occupancy import OccupancyGrid


@dataclass(frozen=True)
class BeamModelParams:
    """nav2_amcl's defaults."""

    z_hit: float = 0.5
    z_short: float = 0.05
    z_max: float = 0.05
    z_rand: float = 0.5
    sigma_hit: float = 0.2
    lambda_short: float = 0.1

    def __post_init__(self) -> None:
        if self.sigma_hit <= 0 or self.lambda_short <= 0:
            raise ValueError(f"sigma_hit and lambda_short must be positive: {self}")


def beam_probabilities(
    measured: np.ndarray, expected: np.ndarray, range_max: float, params: BeamModelParams = BeamModelParams()
) -> np.ndarray:
    """pz of each beam (any shape, ``measured`` broadcast against ``expected``) as nav2's ``BeamModel`` adds
    it up; a measured range of ``range_max`` or more is a max-range reading."""
    p = params
    z = measured - expected
    pz = p.z_hit * np.exp(-(z * z) / (2 * p.sigma_hit**2))
    pz = pz + np.where(z < 0, p.z_short * p.lambda_short * np.exp(-p.lambda_short * measured), 0.0)
    is_max = measured >= range_max
    return pz + np.where(is_max, p.z_max, p.z_rand / range_max)


class RangeCaster:
    """Ranges along rays in an occupancy grid to the first cell that is not free (nav2's ``map_calc_range``:
    occupied, unknown or off the map), capped at ``range_max``."""

    #: Smallest step (cells): a ray grazing a wall still advances; the range is then good to about this.
    MIN_STEP = 0.5
    #: Steps before a ray is given up at its current range (grazing rays along long walls need the most).
    MAX_STEPS = 400

    def __init__(self, occupancy: OccupancyGrid, range_max: float) -> None:
        if range_max <= 0:
            raise ValueError(f"range_max must be positive, got {range_max}")
        self.grid = occupancy.grid
        self.range_max = float(range_max)
        blocked = ~occupancy.free
        rows, cols = self.grid.shape
        padded = np.ones((rows + 2, cols + 2), dtype=bool)  # a ring of off-map cells: they stop rays too
        padded[1:-1, 1:-1] = blocked
        # A safe step (cells) from anywhere in a cell: its centre's distance to the nearest blocked cell's centre,
        # less half a diagonal at each end.
        clearance = ndimage.distance_transform_edt(~padded) - np.sqrt(2.0)
        self._clearance = np.maximum(clearance, 0.0).astype(np.float32).ravel()
        self._blocked = padded.ravel()
        self._cols = cols + 2
        self._limits = (cols + 1, rows + 1)

    def ranges(self, poses: np.ndarray, bearings: np.ndarray, origin: tuple[float, float] = (0.0, 0.0)) -> np.ndarray:
        """(N, B) ranges (m) from each pose's sensor (at ``origin`` in the robot frame) along each bearing."""
        poses = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
        bearings = np.asarray(bearings, dtype=np.float64).ravel()
        res = self.grid.resolution
        c, s = np.cos(poses[:, 2]), np.sin(poses[:, 2])
        sx = poses[:, 0] + c * origin[0] - s * origin[1]
        sy = poses[:, 1] + s * origin[0] + c * origin[1]
        angle = (poses[:, 2:3] + bearings[None, :]).ravel()
        # Ray start and direction in cell units of the padded grid (cell centres at integer + 0.5).
        x0 = np.repeat((sx - self.grid.origin[0]) / res + 1.0, len(bearings)).astype(np.float32)
        y0 = np.repeat((sy - self.grid.origin[1]) / res + 1.0, len(bearings)).astype(np.float32)
        dx, dy = np.cos(angle).astype(np.float32), np.sin(angle).astype(np.float32)
        limit = np.float32(self.range_max / res)
        travelled = np.zeros(len(angle), dtype=np.float32)
        active = np.arange(len(angle))
        for _ in range(self.MAX_STEPS):
            t = travelled[active]
            col = np.clip(x0[active] + t * dx[active], 0, self._limits[0]).astype(np.int64)
            row = np.clip(y0[active] + t * dy[active], 0, self._limits[1]).astype(np.int64)
            flat = row * self._cols + col
            hit = self._blocked[flat]
            step = np.maximum(self._clearance[flat], np.float32(self.MIN_STEP))
            t = np.where(hit, t, t + step)
            travelled[active] = np.minimum(t, limit)
            active = active[~hit & (t < limit)]
            if active.size == 0:
                break
        return (travelled * np.float32(res)).astype(np.float64).reshape(len(poses), len(bearings))


class BeamModel:
    """nav2's beam model over an occupancy grid: weight factors for many poses at once."""

    def __init__(self, occupancy: OccupancyGrid, range_max: float, params: BeamModelParams = BeamModelParams()):
        self.params = params
        self.caster = RangeCaster(occupancy, range_max)

    def weight_factors(
        self, poses: np.ndarray, ranges: np.ndarray, bearings: np.ndarray, origin: tuple[float, float] = (0.0, 0.0)
    ) -> np.ndarray:
        """1 + sum over the beams of pz^3, for each pose (N, 3); ``ranges`` at or over range_max are no-returns."""
        if np.size(ranges) == 0:
            return np.ones(len(poses))
        expected = self.caster.ranges(poses, bearings, origin)
        measured = np.minimum(np.asarray(ranges, dtype=np.float64), self.caster.range_max)
        pz = beam_probabilities(measured[None, :], expected, self.caster.range_max, self.params)
        return 1.0 + (pz**3).sum(axis=1)
