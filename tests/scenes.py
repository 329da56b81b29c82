"""The scenes the filter, step and rival tests share: an L-shaped room with its corners, and two identical rooms
told apart by one block; the rays a robot sees there, and a drive as the localizer drives its measurement step."""

from collections.abc import Callable

import numpy as np

from pimm_agents.corners.lookup import NearestCornerGrid
from pimm_agents.particles.likelihood_field import LikelihoodField, LikelihoodFieldParams
from pimm_agents.pimm.ambiguity import AmbiguityCheck
from pimm_agents.pimm.feature_filter import FeatureFilter, FeatureFilterConfig
from pimm_agents.pimm.rivals import RivalConfig
from pimm_agents.pimm.step import MeasurementStep
from pimm_env.geometry import carry, compose, relative_motion
from pimm_env.mapping.corner_map import CornerMap
from pimm_env.mapping.occupancy import OccupancyGrid
from pimm_env.world.grid import GridSpec

# An L-shaped room: 10 m x 6 m without its 4 m x 3 m north-east block. Corners as (x, y, bisector heading).
CORNERS = np.array(
    [
        [0.0, 0.0, np.pi / 4],
        [10.0, 0.0, 3 * np.pi / 4],
        [10.0, 3.0, -3 * np.pi / 4],
        [6.0, 3.0, np.pi / 4 + np.pi],  # the outside corner faces away from the block
        [6.0, 6.0, -3 * np.pi / 4],
        [0.0, 6.0, -np.pi / 4],
    ]
)


def l_room() -> tuple[OccupancyGrid, NearestCornerGrid]:
    grid = GridSpec.covering(np.array([0.0, 0.0]), np.array([10.0, 6.0]), 0.1, margin=0.5)
    gx, gy = grid.cell_centers()
    inside = (gx > 0) & (gx < 10) & (gy > 0) & (gy < 6) & ~((gx > 6) & (gy > 3))
    ring = (gx > -0.3) & (gx < 10.3) & (gy > -0.3) & (gy < 6.3) & ~inside & ~((gx > 6.3) & (gy > 3.3))
    occupancy = OccupancyGrid(grid, occupied=ring, free=inside)
    corners = CornerMap(xy=CORNERS[:, :2].copy(), z=np.full(len(CORNERS), 3.0), theta=CORNERS[:, 2].copy())
    return occupancy, NearestCornerGrid(corners)


def features_from(pose: np.ndarray, sigma_pos: float = 0.3, sigma_theta: float = 0.2, reach: float = 8.0):
    """The corners within ``reach``, in the robot frame at ``pose``, as the filter takes them."""
    near = CORNERS[np.hypot(*(CORNERS[:, :2] - pose[:2]).T) < reach]
    local = np.array([relative_motion(pose, c) for c in near])
    return np.column_stack([local, np.full(len(local), sigma_pos), np.full(len(local), sigma_theta)])


def path() -> np.ndarray:
    """A drive east along y = 1.5, then north at x = 3: true poses every 0.15 m."""
    east = [[x, 1.5, 0.0] for x in np.arange(1.0, 8.0, 0.15)]
    north = [[3.0, y, np.pi / 2] for y in np.arange(1.5, 5.0, 0.15)]
    return np.array(east + north)


def walls_seen_from(pose: np.ndarray, count: int = 60) -> np.ndarray:
    """End points of ``count`` rays from ``pose`` to the L room's walls (its outline), in the robot frame."""
    occupancy, _ = l_room()
    directions = np.linspace(-np.pi, np.pi, count, endpoint=False)
    steps = np.arange(0.05, 12.0, 0.02)
    points = []
    for a in directions:
        ray = pose[:2] + steps[:, None] * [np.cos(pose[2] + a), np.sin(pose[2] + a)]
        rows, cols, valid = occupancy.grid.cells_of(ray)
        hit = np.nonzero(valid & occupancy.occupied[np.where(valid, rows, 0), np.where(valid, cols, 0)])[0]
        if len(hit):
            points.append(relative_motion(pose, np.array([*ray[hit[0]], 0.0]))[:2])
    return np.array(points)


# Two identical rooms, 10 m x 4 m, 2 m apart, each cut in two by a partition at its x = 5 with a door at its
# y = 0.5-1.5; the second room (x = 12-22) also has a block in the north-east corner of its east half, hidden
# from the west half by the partition.
BLOCK = (21.0, 21.7, 3.0, 3.8)


def twin_rooms() -> OccupancyGrid:
    grid = GridSpec.covering(np.array([0.0, 0.0]), np.array([22.0, 4.0]), 0.1, margin=0.5)
    gx, gy = grid.cell_centers()

    def room(x0: float) -> np.ndarray:
        x = gx - x0
        partition = (x > 4.9) & (x < 5.1) & ~((gy > 0.5) & (gy < 1.5))
        return (x > 0) & (x < 10) & (gy > 0) & (gy < 4) & ~partition

    block = (gx > BLOCK[0]) & (gx < BLOCK[1]) & (gy > BLOCK[2]) & (gy < BLOCK[3])
    free = (room(0.0) | room(12.0)) & ~block
    return OccupancyGrid(grid, occupied=~free, free=free)


def rays_from(occupancy: OccupancyGrid, pose: np.ndarray, reach: float, count: int = 60) -> np.ndarray:
    """End points (robot frame) of ``count`` rays from ``pose`` that hit an obstacle within ``reach``."""
    steps = np.arange(0.05, reach, 0.02)
    points = []
    for a in np.linspace(-np.pi, np.pi, count, endpoint=False):
        ray = pose[:2] + steps[:, None] * [np.cos(pose[2] + a), np.sin(pose[2] + a)]
        rows, cols, valid = occupancy.grid.cells_of(ray)
        hit = np.nonzero(valid & occupancy.occupied[np.where(valid, rows, 0), np.where(valid, cols, 0)])[0]
        if len(hit):
            points.append(relative_motion(pose, np.array([*ray[hit[0]], 0.0]))[:2])
    return np.array(points).reshape(-1, 2)


def wall_field_for(occupancy: OccupancyGrid) -> LikelihoodField:
    return LikelihoodField(occupancy, LikelihoodFieldParams(0.5, 0.5, 0.2, 2.0, 10.0))


def no_corners() -> NearestCornerGrid:
    """A corner map of one corner far from the robot's view: the filter weighs with the walls alone."""
    return NearestCornerGrid(CornerMap(xy=np.zeros((1, 2)), z=np.ones(1), theta=np.zeros(1)))


def make_step(
    occupancy: OccupancyGrid,
    corners: NearestCornerGrid | None,
    config: FeatureFilterConfig,
    rivals: RivalConfig | None = RivalConfig(),
    temperature: float | None = 0.2,
) -> MeasurementStep:
    """A filter with the wall field (``temperature``; None: nav2's sum of cubes) and, beside it, a rival check of
    ``rivals`` (None: the filter alone), as PIMM's localizer builds them; not reset."""
    field = wall_field_for(occupancy)
    filt = FeatureFilter(occupancy, corners, config, field, temperature)
    check = None if rivals is None or temperature is None else AmbiguityCheck(occupancy, field, temperature, rivals)
    return MeasurementStep(filt, check, 10)


def track(
    step: MeasurementStep,
    odometry: np.ndarray,
    truths: np.ndarray,
    scan: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray | None]],
) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """Drive the step as the localizer does: the last estimate carried by the odometry is the one a new
    estimate must outweigh. ``scan(truth)`` gives (features, wall points). Per update: status, estimate, truth."""
    out: list[tuple[str, np.ndarray, np.ndarray]] = []
    estimate, at = None, None
    for odom, truth in zip(odometry, truths, strict=True):
        if step.filter.motion_update(odom):
            previous = None if estimate is None else carry(estimate, at, odom)
            features, walls = scan(truth)
            found = step(features, walls, np.zeros((0, 2)), previous, np.asarray(odom, dtype=float))
            if found is not None:
                estimate, at = found, odom
            elif previous is not None:
                estimate, at = previous, odom
            out.append((step.reading.status, None if estimate is None else estimate.copy(), truth))
    return out


def round_east_and_round() -> np.ndarray:
    """True poses in the twin rooms: round and about in the second room's west half, east through the door to
    x = 20, and round again there. The block is a few of each scan's 60 rays; the first room's twin, fitted as
    well as the estimate, trails it by the drop margin (and so falls) only once the block is in sight."""
    turn = np.array([[14.0, 1.0, a] for a in np.linspace(0.0, 2 * np.pi, 40)])
    drive = [[x, 1.0, 0.0] for x in np.arange(14.0, 20.0, 0.12)]
    return np.vstack([turn, drive, [[20.0, 1.0, a] for a in np.linspace(0.0, 2 * np.pi, 40)[1:]]])


# A corridor (y 0-2) with five identical offices north of it (each 4 m x 3.8 m, its door at its west end), and a
# cabinet at the corridor's west end: the one thing that tells the offices' doorways apart, within a LiDAR's reach.
CABINET = (3.0, 3.6, 0.0, 0.5)


def office_row(offices: int = 5, pitch: float = 5.0) -> OccupancyGrid:
    length = offices * pitch
    grid = GridSpec.covering(np.array([0.0, 0.0]), np.array([length, 6.0]), 0.1, margin=0.5)
    gx, gy = grid.cell_centers()
    free = (gx > 0) & (gx < length) & (gy > 0) & (gy < 2)
    for k in range(offices):
        x0 = k * pitch + 0.5
        free |= (gx > x0) & (gx < x0 + 4.0) & (gy > 2.2) & (gy < 6)
        free |= (gx > x0 + 0.5) & (gx < x0 + 1.5) & (gy >= 1.9) & (gy <= 2.3)
    free &= ~((gx > CABINET[0]) & (gx < CABINET[1]) & (gy > CABINET[2]) & (gy < CABINET[3]))
    return OccupancyGrid(grid, occupied=~free, free=free)


def kidnapped_into_an_office() -> tuple[np.ndarray, np.ndarray, int]:
    """Odometry and true poses: east along the corridor from x = 1 to 8, then carried into the third office
    (turned), where it turns round once, leaves by the door and drives west along the corridor to x = 4; and the
    index of the first pose after the kidnap. The odometry knows nothing of the carrying."""
    truth = [[x, 1.0, 0.0] for x in np.arange(1.0, 8.0, 0.12)]
    kidnap = len(truth)
    truth += [[13.0, 4.0, 1.3 + a] for a in np.linspace(0.0, 2 * np.pi, 50)]
    for a, b in zip([(13.0, 4.0), (11.5, 3.0), (11.5, 1.0)], [(11.5, 3.0), (11.5, 1.0), (4.0, 1.0)], strict=True):
        a, b = np.array(a), np.array(b)
        heading = float(np.arctan2(*(b - a)[::-1]))
        truth += [[*(a + (b - a) * s), heading] for s in np.arange(0.0, 1.0, 0.12 / np.hypot(*(b - a)))]
    poses = np.array(truth)
    odometry = [poses[0]]
    for k in range(1, len(poses)):
        step = np.zeros(3) if k == kidnap else relative_motion(poses[k - 1], poses[k])
        odometry.append(compose(odometry[-1], step).reshape(3))
    return np.array(odometry), poses, kidnap
