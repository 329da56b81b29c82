"""Start a localizer as a ROS 2 node for a world: its maps, its sensors, its params file, until stopped."""

from __future__ import annotations

import tempfile
from dataclasses import replace
from pathlib import Path
from typing import Any

from pimm_agents.ros2.node import LocalizationNode
from pimm_agents.ros2.node_config import read_node_params

NODE_NAME = "pimm_localization"


def run_node(
    world: str,
    localizer: str,
    params: Path | None = None,
    sensors: str = "thesis",
    discovery: str = "localhost",
    seconds: float | None = None,
    name: str = NODE_NAME,
    on_ready: Any = None,
    should_stop: Any = None,
    domain: int | None = None,
) -> dict[str, Any]:
    """Run ``localizer`` for ``world`` as the node ``name`` (its parameters and the localizer's settings from the
    ``name`` section of the nav2 params file ``params``) for ``seconds`` of wall time (None: until Ctrl-C);
    returns what the node did (``LocalizationNode.report``). ``on_ready(node)`` is called once it listens;
    ``domain`` is the ROS 2 domain (None: ``ROS_DOMAIN_ID``)."""
    from pimm_agents.factory import make_localizer
    from pimm_env.mapping.derived_maps import ensure_derived_maps
    from pimm_env.ros2.domain import Domain
    from pimm_env.sim.sensors import sensor_layouts, write_sensors_file
    from pimm_env.world.files import load_world

    config, settings = read_node_params(params, name)
    loaded = load_world(world)
    occupancy = ensure_derived_maps(loaded).occupancy if config.publish_map else None
    lidar3d, lidar2d = sensor_layouts(sensors)
    with tempfile.TemporaryDirectory(prefix="pimm-node-") as folder:

        def make(mount: dict[str, float] | None) -> Any:
            chosen = sensors
            if mount is not None:  # the mount the robot publishes, over the preset's
                note = f"{sensors} with the LiDAR mount read from /tf_static"
                mounted = replace(lidar3d, **mount)  # type: ignore[arg-type]
                chosen = str(write_sensors_file(Path(folder) / "sensors.yaml", mounted, lidar2d, note))
            return make_localizer(localizer, loaded, params=settings, sensors=chosen)

        with Domain(discovery, domain) as dds:
            node = LocalizationNode(make, lidar3d, lidar2d, dds, config, name, occupancy)
            if on_ready is not None:
                on_ready(node)
            try:
                node.spin(seconds, should_stop)
            except KeyboardInterrupt:
                pass
            finally:
                node.close()
            return node.report()
