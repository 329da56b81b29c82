"""Waypoint rollouts: drive a scenario's path with pure pursuit and measure length, time and odometry drift."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import gymnasium as gym
import numpy as np

from pimm_env.driving.controller import PurePursuit, PursuitConfig
from pimm_env.driving.scenarios import Scenario
from pimm_env.envs.base_env import LidarRobotEnv, SimConfig
from pimm_env.errors import EnvError
from pimm_env.geometry import compose
from pimm_env.world.model import World
from pimm_env.world.polyline import nearest_on_path

StepCallback = Callable[[dict[str, np.ndarray], dict[str, Any]], None]


@dataclass
class RolloutResult:
    scenario: str
    length_m: float  # distance the robot travelled (ground truth)
    duration_s: float  # sim time
    wall_s: float  # real time it took
    final_drift_m: float  # odometry position error at the end, map frame
    drift_percent: float  # final drift as a share of the distance travelled
    collided: bool
    completed: bool
    true_path: np.ndarray = field(repr=False)  # (T, 3)
    odom_path: np.ndarray = field(repr=False)  # (T, 3), odometry mapped into the map frame at the start

    @property
    def realtime_factor(self) -> float:
        return self.duration_s / max(self.wall_s, 1e-9)


def odom_to_map(odom: np.ndarray, start: np.ndarray) -> np.ndarray:
    """Express odometry poses (N, 3) in the map frame, given the true pose where odometry started."""
    return compose(start, odom)


def _simulator(env: LidarRobotEnv | gym.Wrapper) -> LidarRobotEnv:
    base = env.unwrapped
    if not isinstance(base, LidarRobotEnv):
        raise EnvError(f"rollouts drive a PIMM simulator env, got {type(base).__name__}")
    return base


def rest_of_route(waypoints: np.ndarray, pose: np.ndarray) -> np.ndarray:
    """The route from the point nearest ``pose`` (on its nearest segment) to its end."""
    path = np.asarray(waypoints, dtype=float).reshape(-1, 2)
    j, point, _ = nearest_on_path(path, np.asarray(pose, dtype=float))
    return np.vstack([point, path[j + 1 :]])


def drive(
    env: LidarRobotEnv | gym.Wrapper,
    waypoints: np.ndarray,
    speed: float,
    on_step: StepCallback | None = None,
    max_steps: int = 20_000,
) -> tuple[bool, bool, list[np.ndarray], list[np.ndarray]]:
    """Follow ``waypoints`` from the env's current pose; returns (completed, collided, true poses, odometry)."""
    controller = PurePursuit(waypoints, PursuitConfig(speed=speed))
    true_poses, odoms = [], []
    pose = _simulator(env).robot.pose
    for _ in range(max_steps):
        obs, _, terminated, truncated, info = env.step(np.array(controller.command(pose), dtype=np.float32))
        pose = info["true_pose"]
        true_poses.append(pose)
        odoms.append(np.asarray(obs["odom"], dtype=float))
        if on_step is not None:
            on_step(obs, info)
        if info.get("kidnapped"):  # a fault teleported the robot: drive on from there (its own route, or one given)
            path = info["route"] if "route" in info else rest_of_route(waypoints, pose)
            controller = PurePursuit(path, PursuitConfig(speed=speed))
        if info["collision"]:
            return False, True, true_poses, odoms
        if controller.done:
            return True, False, true_poses, odoms
        if terminated or truncated:
            break
    return False, False, true_poses, odoms


def run(
    scenario: Scenario,
    world: str | World = "iilab",
    seed: int = 0,
    lidar3d: bool = True,
    on_step: StepCallback | None = None,
    env: LidarRobotEnv | gym.Wrapper | None = None,
) -> RolloutResult:
    """Roll out ``scenario`` in a fresh env (or ``env``); kidnap scenarios drive the path twice."""
    import time

    own_env = env is None
    if env is None:
        config = SimConfig()
        if not lidar3d:  # for fast odometry and path checks
            config = replace(config, lidar3d=replace(config.lidar3d, enabled=False))
        from pimm_env.envs.iilab_env import IILabEnv

        env = IILabEnv(world=world, config=config, terminate_on_collision=False)
    start_wall = time.perf_counter()
    try:
        obs, info = env.reset(seed=seed, options={"pose": scenario.start})
        if on_step is not None:
            on_step(obs, info)
        completed, collided, true_poses, odoms = drive(env, scenario.waypoints, scenario.speed, on_step)
        if scenario.kidnap_to is not None and completed:
            obs, info = env.reset(options={"kidnap": scenario.kidnap_to})
            if on_step is not None:
                on_step(obs, info)
            completed, collided, more_true, more_odom = drive(env, scenario.waypoints, scenario.speed, on_step)
            true_poses += more_true
            odoms += more_odom
        duration = float(_simulator(env).sim_time)
        travelled = float(_simulator(env).robot.travelled)
    finally:
        if own_env:
            env.close()
    true_path = np.array(true_poses)
    odom_path = odom_to_map(np.array(odoms), scenario.start)
    drift = float(np.linalg.norm(true_path[-1, :2] - odom_path[-1, :2]))
    if scenario.kidnap_to is not None:  # odometry knows nothing of the teleport: drift is meaningless
        drift = float("nan")
    return RolloutResult(
        scenario=scenario.name,
        length_m=travelled,
        duration_s=duration,
        wall_s=time.perf_counter() - start_wall,
        final_drift_m=drift,
        drift_percent=100 * drift / max(travelled, 1e-9),
        collided=collided,
        completed=completed,
        true_path=true_path,
        odom_path=odom_path,
    )


def rollout_row(result: RolloutResult, scenario: Scenario) -> dict[str, Any]:
    """One rollout as ``rollouts.json`` keeps it, beside the thesis's length and duration of the scenario."""
    laps = 2 if scenario.kidnap_to is not None else 1

    def finite(value: float, digits: int) -> float | None:
        return None if not np.isfinite(value) else round(value, digits)

    return {
        "length_m": round(result.length_m, 3),
        "path_length_m": round(scenario.length * laps, 3),
        "thesis_length_m": scenario.thesis_length_m,
        "duration_s": round(result.duration_s, 2),
        "thesis_duration_s": scenario.thesis_duration_s,
        "odometry_drift_m": finite(result.final_drift_m, 3),
        "odometry_drift_percent": finite(result.drift_percent, 2),
        "collided": result.collided,
        "completed": result.completed,
        "realtime_factor": round(result.realtime_factor, 2),
    }


def run_scenarios(
    world: str, names: list[str] | None = None, seed: int = 0, progress: bool = True
) -> tuple[list[RolloutResult], dict[str, dict[str, Any]], Any]:
    """Roll out the world's scenarios (all, or ``names``): the results, their ``rollouts.json`` rows and the
    world's occupancy grid (for the figure)."""
    from tqdm import tqdm

    from pimm_env.driving.scenarios import load_scenarios
    from pimm_env.errors import WorldError
    from pimm_env.mapping.derived_maps import ensure_derived_maps
    from pimm_env.world.files import load_world

    loaded = load_world(world)
    occupancy = ensure_derived_maps(loaded).occupancy
    available = load_scenarios(loaded)
    unknown = [s for s in names or () if s not in available]
    if unknown:
        raise WorldError(f"unknown scenario(s) {unknown} in world {world!r}; valid: {', '.join(available)}")
    results = []
    for name in names or list(available):
        scenario = available[name]
        expected_s = scenario.length * (2 if scenario.kidnap_to is not None else 1) / scenario.speed
        with tqdm(total=round(expected_s), desc=name, unit="sim s", disable=not progress, leave=False) as bar:

            def advance(obs: dict, info: dict, bar: tqdm = bar) -> None:
                bar.update(max(0, int(float(obs["time"][0])) - bar.n))

            results.append(run(scenario, world=loaded, seed=seed, on_step=advance))
    return results, {r.scenario: rollout_row(r, available[r.scenario]) for r in results}, occupancy
