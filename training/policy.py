"""Training an active-localization policy with stable-baselines3: ``python -m training policy``.

PPO with a multi-input MLP over the env's dict observation (``pimm/ActiveLocalization-v0``), one env per world
(worlds cycle when there are more envs than worlds), run in worker processes when ``workers`` > 1. The
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

#: PPO's settings: stable-baselines3's defaults, but for rollouts of 128 steps per env (an episode is 10-60
#: primitives) and a discount for about a minute of them
PPO_SETTINGS: dict[str, Any] = {"n_steps": 128, "batch_size": 64, "gamma": 0.98, "learning_rate": 3e-4}


def _make_env(world: str, localizer: str, seed: int):
    def build() -> Any:
        from stable_baselines3.common.monitor import Monitor

        from pimm_agents.active.env import ActiveLocalizationEnv

        env = ActiveLocalizationEnv(world, localizer)
        env.reset(seed=seed)
        return Monitor(env)

    return build


def train_policy(
    worlds: Sequence[str],
    steps: int,
    out: Path,
    seed: int = 0,
    localizer: str = "pimm",
    workers: int = 1,
    algo: str = "ppo",
) -> Path:
    """Train and save a policy to ``out`` (a ``.zip``); returns its path."""
    from stable_baselines3 import PPO
    from stable_baselines3.common.logger import configure
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv

    from pimm_env.errors import EnvError

    if algo != "ppo":
        raise EnvError(f"--algo {algo!r}: only ppo is implemented")
    if steps < 1 or workers < 1 or not worlds:
        raise EnvError("policy training needs steps >= 1, workers >= 1 and at least one world")
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    builders = [_make_env(worlds[i % len(worlds)], localizer, seed + i) for i in range(max(workers, 1))]
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
        model.learn(total_timesteps=steps, callback=_progress_bar(steps), progress_bar=False)
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
        "settings": settings,
        "wall_s": round(wall, 1),
        "versions": _versions(),
    }
    out.with_suffix(".json").write_text(json.dumps(record, indent=2) + "\n")
    return out


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
