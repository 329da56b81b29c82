"""How long the node takes from a cloud's arrival to the pose's publication, with a simulated robot beside it.

``sim-robot`` runs in a process of its own (as on a robot, where the drivers are other processes), in a ROS 2
domain of this measurement's own on loopback, so that nothing reaches a robot's stack that may be running; the
node runs in this process for ``seconds`` of wall time.
"""

from __future__ import annotations

import os
from typing import Any


def measurement_domain() -> int:
    """A domain id no other stack on this computer is likely to use (ROS 2 allows 0-232)."""
    return 200 + os.getpid() % 30


def node_latency(localizer: str = "pimm", scenario: str = "area_a", seconds: float = 30.0) -> dict[str, Any]:
    """The node's report (``LocalizationNode.report``: updates, skipped clouds, update times, latencies) for
    ``localizer`` while ``sim-robot`` drives ``scenario`` of the iiLab at real time for ``seconds``."""
    import multiprocessing

    from pimm_agents.ros2.run import run_node
    from pimm_env.ros2.sim_robot import run_sim_robot

    domain = measurement_domain()
    robot = multiprocessing.get_context("spawn").Process(
        target=run_sim_robot, kwargs={"scenario": scenario, "domain": domain}, daemon=True
    )
    robot.start()
    try:
        return run_node("iilab", localizer, seconds=seconds, domain=domain)
    finally:
        robot.terminate()
        robot.join(timeout=10)
        if robot.is_alive():
            robot.kill()
            robot.join(timeout=5)
