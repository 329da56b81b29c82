"""Run localizers on scenarios: one trial in one process, many trials across worker processes."""

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


@dataclass
class TrialResult:
    spec: TrialSpec
    log: TrialLog
    metrics: TrialMetrics  # for kidnap scenarios: measured from the kidnap on
    wall_s: float
    completed: bool


def run_trial(spec: TrialSpec) -> TrialResult:
    """Drive the scenario with the localizer attached; seeds the env and the localizer with ``spec.seed``."""
    from pimm_agents.evaluation.recorder import LocalizationRecorder
    from pimm_agents.factory import make_localizer
    from pimm_env.driving.rollout import run
    from pimm_env.driving.scenarios import get_scenario
    from pimm_env.envs.base_env import SimConfig
    from pimm_env.envs.iilab_env import IILabEnv
    from pimm_env.world.files import load_world

    start = time.perf_counter()
    world = load_world(spec.world)  # read once, passed to everything below
    scenario = get_scenario(spec.scenario, world)
    localizer = make_localizer(spec.localizer, world, params=spec.params)
    config = SimConfig()
    if "cloud" not in getattr(localizer, "sensors", ("cloud",)):  # nobody reads it: do not cast 14 400 rays
        config = replace(config, lidar3d=replace(config.lidar3d, enabled=False))
    env = LocalizationRecorder(IILabEnv(world=world, config=config, terminate_on_collision=False), localizer)
    try:
        rollout = run(scenario, seed=spec.seed, env=env)
        log = env.trial_log()
    finally:
        env.close()
    metrics = trial_metrics(log.after_kidnap() if scenario.kidnap_to is not None else log)
    return TrialResult(spec, log, metrics, time.perf_counter() - start, rollout.completed)


def _limit_threads(threads: int) -> None:
    """Keep each worker's torch to its share of the cores: oversubscribed threads slow every worker down."""
    import torch

    torch.set_num_threads(threads)


def run_trials(
    specs: Sequence[TrialSpec], workers: int = 1, on_done: Callable[[TrialResult], None] | None = None
) -> list[TrialResult]:
    """All trials, in ``workers`` processes (1: in this one); results in the order of ``specs``."""
    results: dict[int, TrialResult] = {}
    if workers <= 1:
        for i, spec in enumerate(specs):
            results[i] = run_trial(spec)
            if on_done:
                on_done(results[i])
    else:
        threads = max(1, (os.cpu_count() or 1) // workers)
        with ProcessPoolExecutor(max_workers=workers, initializer=_limit_threads, initargs=(threads,)) as pool:
            futures = {pool.submit(run_trial, spec): i for i, spec in enumerate(specs)}
            for future in as_completed(futures):
                results[futures[future]] = future.result()
                if on_done:
                    on_done(results[futures[future]])
    return [results[i] for i in range(len(specs))]
