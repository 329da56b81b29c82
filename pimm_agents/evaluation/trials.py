"""Run localizers on scenarios: one simulation per trial feeds every localizer asked for; trials run across
worker processes.

The robot's path does not depend on the localizer (the controller drives on the true pose), so a trial is
simulated once and the same observations go to each localizer, each seeded with the trial's seed. The
results equal separate runs with the same seeds: every LiDAR draws its noise from its own stream, so that
a simulation that casts the 3D cloud for one localizer gives the others the same odometry and 2D scans.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass, field, replace
from typing import Any

from pimm_agents.evaluation.metrics import TrialMetrics, trial_metrics
from pimm_agents.evaluation.trial_log import TrialLog


@dataclass(frozen=True)
class TrialSpec:
    scenario: str
    localizer: str
    trial: int
    seed: int
    world: str = "iilab"
    params: dict[str, Any] = field(default_factory=dict)  # the localizer's params-file section
    sensors: str = "thesis"  # LiDAR presets (pimm_env.sim.sensors)
    start: str = "global"  # or "known": the true start pose with nav2's covariance (recorder.STARTS)
    label: str = ""  # how reports name the localizer (a sweep's "amcl[max_particles=500]"); default its name
    row: str = ""  # how reports name the scenario (a sweep over worlds: "gen-900/route_1"); default its name
    faults: str = ""  # pimm_env.envs.faults.parse_faults's form, e.g. "dropout@30:5,kidnap@60"
    walkers: int = 0  # people walking about (pimm_env/sim/movers.py)
    unmapped: int = 0  # furniture the maps do not have

    @property
    def name(self) -> str:
        return self.label or self.localizer

    @property
    def case(self) -> str:
        return self.row or self.scenario

    @property
    def simulation(self) -> tuple[str, str, int, int, str, str, int, int]:
        """What the simulated stream depends on; specs that share it share one simulation."""
        return (
            self.world,
            self.scenario,
            self.trial,
            self.seed,
            self.sensors,
            self.faults,
            self.walkers,
            self.unmapped,
        )


@dataclass
class TrialResult:
    spec: TrialSpec
    log: TrialLog
    metrics: TrialMetrics  # for kidnap scenarios: measured from the kidnap on
    wall_s: float  # the shared simulation's wall time, with every localizer it fed
    completed: bool


def metrics_of(log: TrialLog) -> TrialMetrics:
    """The thesis's metrics of one trial; a kidnap trial counts from the kidnap on."""
    return trial_metrics(log.after_kidnap())


def run_trial(spec: TrialSpec) -> TrialResult:
    """One localizer on one trial (a simulation of its own)."""
    return run_shared([spec])[0]


#: Called after every env step of a shared trial with its localizers (in the order of the specs), the
#: observation and the info (whose ``estimate`` is the last localizer's): for replays and figures.
Watcher = Callable[[Sequence[Any], dict[str, Any], dict[str, Any]], None]


def run_shared(specs: Sequence[TrialSpec], watch: Watcher | None = None) -> list[TrialResult]:
    """Simulate the trial once and feed it to every spec's localizer; seeds the env and each localizer with
    the trial's seed. All specs must share ``TrialSpec.simulation``."""
    from pimm_agents.evaluation.recorder import LocalizationRecorder
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
        raise ValueError(f"specs simulate different trials {sorted(shared)}: group them by TrialSpec.simulation")
    first = specs[0]
    start = time.perf_counter()
    world = load_world(first.world)  # read once, passed to everything below
    scenario = get_scenario(first.scenario, world)
    from pimm_env.envs.base_env import with_sensors

    localizers = [make_localizer(spec.localizer, world, params=spec.params, sensors=spec.sensors) for spec in specs]
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
        rollout = run(scenario, seed=first.seed, env=env, on_step=on_step)
        logs = [recorder.trial_log() for recorder in recorders]
    finally:
        env.close()
    wall = time.perf_counter() - start
    return [
        TrialResult(spec, log, metrics_of(log), wall, rollout.completed) for spec, log in zip(specs, logs, strict=True)
    ]


def group_by_simulation(specs: Sequence[TrialSpec]) -> list[list[int]]:
    """Indices of ``specs`` grouped by the simulation they share, in order of first appearance."""
    groups: dict[tuple[str, str, int, int, str, str, int, int], list[int]] = {}
    for i, spec in enumerate(specs):
        groups.setdefault(spec.simulation, []).append(i)
    return list(groups.values())


def _limit_threads(threads: int) -> None:
    """Keep each worker's torch to its share of the cores: oversubscribed threads slow every worker down."""
    import torch

    torch.set_num_threads(threads)


#: Where trials run: ``local`` worker processes (the default, no Ray needed) or a Ray cluster.
BACKENDS = ("local", "ray")


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
    if backend not in BACKENDS:
        raise ValueError(f"backend must be one of {BACKENDS}, got {backend!r}")
    results: dict[int, TrialResult] = {}
    groups = group_by_simulation(specs)

    def finish(indices: list[int], done: list[TrialResult]) -> None:
        for i, result in zip(indices, done, strict=True):
            results[i] = result
            if on_done:
                on_done(result)

    if backend == "ray":
        _run_on_ray(specs, groups, workers, address, finish)
    elif workers <= 1 or len(groups) <= 1:
        for indices in groups:
            finish(indices, run_shared([specs[i] for i in indices]))
    else:
        threads = max(1, (os.cpu_count() or 1) // workers)
        with ProcessPoolExecutor(max_workers=workers, initializer=_limit_threads, initargs=(threads,)) as pool:
            futures = {pool.submit(run_shared, [specs[i] for i in indices]): indices for indices in groups}
            for future in as_completed(futures):
                finish(futures[future], future.result())
    return [results[i] for i in range(len(specs))]


def _shared_on_one_thread(specs: list[TrialSpec]) -> list[TrialResult]:
    """A Ray task: one CPU each, so torch keeps to one thread."""
    _limit_threads(1)
    return run_shared(specs)


def _run_on_ray(
    specs: Sequence[TrialSpec],
    groups: list[list[int]],
    workers: int,
    address: str | None,
    finish: Callable[[list[int], list[TrialResult]], None],
) -> None:
    """Each shared simulation as a Ray task (one CPU); results handed to ``finish`` as they complete. Starts a
    local Ray with ``workers`` CPUs unless one is running or ``address`` names a cluster (then it joins it)."""
    try:
        import ray
    except ImportError:
        raise RuntimeError("--backend ray needs Ray: pip install 'ray>=2.9' (or the project's [ray] extra)") from None
    started = not ray.is_initialized()
    if started:
        ray.init(
            address=address,
            num_cpus=None if address else max(1, workers),
            include_dashboard=False,
            log_to_driver=False,
            configure_logging=False,
        )
    try:
        task = ray.remote(num_cpus=1)(_shared_on_one_thread)
        pending = {task.remote([specs[i] for i in indices]): indices for indices in groups}
        while pending:
            ready, _ = ray.wait(list(pending), num_returns=1)
            for ref in ready:
                finish(pending.pop(ref), ray.get(ref))
    finally:
        if started:
            ray.shutdown()
