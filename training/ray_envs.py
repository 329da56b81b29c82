"""A stable-baselines3 vector env whose envs run as Ray actors (``python -m training policy --backend ray``).

Each actor holds one env in a one-env ``DummyVecEnv``, which already does what a vector env must (the reset at
an episode's end, the terminal observation in the info, the seeds and options of the next reset); this class
hands every call to the actors and stacks their answers. The seeds are those ``SubprocVecEnv`` gives its
workers, so a run on Ray writes the policy that ``--workers`` local processes write.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from stable_baselines3.common.vec_env.base_vec_env import VecEnv, VecEnvIndices, VecEnvStepReturn

from pimm_env.errors import ExperimentError


class _OneEnv:
    """A Ray actor's state: one env in a ``DummyVecEnv``, its torch on one thread (one CPU per actor)."""

    def __init__(self, build: Callable[[], gym.Env]) -> None:
        from stable_baselines3.common.vec_env import DummyVecEnv

        from pimm_agents.experiments.engines import limit_threads

        limit_threads(1)
        self.venv = DummyVecEnv([build])

    def spaces(self) -> tuple[gym.Space, gym.Space]:
        return self.venv.observation_space, self.venv.action_space

    def reset(self, seed: int | None, options: dict[str, Any] | None) -> tuple[Any, list[dict[str, Any]]]:
        self.venv._seeds = [seed]  # as given: ``seed(None)`` would draw one from NumPy's global state
        self.venv.set_options(options or {})
        return self.venv.reset(), self.venv.reset_infos

    def step(self, action: np.ndarray) -> VecEnvStepReturn:
        return self.venv.step(action)

    def call(self, method: str, *args: Any, **kwargs: Any) -> Any:
        return getattr(self.venv, method)(*args, **kwargs)

    def close(self) -> None:
        self.venv.close()


def _stack(parts: Sequence[Any]) -> Any:
    if isinstance(parts[0], dict):
        return {key: np.concatenate([part[key] for part in parts]) for key in parts[0]}
    return np.concatenate(parts)


class RayVecEnv(VecEnv):
    """The envs of ``builders`` as Ray actors, one CPU each, on a local Ray (``address`` None: started here
    with a CPU per env unless one runs) or on the cluster at ``address``."""

    def __init__(self, builders: Sequence[Callable[[], gym.Env]], address: str | None = None) -> None:
        try:
            import ray
        except ImportError:
            raise ExperimentError(
                "--backend ray needs Ray: pip install 'ray>=2.9' (or the project's [ray] extra)"
            ) from None
        self._ray = ray
        self._started = not ray.is_initialized()
        if self._started:
            ray.init(
                address=address,
                num_cpus=None if address else len(builders),
                include_dashboard=False,
                log_to_driver=False,
                configure_logging=False,
            )
        actor = ray.remote(num_cpus=1)(_OneEnv)
        self._actors = [actor.remote(build) for build in builders]
        observation_space, action_space = ray.get(self._actors[0].spaces.remote())
        super().__init__(len(builders), observation_space, action_space)
        self._pending: list[Any] = []

    def _indices(self, indices: VecEnvIndices) -> list[int]:
        return list(self._get_indices(indices))

    def reset(self) -> Any:
        answers = self._ray.get([a.reset.remote(self._seeds[i], self._options[i]) for i, a in enumerate(self._actors)])
        self.reset_infos = [infos[0] for _, infos in answers]
        self._reset_seeds()
        self._reset_options()
        return _stack([observation for observation, _ in answers])

    def step_async(self, actions: np.ndarray) -> None:
        self._pending = [a.step.remote(np.asarray(actions[i : i + 1])) for i, a in enumerate(self._actors)]

    def step_wait(self) -> VecEnvStepReturn:
        answers = self._ray.get(self._pending)
        self._pending = []
        observations = _stack([answer[0] for answer in answers])
        rewards = np.concatenate([answer[1] for answer in answers])
        dones = np.concatenate([answer[2] for answer in answers])
        infos = [answer[3][0] for answer in answers]
        return observations, rewards, dones, infos

    def close(self) -> None:
        try:
            self._ray.get([a.close.remote() for a in self._actors])
        finally:
            for a in self._actors:
                self._ray.kill(a)
            if self._started:
                self._ray.shutdown()

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        calls = [self._actors[i].call.remote("get_attr", attr_name) for i in self._indices(indices)]
        return [answer[0] for answer in self._ray.get(calls)]

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        self._ray.get([self._actors[i].call.remote("set_attr", attr_name, value) for i in self._indices(indices)])

    def env_method(self, method_name: str, *args: Any, indices: VecEnvIndices = None, **kwargs: Any) -> list[Any]:
        calls = [
            self._actors[i].call.remote("env_method", method_name, *args, **kwargs) for i in self._indices(indices)
        ]
        return [answer[0] for answer in self._ray.get(calls)]

    def env_is_wrapped(self, wrapper_class: type[gym.Wrapper], indices: VecEnvIndices = None) -> list[bool]:
        calls = [self._actors[i].call.remote("env_is_wrapped", wrapper_class) for i in self._indices(indices)]
        return [answer[0] for answer in self._ray.get(calls)]
