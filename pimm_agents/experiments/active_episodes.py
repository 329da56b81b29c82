"""``evaluate.py active``: policies compared on the same episodes of the active-localization env.

Every policy starts from the same poses: each generated route's start (``route_1`` ... of the world's
scenarios), ``trials`` times with seeds ``seed``, ``seed + 1``, ...; the episode's clock and the localizer start
there with nothing known. ``route`` drives the route itself (its waypoints, as ``run`` does) and is scored on
the same terms; the others drive the env's primitives. Per policy: success (a right ``localized`` within the
time limit), the median and 90th percentile of the time to it (an episode without one counts as never), the
distance driven, collisions and the seconds reported ``localized`` while wrong.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

ROUTE = "route"


@dataclass(frozen=True)
class Episode:
    policy: str
    world: str
    scenario: str
    seed: int
    first_right_s: float | None
    distance_m: float
    collided: bool
    false_localized_s: float


def run_policy_episode(env: Any, policy: Any, start: np.ndarray, seed: int, world: str, scenario: str) -> Episode:
    """One episode of a primitive policy from ``start``."""
    policy.reset(seed)
    obs, info = env.reset(seed=seed, options={"pose": start})
    collided = False
    while True:
        obs, _, terminated, truncated, info = env.step(policy(obs))
        collided = collided or info["collision"]
        if terminated or truncated:
            break
    return Episode(
        policy.name,
        world,
        scenario,
        seed,
        info["first_right_localized_s"],
        info["distance_m"],
        collided,
        info["false_localized_s"],
    )


def run_route_episode(world: str, localizer: str, scenario: str, seed: int, limit_s: float) -> Episode:
    """The route baseline: the scenario driven along its waypoints, scored over its first ``limit_s``."""
    from pimm_agents.experiments.runner import run_trial
    from pimm_agents.scoring.honesty import honesty_metrics
    from pimm_agents.scoring.trial import TrialSpec

    result = run_trial(TrialSpec(scenario, localizer, 0, seed, world=world))
    clipped = result.log.until(limit_s)
    honesty = honesty_metrics(clipped, None)
    steps = np.diff(clipped.true[:, :2], axis=0)
    distance = float(np.sum(np.hypot(steps[:, 0], steps[:, 1])))
    return Episode(
        ROUTE, world, scenario, seed, honesty.time_to_localized_s, distance, result.collided, honesty.false_localized_s
    )


def summarize(episodes: Sequence[Episode], limit_s: float) -> dict[str, Any]:
    """The per-policy figures of the JSON contract."""
    times = np.array(
        [e.first_right_s if e.first_right_s is not None and e.first_right_s <= limit_s else np.inf for e in episodes]
    )

    def finite(value: float) -> float | None:
        return float(value) if np.isfinite(value) else None

    return {
        "episodes": len(episodes),
        "success_rate": float(np.mean(np.isfinite(times))) if len(times) else 0.0,
        "median_time_s": finite(np.median(times)) if len(times) else None,
        "p90_time_s": finite(np.percentile(times, 90, method="higher")) if len(times) else None,
        "distance_m": float(np.mean([e.distance_m for e in episodes])) if episodes else 0.0,
        "collisions": int(sum(e.collided for e in episodes)),
        "false_localized_s": float(sum(e.false_localized_s for e in episodes)),
    }


@dataclass(frozen=True)
class EpisodePlan:
    """One episode to run: which policy drives from which route's start, in which world, with which seed."""

    world: str
    scenario: str
    start: tuple[float, ...]
    policy: str
    seed: int
    localizer: str
    limit_s: float


#: a worker's envs, one per (world, localizer, time limit), built on first use and kept for its next episodes
_ENVS: dict[tuple[str, str, float], Any] = {}


def run_planned_episode(plan: EpisodePlan) -> Episode:
    """Run ``plan`` (in this process or a worker's), reusing the env this process built for its world."""
    from dataclasses import replace

    from pimm_agents.active.env import ActiveConfig, ActiveLocalizationEnv
    from pimm_agents.active.policies import make_policy

    if plan.policy == ROUTE:
        return run_route_episode(plan.world, plan.localizer, plan.scenario, plan.seed, plan.limit_s)
    key = (plan.world, plan.localizer, plan.limit_s)
    if key not in _ENVS:
        config = replace(ActiveConfig(), time_limit_s=plan.limit_s)
        _ENVS[key] = ActiveLocalizationEnv(plan.world, plan.localizer, config)
    env = _ENVS[key]
    policy = make_policy(plan.policy, env.scan_range)
    return run_policy_episode(env, policy, np.array(plan.start), plan.seed, plan.world, plan.scenario)


def close_envs() -> None:
    """Close and forget the envs this process built."""
    while _ENVS:
        _ENVS.popitem()[1].close()


def evaluate_active(
    worlds: str | Sequence[str],
    policies: Sequence[str],
    trials: int,
    seed: int,
    localizer: str = "pimm",
    limit_s: float = 60.0,
    progress: bool = False,
    workers: int = 1,
    backend: str = "local",
    address: str | None = None,
) -> dict[str, Any]:
    """``{"policies": {NAME: summary}, "worlds": {WORLD: {NAME: summary}}, "episodes": [...]}`` over each
    world's generated routes' starts (the figures of ``policies`` pool every world's episodes). The episodes
    run in this process, in ``workers`` local processes or as Ray tasks (``engines.run_jobs``); each is seeded on
    its own, so where they run changes no figure (``workers`` 0: one per core)."""
    import os
    from dataclasses import asdict

    from tqdm import tqdm

    from pimm_agents.active.policies import check_policy
    from pimm_agents.experiments.engines import run_jobs
    from pimm_env.driving.scenarios import load_scenarios

    worlds = [worlds] if isinstance(worlds, str) else list(worlds)
    for name in policies:  # a bad name or policy file is refused before any episode runs
        if name != ROUTE:
            check_policy(name)
    plans = []
    for world in worlds:
        starts = {n: s.start for n, s in load_scenarios(world).items() if s.kidnap_to is None}
        plans += [
            EpisodePlan(world, n, tuple(float(v) for v in start), name, seed + t, localizer, limit_s)
            for name in policies
            for n, start in starts.items()
            for t in range(trials)
        ]
    workers = workers or os.cpu_count() or 1
    bar = tqdm(total=len(plans), desc="episodes", disable=not progress)
    try:
        episodes = run_jobs(run_planned_episode, plans, workers, backend, address, on_done=lambda i, e: bar.update())
    finally:
        bar.close()
        close_envs()
    return {
        "policies": _by_policy(episodes, limit_s),
        "worlds": {w: _by_policy([e for e in episodes if e.world == w], limit_s) for w in worlds},
        "episodes": [asdict(e) for e in episodes],
    }


def _by_policy(episodes: Sequence[Episode], limit_s: float) -> dict[str, Any]:
    grouped: dict[str, list[Episode]] = {}
    for e in episodes:
        grouped.setdefault(e.policy, []).append(e)
    return {name: summarize(eps, limit_s) for name, eps in grouped.items()}
