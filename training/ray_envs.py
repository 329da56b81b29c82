"""A stable-baselines3 vector env whose envs run as Ray actors (``python -m training policy --backend ray``).

Each actor holds one env and answers as a ``SubprocVecEnv`` worker does; this class hands every call to the
actors and stacks their answers as ``SubprocVecEnv`` stacks its workers'. The seeds are those it gives its
workers, so a run on Ray writes the policy that ``--workers`` local processes write.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any, SupportsFloat

import gymnasium as gym
import numpy as np
from stable_baselines3.common.vec_env.base_vec_env import VecEnv, VecEnvIndices, VecEnvStepReturn


class _OneEnv:
    """A Ray actor's state: one env, its torch on one thread (one CPU per actor). It answers as a
    ``SubprocVecEnv`` worker does (the reset at an episode's end, the terminal observation in the info, the
    rewards as the env gives them), so that both backends hand PPO the same numbers."""

    def __init__(self, build: Callable[[], gym.Env]) -> None:
        from pimm_agents.experiments.engines import limit_threads

        limit_threads(1)
        self.env = build()

    def spaces(self) -> tuple[gym.Space, gym.Space]:
        return self.env.observation_space, self.env.action_space

    def reset(self, seed: int | None, options: dict[str, Any] | None) -> tuple[Any, dict[str, Any]]:
        return self.env.reset(seed=seed, **({"options": options} if options else {}))

    def step(self, action: Any) -> tuple[Any, SupportsFloat, bool, dict[str, Any], dict[str, Any]]:
        observation, reward, terminated, truncated, info = self.env.step(action)
        done = terminated or truncated
        info["TimeLimit.truncated"] = truncated and not terminated
        reset_info: dict[str, Any] = {}
        if done:
            info["terminal_observation"] = observation
            observation, reset_info = self.env.reset()
        return observation, reward, done, info, reset_info

    def get_attr(self, name: str) -> Any:
        return self.env.get_wrapper_attr(name)

    def set_attr(self, name: str, value: Any) -> None:
        setattr(self.env, name, value)

    def env_method(self, name: str, *args: Any, **kwargs: Any) -> Any:
        return self.env.get_wrapper_attr(name)(*args, **kwargs)

    def env_is_wrapped(self, wrapper_class: type[gym.Wrapper]) -> bool:
        from stable_baselines3.common.env_util import is_wrapped

        return is_wrapped(self.env, wrapper_class)

    def close(self) -> None:
        self.env.close()


def _stack(observations: Sequence[Any]) -> Any:
    if isinstance(observations[0], dict):
        return {key: np.stack([o[key] for o in observations]) for key in observations[0]}
    return np.stack(observations)


class RayVecEnv(VecEnv):
    """The envs of ``builders`` as Ray actors, one CPU each, on a local Ray (``address`` None: started here
    with a CPU per env unless one runs) or on the cluster at ``address``."""

    def __init__(self, builders: Sequence[Callable[[], gym.Env]], address: str | None = None) -> None:
        from pimm_agents.experiments.engines import start_ray

        ray, self._started = start_ray(len(builders), address)
        self._ray = ray
        actor = ray.remote(num_cpus=1)(_OneEnv)
        self._actors = [actor.remote(build) for build in builders]
        observation_space, action_space = ray.get(self._actors[0].spaces.remote())
        super().__init__(len(builders), observation_space, action_space)
        self._pending: list[Any] = []

    def reset(self) -> Any:
        answers = self._ray.get([a.reset.remote(self._seeds[i], self._options[i]) for i, a in enumerate(self._actors)])
        self.reset_infos = [info for _, info in answers]
        self._reset_seeds()
        self._reset_options()
        return _stack([observation for observation, _ in answers])

    def step_async(self, actions: np.ndarray) -> None:
        self._pending = [a.step.remote(action) for a, action in zip(self._actors, actions, strict=True)]

    def step_wait(self) -> VecEnvStepReturn:
        answers = self._ray.get(self._pending)
        self._pending = []
        observations, rewards, dones, infos, reset_infos = zip(*answers, strict=True)
        self.reset_infos = list(reset_infos)
        return _stack(observations), np.stack(rewards), np.stack(dones), list(infos)

    def close(self) -> None:
        try:
            self._ray.get([a.close.remote() for a in self._actors])
        finally:
            for a in self._actors:
                self._ray.kill(a)
            if self._started:
                self._ray.shutdown()

    def _ask(self, method: str, indices: VecEnvIndices, *args: Any, **kwargs: Any) -> list[Any]:
        actors = [self._actors[i] for i in self._get_indices(indices)]
        return self._ray.get([getattr(a, method).remote(*args, **kwargs) for a in actors])

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        return self._ask("get_attr", indices, attr_name)

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        self._ask("set_attr", indices, attr_name, value)

    def env_method(self, method_name: str, *args: Any, indices: VecEnvIndices = None, **kwargs: Any) -> list[Any]:
        return self._ask("env_method", indices, method_name, *args, **kwargs)

    def env_is_wrapped(self, wrapper_class: type[gym.Wrapper], indices: VecEnvIndices = None) -> list[bool]:
        return self._ask("env_is_wrapped", indices, wrapper_class)
