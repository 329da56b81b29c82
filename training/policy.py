"""Training an active-localization policy with stable-baselines3: ``python -m training policy``.

PPO with a multi-input MLP over the env's dict observation (``pimm/ActiveLocalization-v0``): ``workers`` envs
(in worker processes when more than one), each drawing its building anew from all of ``worlds`` at every
episode. The
training's progress goes to ``progress.csv`` (and TensorBoard, where it is installed) beside the policy, and a
record (``.json`` beside the ``.zip``) says how it was made: algorithm, steps, seed, worlds, localizer, versions,
wall time. The same seed and worlds give the same policy (single worker; torch's CPU kernels are deterministic
here).
"""

from __future__ import annotations

import json
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

#: PPO's settings: stable-baselines3's defaults, but for rollouts of 128 steps per env (an episode is 10-60
#: primitives), a discount for about a minute of them, and an entropy bonus (the default is none) to keep a
#: run of a few thousand episodes exploring
PPO_SETTINGS: dict[str, Any] = {
    "n_steps": 128,
    "batch_size": 64,
    "gamma": 0.98,
    "learning_rate": 3e-4,
    "ent_coef": 0.01,
}


def _make_env(worlds: Sequence[str], localizer: str, seed: int):
    def build() -> Any:
        from stable_baselines3.common.monitor import Monitor

        env = WorldCycle(worlds, localizer)
        env.reset(seed=seed)
        return Monitor(env)

    return build


class WorldCycle(gym.Env):
    """``pimm/ActiveLocalization-v0`` in a building drawn anew at every reset from ``worlds`` (by the env's own
    seeded generator), so that each training env sees every building rather than one. The envs are built on
    first use and kept (about 70 MB and 0.6 s each)."""

    def __init__(self, worlds: Sequence[str], localizer: str) -> None:
        from pimm_agents.active.env import ActiveLocalizationEnv

        self.worlds = [str(w) for w in worlds]
        self.localizer = localizer
        self._envs: dict[str, ActiveLocalizationEnv] = {}
        self.current = self._env(self.worlds[0])
        self.observation_space = self.current.observation_space
        self.action_space = self.current.action_space

    def _env(self, world: str) -> Any:
        from pimm_agents.active.env import ActiveLocalizationEnv

        if world not in self._envs:
            self._envs[world] = ActiveLocalizationEnv(world, self.localizer)
        return self._envs[world]

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        self.current = self._env(self.worlds[int(self.np_random.integers(len(self.worlds)))])
        return self.current.reset(seed=int(self.np_random.integers(2**31)), options=options)

    def step(self, action: Any):
        return self.current.step(action)

    def close(self) -> None:
        for env in self._envs.values():
            env.close()


def train_policy(
    worlds: Sequence[str],
    steps: int,
    out: Path,
    seed: int = 0,
    localizer: str = "pimm",
    workers: int = 1,
    algo: str = "ppo",
    imitate: int = 0,
    dagger: int = 0,
    critic: bool = False,
    backend: str = "local",
    address: str | None = None,
) -> Path:
    """Train and save a policy to ``out`` (a ``.zip``); returns its path. With ``imitate`` > 0, the policy
    network first learns to act as the ``greedy`` policy does, from that many of its steps in the same envs
    (:func:`imitate_greedy`; with ``dagger`` > 0, then from as many steps of its own drives, labelled by
    ``greedy``), and PPO goes on from there. With ``critic``, the imitation fits the value head too, to the
    returns of the steps it learns from, so that PPO's first advantages are not an untrained critic's noise.
    ``backend`` ``ray`` runs the envs as Ray actors (a local Ray, or the cluster at ``address``) instead of
    worker processes; the same seeds, so the same policy."""
    from stable_baselines3 import PPO
    from stable_baselines3.common.logger import configure
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecEnv

    from pimm_agents.experiments.engines import check_backend
    from pimm_env.errors import EnvError

    if algo != "ppo":
        raise EnvError(f"--algo {algo!r}: only ppo is implemented")
    if steps < 1 or workers < 1 or imitate < 0 or dagger < 0 or not worlds:
        raise EnvError("policy training needs steps >= 1, workers >= 1, imitate and dagger >= 0 and a world")
    if (dagger or critic) and not imitate:
        raise EnvError("--dagger and --critic fit on the drives of --imitate: give --imitate too")
    check_backend(backend, address)
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    builders = [_make_env(worlds, localizer, seed + i) for i in range(workers)]
    venv: VecEnv
    if backend == "ray":
        from training.ray_envs import RayVecEnv

        venv = RayVecEnv(builders, address)
    else:
        venv = SubprocVecEnv(builders) if workers > 1 else DummyVecEnv(builders)
    settings = dict(PPO_SETTINGS)
    settings["n_steps"] = min(settings["n_steps"], max(steps // len(builders), 8))
    settings["batch_size"] = min(settings["batch_size"], settings["n_steps"] * len(builders))
    model = PPO("MultiInputPolicy", venv, seed=seed, device="cpu", verbose=0, **settings)
    formats = ["csv"]
    try:
        import tensorboard  # noqa: F401

        formats.append("tensorboard")
    except ImportError:
        pass
    logger = configure(str(out.with_suffix("")) + "_log", formats)
    model.set_logger(logger)
    start = time.perf_counter()
    try:
        imitation = imitate_greedy(model, venv, imitate, seed, dagger, critic) if imitate else None
        model.learn(
            total_timesteps=steps, callback=[_progress_bar(steps), _checkpoints(steps, out)], progress_bar=False
        )
    finally:
        logger.close()
        venv.close()
    wall = time.perf_counter() - start
    model.save(str(out))
    record = {
        "algo": algo,
        "steps": steps,
        "seed": seed,
        "worlds": [str(w) for w in worlds],
        "localizer": localizer,
        "workers": workers,
        "backend": backend,
        "settings": settings,
        "imitate": imitate,
        "dagger": dagger,
        "critic": critic,
        "imitation": imitation,
        "wall_s": round(wall, 1),
        "versions": _versions(),
        "reproduce": f"python -m training policy --algo {algo} --steps {steps} --imitate {imitate}"
        + (f" --dagger {dagger}" if dagger else "")
        + (" --critic" if critic else "")
        + (" --backend ray" if backend == "ray" else "")
        + f" --seed {seed}"
        f" --workers {workers} --localizer {localizer}" + "".join(f" --world {w}" for w in worlds),
    }
    out.with_suffix(".json").write_text(json.dumps(record, indent=2) + "\n")
    from training.policy_plots import plot_progress

    plot_progress(Path(str(out.with_suffix("")) + "_log") / "progress.csv")
    return out


#: the imitation's fit: epochs over the greedy policy's steps, minibatch, Adam's step (PPO's own learning rate)
IMITATION_EPOCHS, IMITATION_BATCH = 20, 64
#: the weight of the critic's squared error beside the actions' cross-entropy when the imitation fits both
#: (stable-baselines3 PPO's own ``vf_coef``)
IMITATION_VALUE_WEIGHT = 0.5


def imitate_greedy(
    model: Any, venv: Any, steps: int, seed: int, dagger: int = 0, critic: bool = False
) -> dict[str, float | None]:
    """Drive ``venv`` for ``steps`` steps with the ``greedy`` policy (one per env, reset at each episode) and
    fit ``model``'s policy network to its actions (cross-entropy, Adam): a start for PPO that already follows
    the guide and drives where it is open, instead of the uniform policy that PPO's few thousand episodes here
    did not get far from (after 3 840-7 680 steps without it: policies that turned on the spot).

    With ``dagger`` > 0, one round of DAgger (Ross et al., 2011) follows: the fitted network drives for
    ``dagger`` steps (deterministically), ``greedy`` says at each what it would do there, and the network is
    fitted again on all the steps. A copy fitted only on ``greedy``'s own drives never sees the places its own
    mistakes lead to, and drove on from them where ``greedy`` would have turned. ``greedy`` keeps its memory
    (what it has faced, its last turn) as if its own choices had been driven.

    With ``critic``, the value head is fitted too, to each step's discounted return (PPO's discount) on the
    drives (:func:`discounted_returns`): PPO otherwise starts from an untrained critic (explained variance about
    0 at its first update), whose advantages push the imitated policy about.

    Returns the fit's agreement with ``greedy`` on its own steps (and on the network's, with ``dagger``), and
    with ``critic`` the share of the returns' variance the value head explains."""
    import torch

    from pimm_agents.active.policies import Greedy
    from pimm_env.envs.base_env import SimConfig

    teachers = [Greedy(SimConfig().lidar2d.max_range) for _ in range(venv.num_envs)]  # the env's own LiDAR
    observations, actions, returns = _drive(venv, teachers, steps, "imitation", gamma=model.gamma)
    generator = torch.Generator().manual_seed(seed)
    fit_to(model.policy, observations, actions, generator, returns if critic else None)
    result: dict[str, float | None] = {"steps": len(actions)}
    own: list[dict[str, np.ndarray]] = []
    if dagger:
        for teacher in teachers:
            teacher.reset()
        own, labels, own_returns = _drive(venv, teachers, dagger, "DAgger", model, gamma=model.gamma)
        before = agreement(model.policy, own, labels)
        returns = np.concatenate([returns, own_returns])
        fit_to(model.policy, observations + own, actions + labels, generator, returns if critic else None)
        result.update(
            dagger_steps=len(labels),
            dagger_agreement_before=round(before, 3),
            dagger_agreement=round(agreement(model.policy, own, labels), 3),
        )
    result["agreement"] = round(agreement(model.policy, observations, actions), 3)
    result["forward_share"] = round(float(np.mean(np.array(actions) == 0)), 3)
    if critic:
        result["value_steps"] = int(np.isfinite(returns).sum())
        explained = explained_variance(model.policy, observations + own, returns)
        result["value_explained_variance"] = round(explained, 3) if np.isfinite(explained) else None
    return result


def _drive(
    venv: Any, teachers: list[Any], steps: int, desc: str, driver: Any = None, gamma: float = 1.0
) -> tuple[list[dict[str, np.ndarray]], list[int], np.ndarray]:
    """About ``steps`` steps of ``venv`` (a whole number per env), driven by ``teachers`` or, given, by
    ``driver``'s deterministic actions: each step's observation, what its env's teacher chose there, and the
    discounted return from it (``gamma``; NaN where its episode had not ended when the drives stopped)."""
    from tqdm import tqdm

    observations: list[dict[str, np.ndarray]] = []
    labels: list[int] = []
    rewards: list[np.ndarray] = []
    ended: list[np.ndarray] = []
    obs = venv.reset()
    rounds = max(1, steps // venv.num_envs)
    bar = tqdm(total=rounds * venv.num_envs, desc=desc, unit="step")
    for _ in range(rounds):
        bar.update(venv.num_envs)
        chosen = [teacher({k: v[i] for k, v in obs.items()}) for i, teacher in enumerate(teachers)]
        observations += [{k: v[i].copy() for k, v in obs.items()} for i in range(venv.num_envs)]
        labels += chosen
        driven = np.array(chosen) if driver is None else driver.predict(obs, deterministic=True)[0]
        obs, reward, dones, _ = venv.step(np.asarray(driven))
        rewards.append(np.asarray(reward, dtype=float))
        ended.append(np.asarray(dones, dtype=bool))
        for i, done in enumerate(dones):
            if done:
                teachers[i].reset()
    bar.close()
    return observations, labels, discounted_returns(np.array(rewards), np.array(ended), gamma).reshape(-1)


def discounted_returns(rewards: np.ndarray, ended: np.ndarray, gamma: float) -> np.ndarray:
    """Each step's discounted sum of rewards to its episode's end, for rewards and ends of shape (steps, envs)
    (the vector env's order: a row per step of all envs). An episode cut at the time limit counts as ended
    there; steps of an episode still running at the last row have no return yet (NaN)."""
    returns = np.empty_like(rewards, dtype=float)
    running = np.full(rewards.shape[1], np.nan)
    for t in range(len(rewards) - 1, -1, -1):
        running = np.where(ended[t], rewards[t], rewards[t] + gamma * running)
        returns[t] = running
    return returns


def _batch(observations: list[dict[str, np.ndarray]]) -> dict[str, Any]:
    import torch

    return {k: torch.as_tensor(np.stack([o[k] for o in observations])) for k in observations[0]}


def fit_to(
    policy: Any,
    observations: list[dict[str, np.ndarray]],
    actions: list[int],
    generator: Any,
    returns: np.ndarray | None = None,
) -> None:
    """``IMITATION_EPOCHS`` epochs of cross-entropy of ``policy``'s action distribution on ``actions``; given
    ``returns``, plus ``IMITATION_VALUE_WEIGHT`` times the value head's squared error on the finite ones."""
    import torch

    batch, target = _batch(observations), torch.as_tensor(np.array(actions))
    if returns is not None:
        value_target = torch.as_tensor(np.nan_to_num(returns), dtype=torch.float32)
        known = torch.as_tensor(np.isfinite(returns))
    optimizer = torch.optim.Adam(policy.parameters(), lr=PPO_SETTINGS["learning_rate"])
    for _ in range(IMITATION_EPOCHS):
        for index in torch.randperm(len(target), generator=generator).split(IMITATION_BATCH):
            values, log_prob, _ = policy.evaluate_actions({k: v[index] for k, v in batch.items()}, target[index])
            loss = -log_prob.mean()
            if returns is not None and bool(known[index].any()):
                rows = index[known[index]]
                error = values.flatten()[known[index]] - value_target[rows]
                loss = loss + IMITATION_VALUE_WEIGHT * (error**2).mean()
            optimizer.zero_grad()
            loss.backward()
            optimizer.step()


def agreement(policy: Any, observations: list[dict[str, np.ndarray]], actions: list[int]) -> float:
    """The share of ``observations`` at which ``policy``'s likeliest action is the one in ``actions``."""
    import torch

    with torch.no_grad():
        probs = policy.get_distribution(_batch(observations)).distribution.probs
    return float((probs.argmax(1) == torch.as_tensor(np.array(actions))).float().mean())


def explained_variance(policy: Any, observations: list[dict[str, np.ndarray]], returns: np.ndarray) -> float:
    """The share of the finite ``returns``' variance that ``policy``'s value head explains (1 - var(G - V) /
    var(G), as stable-baselines3 logs it; NaN with fewer than two returns or none that vary)."""
    import torch
    from stable_baselines3.common.utils import explained_variance as stable_baselines3_explained_variance

    known = np.isfinite(returns)
    if known.sum() < 2:
        return float("nan")
    with torch.no_grad():
        kept = [o for o, k in zip(observations, known, strict=True) if k]
        values = policy.predict_values(_batch(kept)).numpy().ravel()
    return float(stable_baselines3_explained_variance(values, returns[known]))


def _checkpoints(total: int, out: Path) -> Any:
    """The policy at every tenth of the run (whole rollouts of 256 steps), in ``<out>_log/checkpoints/``: what a
    shorter run of the same seed would have written, so a stopped run keeps its progress."""
    from stable_baselines3.common.callbacks import BaseCallback

    folder = Path(str(out.with_suffix("")) + "_log") / "checkpoints"
    every = max(256, total // 10 // 256 * 256)

    class Checkpoints(BaseCallback):
        def _on_rollout_start(self) -> None:  # the last rollout has been learned from
            if self.num_timesteps and self.num_timesteps % every == 0:
                folder.mkdir(parents=True, exist_ok=True)
                self.model.save(str(folder / f"{out.stem}_{self.num_timesteps}_steps.zip"))

        def _on_step(self) -> bool:
            return True

    return Checkpoints()


def _progress_bar(total: int) -> Any:
    """A tqdm bar over the training's environment steps (stable-baselines3's own needs rich)."""
    from stable_baselines3.common.callbacks import BaseCallback
    from tqdm import tqdm

    class Bar(BaseCallback):
        def _on_training_start(self) -> None:
            self.bar = tqdm(total=total, desc="policy", unit="step")

        def _on_step(self) -> bool:
            self.bar.update(self.training_env.num_envs)
            return True

        def _on_training_end(self) -> None:
            self.bar.close()

    return Bar()


def _versions() -> dict[str, str]:
    from importlib.metadata import PackageNotFoundError, version

    found = {}
    for name in ("pimm", "stable_baselines3", "torch", "gymnasium"):
        try:
            found[name] = version(name)
        except PackageNotFoundError:
            found[name] = "not installed"
    return found
