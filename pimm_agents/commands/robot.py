"""PIMM on a robot: the localization node (nav2's interface over ROS 2 DDS) and the simulator as a ROS 2 robot.

Commands of ``evaluate.py``; each imports what it needs inside (``--help`` stays instant)."""

from __future__ import annotations

import json
from pathlib import Path

import typer

from pimm_agents.command_line import command
from pimm_agents.commands.options import JSON, SENSORS, WORLD

app = typer.Typer(add_completion=False)


def _stop_on_sigterm() -> None:
    """SIGTERM (a launch file or a supervisor stopping the process) ends it as Ctrl-C does: cleanly, with its
    report printed and its DDS participant closed."""
    import signal

    def interrupt(signum, frame):
        raise KeyboardInterrupt

    signal.signal(signal.SIGTERM, interrupt)


DISCOVERY = typer.Option(
    "localhost", help="localhost (this computer only, loopback) or subnet (CYCLONEDDS_URI's, or Cyclone's defaults)"
)


@command(app)
def node(
    world: str = WORLD,
    localizer: str = typer.Option("pimm", help="pimm, amcl, amcl-recovery, registration, ... or module:factory"),
    params: Path | None = typer.Option(None, "--params", help="nav2 params file: NODE_NAME: {ros__parameters: ...}"),
    sensors: str = SENSORS,
    name: str = typer.Option("pimm_localization", help="the ROS 2 node name (and the params file's section)"),
    discovery: str = DISCOVERY,
    seconds: float | None = typer.Option(None, min=0, help="stop after this many seconds (default: Ctrl-C)"),
    json_out: bool = JSON,
) -> None:
    """A localizer as a ROS 2 node speaking nav2 AMCL's interface (ROS_DOMAIN_ID; docs/robot.md)."""
    from pimm_agents.ros2.run import run_node

    def ready(started) -> None:
        if not json_out:
            typer.echo(f"{name}: {localizer} in {world}, domain listening ({discovery}); Ctrl-C to stop", err=True)

    _stop_on_sigterm()
    report = run_node(world, localizer, params, sensors, discovery, seconds, name, ready)
    typer.echo(json.dumps(report) if json_out else "\n".join(f"{k}: {v}" for k, v in report.items()))


@command(app, "sim-robot")
def sim_robot(
    world: str = WORLD,
    scenario: str | None = typer.Option(None, help="drive this scenario's waypoints (default: follow /cmd_vel)"),
    seed: int = typer.Option(0, help="seed of the simulation's noise"),
    sensors: str = SENSORS,
    speed: float = typer.Option(1.0, min=0.01, help="sim seconds per wall second (1: real time)"),
    seconds: float | None = typer.Option(None, min=0, help="without a scenario: stop after this much sim time"),
    discovery: str = DISCOVERY,
    json_out: bool = JSON,
) -> None:
    """The simulator as a ROS 2 robot: /clock, /tf, /tf_static, /points, /scan, /odom, /ground_truth."""
    from pimm_env.ros2.sim_robot import run_sim_robot

    _stop_on_sigterm()
    done = run_sim_robot(world, scenario, seed, sensors, speed, seconds, discovery)
    typer.echo(json.dumps(done) if json_out else "\n".join(f"{k}: {v}" for k, v in done.items()))
