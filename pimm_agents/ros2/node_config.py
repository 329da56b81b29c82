"""The localization node's parameters, in nav2's params-file shape.

A nav2 params file holds one section per node, ``NODE: {ros__parameters: {...}}``. The node's own parameters
are nav2 AMCL's where AMCL has one (same name, same default, so an ``amcl:`` section's frames and topics carry
over); every other key of the section is the localizer's own settings, nested as in ``--params``
(``pimm: {filter: {...}}`` becomes ``filter: {...}`` here).
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

from pimm_env.errors import Ros2Error


@dataclass(frozen=True)
class NodeConfig:
    """Defaults: nav2 AMCL's (frames, topics, ``transform_tolerance``, ``tf_broadcast``), else as said."""

    global_frame_id: str = "map"  # nav2
    odom_frame_id: str = "odom"  # nav2
    base_frame_id: str = "base_link"  # nav2
    scan_topic: str = "scan"  # nav2
    points_topic: str = "points"  # the 3D cloud; ROS 2 drivers' common name
    pose_topic: str = "amcl_pose"  # nav2's name, so that its consumers need no remap
    transform_tolerance: float = 1.0  # nav2: how far map -> odom is future-dated (s)
    tf_broadcast: bool = True  # nav2
    use_sim_time: bool = False  # ROS 2: stamps from /clock when the robot is simulated
    #: where odometry comes from: "tf" (odom -> base_link on /tf, as nav2 AMCL reads it) or "topic" (/odom)
    odom_source: str = "tf"
    odom_topic: str = "odom"
    set_initial_pose: bool = False  # nav2: start from ``initial_pose`` instead of a global search
    initial_pose: dict[str, float] = field(default_factory=lambda: {"x": 0.0, "y": 0.0, "z": 0.0, "yaw": 0.0})
    publish_map: bool = False  # the world's occupancy grid on /map (transient local), for RViz without map_server
    #: how long to wait for the LiDAR's mount on /tf_static after the first cloud before using the sensors
    #: preset's (s); a mount never published is said in the status
    mount_wait: float = 2.0
    seed: int = 0  # the localizer's random draws (reset(seed=...))

    def __post_init__(self) -> None:
        if self.odom_source not in ("tf", "topic"):
            raise Ros2Error(f"odom_source {self.odom_source!r}: expected 'tf' or 'topic'")
        if not self.transform_tolerance >= 0:
            raise Ros2Error(f"transform_tolerance must be >= 0 s, got {self.transform_tolerance}")
        if not self.mount_wait >= 0:
            raise Ros2Error(f"mount_wait must be >= 0 s, got {self.mount_wait}")
        for name in ("global_frame_id", "odom_frame_id", "base_frame_id", "scan_topic", "points_topic"):
            if not getattr(self, name):
                raise Ros2Error(f"{name} must not be empty")


def read_node_params(path: Path | None, node: str) -> tuple[NodeConfig, dict[str, Any]]:
    """(the node's parameters, the localizer's settings) from the ``node`` section of a nav2 params file
    (None: defaults and no settings). A file without that section is an error naming the sections it has."""
    if path is None:
        return NodeConfig(), {}
    from pimm_env.yaml_file import read_yaml_mapping

    document = read_yaml_mapping(Path(path), "nav2 params file", Ros2Error)
    if node not in document:
        raise Ros2Error(f"{path}: no section {node!r} (sections: {sorted(document)}); nav2's shape is "
                        "NODE: {ros__parameters: ...}")  # fmt: skip
    section = document[node] or {}
    params = section.get("ros__parameters", section) if isinstance(section, dict) else None
    if not isinstance(params, dict):
        raise Ros2Error(f"{path}: {node}.ros__parameters must be a mapping, got {type(params).__name__}")
    own = {f.name for f in fields(NodeConfig)}
    try:
        config = NodeConfig(**{k: v for k, v in params.items() if k in own})
    except TypeError as error:
        raise Ros2Error(f"{path}: {node}: {error}") from None
    return config, {k: v for k, v in params.items() if k not in own}
