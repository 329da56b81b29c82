"""A scenario driven by an active-localization policy instead of its waypoints: ``run --driver policy:NAME``.

The robot starts where the scenario starts and, for as long as the route would have taken (its length over its
speed), drives the motion primitives a policy chooses (``random``, ``greedy``, ``trained`` or a ``.zip``,
policies.py) from what the trial's localizer believes: the env stack's ``info["estimate"]`` (the
:class:`~pimm_agents.experiments.recorder.LocalizationRecorder` puts it there), the 2D scan, the odometry and
the map (the guide, guide.py), built into the task env's observation (env.py). A kidnap scenario carries the
robot to its kidnap pose after one such stretch and drives a second. The trial is recorded and scored as a
route's is.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from pimm_env.errors import ExperimentError

ROUTE = "route"
PREFIX = "policy:"


def policy_name(driver: str) -> str | None:
    """The policy of a ``--driver`` value (None for ``route``); anything else raises, naming what is valid."""
    if driver == ROUTE:
        return None
    if driver.startswith(PREFIX) and driver[len(PREFIX) :]:
        return driver[len(PREFIX) :]
    raise ExperimentError(
        f"driver {driver!r}: expected 'route' or 'policy:NAME' (random, greedy, trained or a policy's .zip)"
    )


def drive_with_policy(env: Any, scenario: Any, policy: str, seed: int, on_step: Any = None) -> Any:
    """Roll ``scenario`` out in ``env`` (a simulator env under its recorders) with ``policy`` at the wheel;
    returns a :class:`pimm_env.driving.rollout.RolloutResult`."""
    from pimm_agents.active.env import ActiveConfig, active_observation
    from pimm_agents.active.explorer import Explorer
    from pimm_agents.active.guide import Guide
    from pimm_agents.active.policies import make_policy
    from pimm_agents.active.primitives import PRIMITIVES, drive
    from pimm_env.driving.rollout import RolloutResult, odom_to_map
    from pimm_env.geometry import relative_motion
    from pimm_env.sim.lidar import beam_bearings_2d

    sim = env.unwrapped
    config, max_range = ActiveConfig(), float(sim.config.lidar2d.max_range)
    bearings = beam_bearings_2d(sim.config.lidar2d)
    chosen = make_policy(policy, max_range)
    guide, explorer = Guide(sim.maps.occupancy), Explorer(max_range)
    stretch_s = scenario.length / scenario.speed
    true_poses: list[np.ndarray] = []
    odoms: list[np.ndarray] = []
    collided = False
    estimate = None  # the localizer's latest, as the recorder hands it on
    end_s = stretch_s
    start_wall = time.perf_counter()

    def record(obs: dict[str, np.ndarray], info: dict[str, Any]) -> bool:
        nonlocal collided, estimate
        estimate = info.get("estimate", estimate)
        true_poses.append(np.asarray(info["true_pose"], dtype=float))
        odoms.append(np.asarray(obs["odom"], dtype=float))
        if on_step is not None:
            on_step(obs, info)
        collided = collided or bool(info["collision"])
        return collided or sim.sim_time >= end_s

    obs, info = env.reset(seed=seed, options={"pose": scenario.start})
    record(obs, info)
    true_poses.clear()
    odoms.clear()  # the rollout's paths start after the reset, as a route's do
    for leg in range(2 if scenario.kidnap_to is not None else 1):
        if leg:
            obs, info = env.reset(options={"kidnap": scenario.kidnap_to})
            record(obs, info)
            end_s = sim.sim_time + stretch_s
        # after a kidnap the policy starts afresh, as the guide and the observation's explorer do (and as the
        # task env's policies do at an episode's start, after its kidnap)
        delta, action = np.zeros(3), None
        guide.reset()
        explorer.reset()
        chosen.reset(seed + leg)
        while not collided and sim.sim_time < end_s:
            scan = np.asarray(obs["scan"], dtype=float)
            shown = guide(estimate, scan, bearings, delta)
            action = chosen(active_observation(estimate, scan, delta, config, max_range, shown, explorer, action))
            odom_start = np.asarray(obs["odom"], dtype=float).copy()
            obs, _, _, _ = drive(env, PRIMITIVES[action], obs, record, bearings)
            delta = relative_motion(odom_start, np.asarray(obs["odom"], dtype=float))
        if collided:
            break
    true_path, odom_path = np.array(true_poses), odom_to_map(np.array(odoms), scenario.start)
    travelled = float(sim.robot.travelled)
    return RolloutResult(
        scenario=scenario.name,
        length_m=travelled,
        duration_s=float(sim.sim_time),
        wall_s=time.perf_counter() - start_wall,
        final_drift_m=float("nan"),
        drift_percent=float("nan"),
        collided=collided,
        completed=not collided,
        true_path=true_path,
        odom_path=odom_path,
    )
