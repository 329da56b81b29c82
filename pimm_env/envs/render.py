"""Top-down pictures: the occupancy map, the robot, its current scans and optional paths (numpy only)."""

from __future__ import annotations

import numpy as np

from pimm_env.mapping.occupancy import OccupancyGrid

#: RGB per semantic class: wall, ceiling, floor, clutter.
CLASS_COLORS = np.array([[200, 60, 40], [60, 140, 220], [150, 150, 150], [230, 170, 30]], dtype=np.uint8)


def map_image(occupancy: OccupancyGrid) -> np.ndarray:
    """RGB image of the map, north up: free white, occupied black, unknown grey."""
    image = np.full((*occupancy.grid.shape, 3), 190, dtype=np.uint8)
    image[occupancy.free] = 255
    image[occupancy.occupied] = 0
    return image


def show_map(ax, occupancy: OccupancyGrid) -> None:
    """Draw an occupancy map on a matplotlib axis, in map coordinates (metres)."""
    g = occupancy.grid
    x0, y0 = g.origin
    extent = [x0, x0 + g.shape[1] * g.resolution, y0, y0 + g.shape[0] * g.resolution]
    ax.imshow(map_image(occupancy), origin="lower", extent=extent)


def plot_points(image: np.ndarray, occupancy: OccupancyGrid, xy: np.ndarray, color, size: int = 0) -> None:
    """Paint map-frame points ``xy`` (N, 2) into a map image (in the grid's row order) in place."""
    rows, cols, valid = occupancy.grid.cells_of(np.asarray(xy, dtype=float).reshape(-1, 2))
    rows, cols = rows[valid], cols[valid]
    for dr in range(-size, size + 1):
        for dc in range(-size, size + 1):
            r = np.clip(rows + dr, 0, image.shape[0] - 1)
            c = np.clip(cols + dc, 0, image.shape[1] - 1)
            image[r, c] = color


def draw_robot(image: np.ndarray, occupancy: OccupancyGrid, pose: np.ndarray, radius: float, color) -> None:
    angles = np.linspace(0, 2 * np.pi, 48)
    disc = np.stack([pose[0] + radius * np.cos(angles), pose[1] + radius * np.sin(angles)], axis=1)
    plot_points(image, occupancy, disc, color)
    ray = pose[:2] + np.linspace(0, 2 * radius, 20)[:, None] * np.array([np.cos(pose[2]), np.sin(pose[2])])
    plot_points(image, occupancy, ray, color)


def draw_top_down(
    occupancy: OccupancyGrid,
    pose: np.ndarray,
    cloud: np.ndarray,
    labels: np.ndarray,
    scan: np.ndarray,
    scan_angles: np.ndarray,
    scan_max_range: float,
    robot_radius: float,
    boxes: np.ndarray | None = None,
) -> np.ndarray:
    """The map with the 3D cloud (sensor frame, ``labels`` -1 where no return) coloured by class, the 2D scan
    (ranges at ``scan_angles`` in the robot frame) in red, the robot at ``pose`` in blue, and ``boxes`` (rows
    of x, y, yaw, length, width, height: walkers and unmapped furniture) filled in orange."""
    image = map_image(occupancy)
    x, y, theta = pose
    c, s = np.cos(theta), np.sin(theta)
    returned = labels >= 0
    points, classes = cloud[returned], labels[returned]
    world_xy = np.stack([x + c * points[:, 0] - s * points[:, 1], y + s * points[:, 0] + c * points[:, 1]], axis=1)
    for label, color in enumerate(CLASS_COLORS):
        if label != 2:  # the floor would cover everything
            plot_points(image, occupancy, world_xy[classes == label], color)
    angles = scan_angles + theta
    hit = scan < scan_max_range
    ends = np.stack([x + scan * np.cos(angles), y + scan * np.sin(angles)], axis=1)[hit]
    plot_points(image, occupancy, ends, (255, 0, 0), size=1)
    for bx, by, yaw, length, width, _ in boxes if boxes is not None else []:
        u, v = np.meshgrid(np.linspace(-0.5, 0.5, 8) * length, np.linspace(-0.5, 0.5, 6) * width)
        cy, sy = np.cos(yaw), np.sin(yaw)
        inside = np.stack([bx + cy * u.ravel() - sy * v.ravel(), by + sy * u.ravel() + cy * v.ravel()], axis=1)
        plot_points(image, occupancy, inside, (255, 140, 0), size=1)
    draw_robot(image, occupancy, pose, robot_radius, (30, 60, 230))
    return np.ascontiguousarray(np.flipud(image))
