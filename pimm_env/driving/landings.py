"""Where a kidnapped robot lands when it may land anywhere, and the route it drives from there.

A kidnap onto the robot's own route (``envs/faults.py``) lands in a place the robot has seen or will see, along
corridors. A robot on a real floor is carried into rooms, and the hardest landing is a room that looks like the
one it left. ``Landings.draw`` lands half the time on one of the map's twins of the place left
(``mapping/twins.py``), otherwise on a random place of the free space, both at least ``min_jump_m`` away and on
the free graph the routes are planned on (so that the robot fits there); then plans a route from the landing
(``AFTER_LANDING``) for the driver. In a twin the robot faces at least ``TWIN_TURN_DEG`` away from the twin's
heading: facing as the twin, it would see what it saw before the kidnap, which no localizer can notice until the
two places' surroundings differ; turned, its first scan shows the jump, and the question is which of the
look-alike rooms it is in (the case a kidnap into a row of identical offices poses).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from scipy.spatial import cKDTree

from pimm_env.driving.routes import RouteConfig, plan_route_from
from pimm_env.errors import RoutePlanningError
from pimm_env.geometry import wrap_angle
from pimm_env.mapping.free_graph import free_graph
from pimm_env.mapping.occupancy import OccupancyGrid
from pimm_env.mapping.twins import MapTwins

#: the route driven after a landing: long enough to be localized again and watched for a while (ours)
AFTER_LANDING = RouteConfig(count=1, min_length_m=15.0, max_length_m=25.0)
#: in a twin, the least turn from the twin's heading (see above)
TWIN_TURN_DEG = 45.0


class Landings:
    """Landing places and the routes from them, in one map (``twins``: its twins, a world's table loaded)."""

    def __init__(
        self, occupancy: OccupancyGrid, twins: MapTwins, min_jump_m: float = 5.0, route: RouteConfig = AFTER_LANDING
    ) -> None:
        self.route = replace(route, count=1)
        self.graph = free_graph(occupancy, route.clearance_m, route.step_m)
        self.nodes = cKDTree(self.graph.xy)
        self.occupancy, self.twins, self.min_jump_m = occupancy, twins, min_jump_m

    def draw(self, pose: np.ndarray, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, str]:
        """Landing pose (x, y, heading), the route's waypoints from it, and ``"twin"`` or ``"free"``."""
        xy, pose = self.graph.xy, np.asarray(pose, dtype=float)
        far = np.hypot(*(xy - pose[:2]).T) >= self.min_jump_m
        if not far.any():
            raise RoutePlanningError(f"no free place lies {self.min_jump_m} m from {pose[:2].round(2)}")
        kind, node, heading = "free", -1, 0.0
        if rng.random() < 0.5:
            twins = self.twins.of(pose)
            if len(twins):
                gaps, nearest = self.nodes.query(twins[:, :2])  # each twin's nearest node of the free graph
                usable = np.flatnonzero((gaps <= self.route.step_m) & far[nearest])
                if len(usable):
                    pick = int(rng.choice(usable))
                    turn = np.radians(rng.uniform(TWIN_TURN_DEG, 360.0 - TWIN_TURN_DEG))
                    kind, node, heading = "twin", int(nearest[pick]), float(wrap_angle(twins[pick, 2] + turn))
        if node < 0:
            node = int(rng.choice(np.flatnonzero(far)))
            heading = float(rng.uniform(-np.pi, np.pi))
        waypoints = plan_route_from(self.graph, self.occupancy, self.route, rng, node)
        return np.array([*xy[node], heading]), waypoints, kind
