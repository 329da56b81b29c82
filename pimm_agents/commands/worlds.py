"""Bring your own building: import a ROS map, a mesh or a Gazebo world, and prepare it.

Commands of ``evaluate.py``; each imports what it needs inside (``--help`` stays instant)."""

from __future__ import annotations

from pathlib import Path

import typer

from pimm_agents.command_line import command

world_app = typer.Typer(add_completion=False, help="Bring your own building: import a ROS map or a mesh, prepare it.")


@command(world_app, "import")
def world_import(
    source: Path = typer.Argument(
        ...,
        help="a map_server .yaml (+ .pgm/.png), a Gazebo world (.world .sdf), a mesh (.obj .ply .stl .glb .dae ...)"
        " or a point-cloud map (.pcd .ply .las .laz .npy)",
    ),
    name: str = typer.Option(..., help="the world's name: it is written to maps/NAME/"),
    ceiling_height: float | None = typer.Option(
        None,
        help="a floor plan's ceiling height (m; default 3); for a mesh or Gazebo world, add a flat ceiling this high",
    ),
    ceilings: Path | None = typer.Option(None, help="YAML of areas with other ceiling heights"),
    furnish: int = typer.Option(0, min=0, help="mapped furniture pieces to add to a floor plan"),
    seed: int = typer.Option(0, help="seed of the furniture, the routes and the fingerprint headings"),
    up_axis: str = typer.Option("z", help="a mesh's up axis: z, or y (the map point of (x, y, z) is (x, -z, y))"),
    rules: Path | None = typer.Option(None, help="YAML list of {match, class} name rules; they win over the defaults"),
    model_path: list[Path] = typer.Option([], help="folders of Gazebo models (model://NAME); also GAZEBO_MODEL_PATH"),
    visual: bool = typer.Option(False, help="a Gazebo world's visual geometry instead of its collision geometry"),
    wall_line: bool = typer.Option(
        True, help="class objects standing in a wall's line (windows, closed doors) wall, whatever their names say"
    ),
    strict: bool = typer.Option(False, help="a Gazebo model or mesh not found stops the import (default: left out)"),
    trajectory: Path | None = typer.Option(
        None,
        help="a point-cloud map's SLAM trajectory (TUM: t x y z qx qy qz qw, the map's frame): clutter where it drove"
        " is set aside as ghosts",
    ),
    routes: int = typer.Option(4, min=1, help="routes to generate"),
    maps_dir: Path | None = typer.Option(None, help="where worlds live (default: the project's maps/)"),
    prepare: bool = typer.Option(True, help="also prepare the world (maps, fingerprints, routes)"),
) -> None:
    """Write maps/NAME/world.yaml from a ROS map, a mesh or a Gazebo world, then prepare it."""
    import shutil

    from pimm_env.importers.mesh_checks import describe_world
    from pimm_env.importers.world_import import import_world, read_rules
    from pimm_env.world.files import MAPS_DIR, load_world

    folder = (maps_dir or MAPS_DIR) / name
    existed = folder.exists()
    path = import_world(
        source,
        name,
        maps_dir or MAPS_DIR,
        ceiling_height,
        ceilings,
        furnish,
        seed,
        rules=read_rules(rules) if rules else None,
        up_axis=up_axis,
        model_paths=model_path,
        geometry="visual" if visual else "collision",
        wall_line=wall_line,
        strict=strict,
        trajectory=trajectory,
    )
    typer.echo(f"wrote {path}\n{describe_world(load_world(path))}")
    if prepare:
        try:
            world_prepare(name=str(path), routes=routes, seed=seed, spacing=0.5, new_routes=True)
        except BaseException:
            if not existed:
                shutil.rmtree(folder, ignore_errors=True)
            raise


@command(world_app, "prepare")
def world_prepare(
    name: str = typer.Argument(..., help="world name under maps/ or a world file"),
    routes: int = typer.Option(4, min=1, help="routes to generate when the world has no scenarios.yaml"),
    seed: int = typer.Option(0, help="seed of the routes and the fingerprint headings"),
    spacing: float = typer.Option(0.5, min=0.1, help="fingerprint grid spacing (m)"),
    new_routes: bool = typer.Option(False, help="replace an existing scenarios.yaml with generated routes"),
) -> None:
    """Rebuild a world's derived maps and fingerprint map; generate routes if it has no scenarios."""
    from pimm_agents.preparation.prepare import describe, prepare_world
    from pimm_env.driving.routes import RouteConfig

    typer.echo(describe(prepare_world(name, RouteConfig(count=routes), seed, spacing, new_routes)))
