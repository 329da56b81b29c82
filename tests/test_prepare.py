import itertools

import numpy as np
from scipy import ndimage

from pimm_agents.preparation.prepare import drivable
from pimm_env.driving.routes import RouteConfig, plan_routes
from pimm_env.mapping.derived_maps import ensure_derived_maps
from pimm_env.world.files import load_world
from tests.conftest import ROOM_WORLD

TABLE = "  - {name: table, class: clutter, box: {min: [2.2, 1.4, 0.0], max: [3.0, 2.6, 0.25]}}\n"


def test_routes_keep_their_clearance_from_a_table_below_the_maps_cut(tmp_path):
    folder = tmp_path / "room"
    folder.mkdir()
    (folder / "world.yaml").write_text(ROOM_WORLD + TABLE)
    world = load_world(folder / "world.yaml")
    occupancy = ensure_derived_maps(world).occupancy
    rows, cols, _ = occupancy.grid.cells_of(np.array([[2.6, 2.0]]))
    assert occupancy.free[rows[0], cols[0]]  # the map's cut (0.30 m) passes over the table
    body = drivable(world, occupancy)
    assert not body.free[rows[0], cols[0]] and body.occupied[rows[0], cols[0]]
    config = RouteConfig(count=3, clearance_m=0.3, min_length_m=4.0, max_length_m=30.0, min_leg_m=1.0)
    table_cells = np.zeros(occupancy.grid.shape, dtype=bool)
    gx, gy = occupancy.grid.cell_centers()
    table_cells[(gx > 2.2) & (gx < 3.0) & (gy > 1.4) & (gy < 2.6)] = True
    from_table = ndimage.distance_transform_edt(~table_cells) * occupancy.grid.resolution
    for waypoints in plan_routes(body, config, seed=3):
        for a, b in itertools.pairwise(waypoints):
            samples = a + np.linspace(0, 1, 50)[:, None] * (b - a)
            r, c, valid = occupancy.grid.cells_of(samples)
            assert valid.all() and from_table[r, c].min() >= config.clearance_m - config.step_m


def test_describe_warns_when_the_corner_map_is_thin():
    from pathlib import Path

    from pimm_agents.preparation.prepare import Preparation, describe

    thin = Preparation(
        "w",
        Path("maps/w"),
        corners=3,
        free_m2=400.0,
        fingerprints=10,
        scenarios=["route_1"],
        routes_written=False,
        seconds={"maps": 0.1},
    )
    assert describe(thin).startswith("warning: 3 corners over 400 m^2 (0.8 per 100 m^2")
    assert "--ceiling-height" not in describe(thin)  # it has a ceiling: the advice fits what was given
    from dataclasses import replace

    assert "the world has no ceiling: give --ceiling-height" in describe(replace(thin, has_ceiling=False))
    assert "warning" not in describe(Preparation("w", Path("maps/w"), 40, 400.0, 10, ["route_1"], False, {}))
