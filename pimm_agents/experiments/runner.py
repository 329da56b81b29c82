"""Run localizers on scenarios: one simulation per trial feeds every localizer asked for; trials run across
worker processes.

The robot's path does not depend on the localizer (the controller drives on the true pose), so a trial is
simulated once and the same observations go to each localizer, each seeded with the trial's seed. The
results equal separate runs with the same seeds: every LiDAR draws its noise from its own stream, so that
a simulation that casts the 3D cloud for one localizer gives the others the same odometry and 2D scans.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import replace
from typing import Any

from pimm_agents.experiments.engines import run_jobs
from pimm_agents.scoring.trial import TrialResult, TrialSpec, metrics_of
from pimm_env.errors import ExperimentError


def run_trial(spec: TrialSpec) -> TrialResult:
    """One localizer on one trial (a simulation of its own)."""
    return run_shared([spec])[0]


#: Called after every env step of a shared trial with its localizers (in the order of the specs), the
#: observation and the info (whose ``estimate`` is the last localizer's): for replays and figures.
Watcher = Callable[[Sequence[Any], dict[str, Any], dict[str, Any]], None]


def run_shared(specs: Sequence[TrialSpec], watch: Watcher | None = None) -> list[TrialResult]:
    """Simulate the trial once and feed it to every spec's localizer; seeds the env and each localizer with
    the trial's seed. All specs must share ``TrialSpec.simulation``."""
    from pimm_agents.experiments.recorder import LocalizationRecorder
    from pimm_agents.factory import make_localizer
    from pimm_env.driving.rollout import run
    from pimm_env.driving.scenarios import get_scenario
    from pimm_env.envs.base_env import SimConfig
    from pimm_env.envs.iilab_env import IILabEnv
    from pimm_env.world.files import load_world

    if not specs:
        return []
    shared = {spec.simulation for spec in specs}
    if len(shared) != 1:
        raise ExperimentError(f"specs simulate different trials {sorted(shared)}: group them by TrialSpec.simulation")
    first = specs[0]
    start = time.perf_counter()
    world = load_world(first.world)  # read once, passed to everything below
    scenario = get_scenario(first.scenario, world)
    from pimm_env.envs.sim_config import with_sensors

    maps = {name: load_world(name) for name in {spec.maps for spec in specs} if name}  # maps made another way
    localizers = [
        make_localizer(spec.localizer, maps.get(spec.maps, world), params=spec.params, sensors=spec.sensors)
        for spec in specs
    ]
    config = replace(with_sensors(SimConfig(), first.sensors), walkers=first.walkers, unmapped=first.unmapped)
    if not any("cloud" in getattr(loc, "sensors", ("cloud",)) for loc in localizers):
        config = replace(config, lidar3d=replace(config.lidar3d, enabled=False))  # nobody reads it: skip 14 400 rays
    recorders = []
    env: Any = IILabEnv(world=world, config=config, terminate_on_collision=False)
    if first.faults:
        from pimm_env.envs.faults import parse_faults, with_faults

        env = with_faults(env, parse_faults(first.faults), route=scenario.waypoints)
    for spec, localizer in zip(specs, localizers, strict=True):
        env = LocalizationRecorder(env, localizer, spec.start)
        recorders.append(env)
    on_step = None if watch is None else (lambda obs, info: watch(localizers, obs, info))
    try:
        if first.driver == "route":
            rollout = run(scenario, seed=first.seed, env=env, on_step=on_step)
        else:  # one spec (TrialSpec.simulation): its localizer's recorder is the outermost wrapper
            from pimm_agents.active.driver import drive_with_policy, policy_name

            rollout = drive_with_policy(env, scenario, str(policy_name(first.driver)), first.seed, on_step)
        logs = [recorder.trial_log() for recorder in recorders]
    finally:
        env.close()
    wall = time.perf_counter() - start
    return [
        TrialResult(spec, log, metrics_of(log), wall, rollout.completed, rollout.collided)
        for spec, log in zip(specs, logs, strict=True)
    ]


def group_by_simulation(specs: Sequence[TrialSpec]) -> list[list[int]]:
    """Indices of ``specs`` grouped by the simulation they share, in order of first appearance."""
    groups: dict[tuple[Any, ...], list[int]] = {}
    for i, spec in enumerate(specs):
        groups.setdefault(spec.simulation, []).append(i)
    return list(groups.values())


def run_trials(
    specs: Sequence[TrialSpec],
    workers: int = 1,
    on_done: Callable[[TrialResult], None] | None = None,
    backend: str = "local",
    address: str | None = None,
) -> list[TrialResult]:
    """All trials, one simulation per group of specs that share it, in ``workers`` local processes (1: in this
    one) or as Ray tasks (``backend="ray"``: a local Ray with ``workers`` CPUs, or the cluster at ``address``);
    ``on_done`` sees each result as its simulation finishes; results come back in the order of ``specs``."""
    groups = group_by_simulation(specs)
    results: dict[int, TrialResult] = {}

    def finish(group: int, done: list[TrialResult]) -> None:
        for i, result in zip(groups[group], done, strict=True):
            results[i] = result
            if on_done:
                on_done(result)

    run_jobs(run_shared, [[specs[i] for i in indices] for indices in groups], workers, backend, address, finish)
    return [results[i] for i in range(len(specs))]
