"""Policies for the active-localization env: the non-learned baselines, and a trained stable-baselines3 policy.

Each is a callable ``policy(observation) -> action`` with ``reset(seed)`` called at the start of an episode:

- ``random``: a random walk: each primitive drawn at random, forward twice as often as each turn (the env's
  forward guard keeps it off the walls);
- ``greedy``: while the observation's ``guide`` shows a place that tells the belief's hypotheses apart (the
  map's views from there differ between them, views.py), it heads for the guide's waypoint: forward when the
  waypoint is within half a turn ahead and the way is clear, else a turn toward it; when the way ahead is
  blocked it turns aside to the side whose way is clear (the one nearer the waypoint first) and drives on a step
  there; when it would turn back the way the guide just turned it (the belief jumped) it explores for a few
  primitives. Otherwise it explores: it drives toward the most open direction it has not yet been towards
  (explorer.py, the same exploring as the env's ``explore`` observation);
- ``trained``: a stable-baselines3 policy loaded from a ``.zip`` (``python -m training policy`` writes one),
  acting deterministically; the name ``trained`` is the shipped one (``SHIPPED_POLICY``, its record beside it).
  It never chooses the forward primitive while the forward guard would stop it at once (the ``scan``
  observation's sectors blocked, the guard's own test): it takes the likelier turn instead. ``greedy``, which
  it imitates, never drives into a blocked way, so the network never saw what to do after doing so, and kept
  choosing the primitive that stands still.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Protocol

import numpy as np

from pimm_agents.active.explorer import Explorer, sectors_blocked
from pimm_agents.active.primitives import FORWARD, LEFT, PRIMITIVES, RIGHT

#: about what each turn primitive turns (rad; squared up with the walls, it may turn up to 22.5 deg more or less)
TURNS = {i: p.angular * p.duration for i, p in enumerate(PRIMITIVES) if p.angular != 0.0}
#: the shipped policy (``trained``), beside the record of how it was trained (``.json``)
SHIPPED_POLICY = Path(__file__).resolve().parent / "weights" / "active_ppo.zip"


class Policy(Protocol):
    name: str

    def reset(self, seed: int | None = None) -> None: ...

    def __call__(self, observation: dict[str, np.ndarray]) -> int: ...


class RandomWalk:
    name = "random"

    def __init__(self) -> None:
        self.rng = np.random.default_rng()

    def reset(self, seed: int | None = None) -> None:
        self.rng = np.random.default_rng(seed)

    def __call__(self, observation: dict[str, np.ndarray]) -> int:
        return int(self.rng.choice([FORWARD, FORWARD, LEFT, RIGHT]))


class Greedy:
    """The ``greedy`` baseline (see the module docstring): heads for the ``guide``'s waypoint when there is
    one, else explores (:class:`Explorer`)."""

    name = "greedy"
    AHEAD = np.pi / 8 + np.radians(5.0)  # as the explorer: within half a turn, and a margin, counts as ahead
    EXPLORE_STEPS = 4  # primitives it explores for when it would turn to and fro between the guide's turns

    def __init__(self, max_range: float = 20.0) -> None:
        self.explorer = Explorer(max_range)
        self.max_range = max_range
        self.reset()

    def reset(self, seed: int | None = None) -> None:
        self.explorer.reset(seed)
        self.last_turn: int | None = None  # the guide's last turn, while it follows the guide
        self.sidestep = False  # it turned aside from a blocked way and drives on once before it turns back
        self.explore_for = 0  # primitives left to explore before it follows the guide again

    def __call__(self, observation: dict[str, np.ndarray]) -> int:
        explore = self.explorer(observation)  # keeps its dead reckoning and what it has faced up to date
        if "guide" not in observation or observation["guide"][3] < 0.5 or self.explore_for > 0:
            self.explore_for = max(0, self.explore_for - 1)
            self.last_turn, self.sidestep = None, False
            return explore
        bearing = float(np.arctan2(observation["guide"][0], observation["guide"][1]))
        scan = np.asarray(observation["scan"], dtype=float) * self.max_range
        # the guide's path keeps to the middle of the map's corridors and doors, so the forward guard's own test
        # (the cone ahead and the lane the body sweeps) is margin enough: a wider one of its own had it stop short
        # of doorways it could pass and explore away from them
        clear = not sectors_blocked(scan)
        if self.sidestep and clear:  # after a turn aside, one step on: the way past what blocked it
            self.sidestep, self.last_turn = False, None
            return FORWARD
        self.sidestep = False
        if abs(bearing) <= self.AHEAD:
            if clear:
                self.last_turn = None
                return FORWARD
            # the way ahead is blocked (the robot stands too near a wall or a jamb to pass it): it turns aside to
            # the side nearer the waypoint whose way is clear (either when neither is) and drives on a step there
            sides = sorted((LEFT, RIGHT), key=lambda a: abs(bearing - TURNS[a]))
            action = next((a for a in sides if not sectors_blocked(scan, turn=TURNS[a])), sides[0])
            self.sidestep, self.last_turn = True, None
            return action
        action = LEFT if bearing > 0 else RIGHT
        if {action, self.last_turn} == {LEFT, RIGHT}:
            # the waypoint moved with the belief and it would turn back the way the guide just turned it: it
            # explores for a few primitives instead of turning to and fro, and then follows the guide again
            self.explore_for, self.last_turn = self.EXPLORE_STEPS - 1, None
            return explore
        self.last_turn = action
        return action


class Trained:
    """A stable-baselines3 policy from a ``.zip``, acting deterministically; named ``trained`` when it is the
    shipped one, else by its file's name."""

    def __init__(self, path: Path, max_range: float = 20.0) -> None:
        from stable_baselines3 import PPO

        from pimm_env.errors import MissingFileError

        if not Path(path).is_file():
            raise MissingFileError(f"policy {path} does not exist (python -m training policy writes one)")
        self.model: Any = PPO.load(str(path), device="cpu")
        self.name = "trained" if Path(path).resolve() == SHIPPED_POLICY else Path(path).stem
        self.path = Path(path)
        #: the observation's entries it was trained on: a policy trained before an entry was added reads the rest
        self.keys = tuple(getattr(self.model.observation_space, "spaces", {}))
        self.max_range = max_range  # the 2D LiDAR's, over which the ``scan`` observation is given

    def reset(self, seed: int | None = None) -> None:
        pass

    def __call__(self, observation: dict[str, np.ndarray]) -> int:
        missing = [k for k in self.keys if k not in observation]
        if missing:
            from pimm_env.errors import EnvError

            raise EnvError(f"policy {self.path} reads observation entries {missing} this observation lacks")
        blocked = "scan" in observation and sectors_blocked(np.asarray(observation["scan"], float) * self.max_range)
        return self.likeliest({k: observation[k] for k in self.keys}, exclude=FORWARD if blocked else None)

    def likeliest(self, inputs: dict[str, np.ndarray], exclude: int | None = None) -> int:
        """The action the network finds likeliest at ``inputs`` (its deterministic choice), ``exclude`` left out."""
        import torch

        tensor, _ = self.model.policy.obs_to_tensor(inputs)
        with torch.no_grad():
            probs = self.model.policy.get_distribution(tensor).distribution.probs[0].numpy().copy()
        if exclude is not None:
            probs[exclude] = -1.0
        return int(np.argmax(probs))


def check_policy(name: str) -> None:
    """Raise unless ``name`` is ``random``, ``greedy``, ``trained`` or the path of an existing ``.zip``."""
    from pimm_env.errors import EnvError, MissingFileError

    if name in ("random", "greedy", "trained"):
        return
    if not name.endswith(".zip"):
        raise EnvError(f"policy {name!r}: expected random, greedy, trained or a trained policy's .zip")
    if not Path(name).is_file():
        raise MissingFileError(f"policy {name} does not exist (python -m training policy writes one)")


def make_policy(name: str, max_range: float = 20.0) -> Policy:
    """``random``, ``greedy``, ``trained`` (the shipped policy) or the path of a trained policy's ``.zip``."""
    check_policy(name)
    if name == "random":
        return RandomWalk()
    if name == "greedy":
        return Greedy(max_range)
    return Trained(SHIPPED_POLICY if name == "trained" else Path(name), max_range)
