"""``python -m pimm_env.mapping WORLD...``: rebuild worlds' occupancy grids and corner maps."""

from __future__ import annotations

import argparse

from pimm_env.mapping.derived_maps import build_derived_maps
from pimm_env.world.files import load_world, world_dir


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description="Rebuild a world's occupancy grid and corner map.")
    parser.add_argument("worlds", nargs="*", default=["iilab"], help="world names or world files")
    args = parser.parse_args(argv)
    for name in args.worlds:
        world = load_world(name)
        maps = build_derived_maps(world)
        occ = maps.occupancy
        print(
            f"{world.name}: occupancy {occ.grid.shape[1]}x{occ.grid.shape[0]} cells at {occ.grid.resolution} m "
            f"({occ.occupied.sum()} occupied, {occ.free.sum()} free), {len(maps.corners)} corners "
            f"-> {world_dir(world)}"
        )


if __name__ == "__main__":
    main()
