"""Generated evaluation routes for any world: shortest paths through free space that keep their clearance.

A route starts at a random place of the largest region the robot can reach with ``clearance_m`` to every
obstacle, and strings together shortest paths (Dijkstra on a coarse 8-connected grid, each step's cost
raised near obstacles so that paths keep to the middle of corridors) to goals drawn far from the places
visited so far, so that it crosses the building rather than circling one room, until it is
``min_length_m``-``max_length_m`` long. The path is then thinned to waypoints whose straight segments keep
the clearance.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse.csgraph import dijkstra

from pimm_env.errors import NoFreeRegionError, RoutePlanningError
from pimm_env.mapping.free_graph import FreeGraph, free_graph, path_nodes
from pimm_env.mapping.occupancy import OccupancyGrid
from pimm_env.world.grid import GridSpec
from pimm_env.world.polyline import douglas_peucker


@dataclass(frozen=True)
class RouteConfig:
    count: int = 4
    clearance_m: float = 0.5  # from every obstacle and unknown cell, along the whole route
    min_length_m: float = 30.0
    max_length_m: float = 80.0
    step_m: float = 0.2  # planning grid
    min_leg_m: float = 6.0  # goals lie at least this far (along paths) from the current place
    speed: float = 0.5  # m/s, as the thesis's area_a


def _length(xy: np.ndarray) -> float:
    return float(np.hypot(*np.diff(xy, axis=0).T).sum()) if len(xy) > 1 else 0.0


def _clear(occupancy_clearance, grid, a: np.ndarray, b: np.ndarray, least: float) -> bool:
    samples = a + np.linspace(0, 1, max(2, int(np.hypot(*(b - a)) / (grid.resolution / 2)) + 1))[:, None] * (b - a)
    rows, cols, valid = grid.cells_of(samples)
    return bool(valid.all() and (occupancy_clearance[rows, cols] >= least).all())


def thin(
    points: np.ndarray, grid: GridSpec, clearance: np.ndarray, least: float, tolerance: float = 0.25
) -> np.ndarray:
    """Douglas-Peucker on the path: a stretch becomes one segment when no point of it lies farther than
    ``tolerance`` from that segment and the segment keeps ``least`` clearance (``clearance``: metres per cell)."""
    kept = douglas_peucker(points, tolerance, lambda i, j: _clear(clearance, grid, points[i], points[j], least))
    return points[kept]


def _plan_route(
    graph: FreeGraph, occupancy: OccupancyGrid, config: RouteConfig, rng: np.random.Generator
) -> np.ndarray:
    """Waypoints (K, 2) of one route from a random place (see the module docstring)."""
    target = rng.uniform(config.min_length_m, config.max_length_m)
    return _route_from(graph, occupancy, config, rng, int(rng.integers(len(graph.xy))), target)


def plan_route_from(
    graph: FreeGraph, occupancy: OccupancyGrid, config: RouteConfig, rng: np.random.Generator, node: int
) -> np.ndarray:
    """Waypoints (K, 2) of one route from ``graph``'s ``node`` (as the routes are planned)."""
    target = rng.uniform(config.min_length_m, config.max_length_m)
    return _route_from(graph, occupancy, config, rng, node, target)


def _route_from(
    graph: FreeGraph,
    occupancy: OccupancyGrid,
    config: RouteConfig,
    rng: np.random.Generator,
    current: int,
    target: float,
) -> np.ndarray:
    visited = [current]
    route = [current]
    length = 0.0
    for _ in range(100):
        if length >= target:
            waypoints = _waypoints(graph.xy[route], graph, occupancy, config)
            if _length(waypoints) >= config.min_length_m:
                return waypoints
            target = length + 1.5 * (config.min_length_m - _length(waypoints))  # thinning cut corners: go on
        costs, predecessors = dijkstra(graph.matrix, indices=current, return_predecessors=True)
        far = np.min(np.hypot(*(graph.xy[:, None, :] - graph.xy[visited][None, :, :]).transpose(2, 0, 1)), axis=1)
        reachable = np.isfinite(costs) & (costs >= config.min_leg_m)
        if not reachable.any():
            reachable = np.isfinite(costs) & (costs > 0)
        if not reachable.any():
            raise RoutePlanningError(f"the free region around {graph.xy[current].round(2)} is too small for a route")
        weights = np.where(reachable, far + 1e-3, 0.0) ** 2
        goal = int(rng.choice(len(weights), p=weights / weights.sum()))
        leg = path_nodes(predecessors, goal)[1:]
        route += leg
        length += _length(graph.xy[[current, *leg]])
        visited.append(goal)
        current = goal
    raise RoutePlanningError(f"no route of {config.min_length_m} m found in 100 legs")


def _waypoints(xy: np.ndarray, graph: FreeGraph, occupancy: OccupancyGrid, config: RouteConfig) -> np.ndarray:
    along = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))])
    least = config.clearance_m - 0.5 * config.step_m
    return thin(xy[along <= config.max_length_m], occupancy.grid, graph.cell_clearance, least)


def plan_routes(occupancy: OccupancyGrid, config: RouteConfig, seed: int) -> list[np.ndarray]:
    """``config.count`` routes, reproducible for one seed."""
    rng = np.random.default_rng(seed)
    try:  # built once: the free space is the same for every route
        graph = free_graph(occupancy, config.clearance_m, config.step_m)
    except NoFreeRegionError as error:
        raise RoutePlanningError(str(error)) from None
    return [_plan_route(graph, occupancy, config, rng) for _ in range(config.count)]


def scenarios_document(world_name: str, routes: list[np.ndarray], config: RouteConfig, seed: int) -> str:
    """``scenarios.yaml`` text: ``route_1`` ... and ``route_1_kidnap`` (route 1, then kidnapped to its start)."""
    lines = [
        f"# Generated by `evaluate.py world prepare` (seed {seed}): {len(routes)} routes of "
        f"{config.min_length_m:.0f}-{config.max_length_m:.0f} m keeping {config.clearance_m} m clearance.",
        "format: pimm-scenarios/1",
        f"world: {world_name}",
        "scenarios:",
    ]
    for k, waypoints in enumerate(routes, start=1):
        heading = float(np.arctan2(*(waypoints[1] - waypoints[0])[::-1]))
        points = ", ".join(f"[{x:.2f}, {y:.2f}]" for x, y in waypoints)
        lines += [
            f"  route_{k}:",
            f"    description: generated route {k}, {_length(waypoints):.1f} m",
            f"    start: [{waypoints[0][0]:.2f}, {waypoints[0][1]:.2f}, {heading:.4f}]",
            f"    waypoints: [{points}]",
            f"    speed: {config.speed}",
        ]
    start = routes[0][0]
    heading = float(np.arctan2(*(routes[0][1] - routes[0][0])[::-1]))
    lines += [
        "  route_1_kidnap:",
        "    description: route 1, then kidnapped back to its start and driven again (as a_c_b_kidnap)",
        "    base: route_1",
        f"    kidnap_to: [{start[0]:.2f}, {start[1]:.2f}, {heading:.4f}]",
    ]
    return "\n".join(lines) + "\n"
