"""Policies for the active-localization env: the non-learned baselines, and a trained stable-baselines3 policy.

Each is a callable ``policy(observation) -> action`` with ``reset(seed)`` called at the start of an episode:

- ``random``: a random walk: each primitive drawn at random, forward twice as often as each turn (the env's
  forward guard keeps it off the walls);
- ``greedy``: while the observation's ``guide`` shows a place that tells the belief's hypotheses apart (the
  map's views from there differ between them, views.py), it heads for the guide's waypoint: forward when the
  waypoint is within half a turn ahead and the way is clear, else a turn toward it; when the way ahead is
  blocked it turns aside to the side whose way is clear (the one nearer the waypoint first) and drives on a step
  there; when it would turn back the way the guide just turned it (the belief jumped) it explores for a few
  primitives. Otherwise it explores: it drives toward the most open direction it has not yet been towards. The scan's 60
  sectors are scored by their free range (up to 8 m), less 0.5 m per radian of turn to face them (of equally
  open ways, the one needing least turning) and 3 m for each time the robot has already faced that way from
  about here (cells of 2 m in the odometry frame, 8 headings; driving on in one cell and heading counts once):
  it goes forward when the best sector is within half a turn ahead (22.5 deg, and 5 deg of margin so that it
  does not turn back and forth across a direction between two headings) and the way ahead is clear, and turns
  toward it otherwise. Corridors are driven to their ends and rooms are looked into, which is where look-alike
  places differ;
- ``trained``: a stable-baselines3 policy loaded from a ``.zip`` (``python -m training policy`` writes one),
  acting deterministically; the name ``trained`` is the shipped one (``SHIPPED_POLICY``, its record beside it).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Protocol

import numpy as np

from pimm_agents.active.primitives import PRIMITIVES, STOP_RANGE, blocked_ahead
from pimm_env.geometry import wrap_angle

FORWARD, LEFT, RIGHT = 0, 1, 2
#: about what each turn primitive turns (rad; squared up with the walls, it may turn up to 22.5 deg more or less)
TURNS = {i: p.angular * p.duration for i, p in enumerate(PRIMITIVES) if p.angular != 0.0}
#: the shipped policy (``trained``), beside the record of how it was trained (``.json``)
SHIPPED_POLICY = Path(__file__).resolve().parent / "weights" / "active_ppo.zip"


class Policy(Protocol):
    name: str

    def reset(self, seed: int | None = None) -> None: ...

    def __call__(self, observation: dict[str, np.ndarray]) -> int: ...


def sector_bearings(n: int) -> np.ndarray:
    """The centres of the ``scan`` observation's ``n`` sectors (robot frame, from behind, counter-clockwise)."""
    return -np.pi + (np.arange(n) + 0.5) * 2 * np.pi / n


def sectors_blocked(scan: np.ndarray, stop_range: float = STOP_RANGE, turn: float = 0.0) -> bool:
    """The forward guard's test (``blocked_ahead``) on the ``scan`` observation's sectors (ranges in metres),
    each sector's nearest return taken at its centre and at both its edges: the guard itself reads every beam,
    and a return near a sector's edge, tested at the centre only, fell outside the lane the body sweeps while the
    guard stopped the robot at it (a policy chose forward three times at a pillar and stood). With ``turn``
    (rad), the test after turning that much on the spot."""
    n = len(scan)
    half = np.pi / n
    bearings = np.concatenate([sector_bearings(n) + k * half - turn for k in (-1, 0, 1)])
    return blocked_ahead(np.tile(np.asarray(scan, dtype=float), 3), bearings, stop_range)


class RandomWalk:
    name = "random"

    def __init__(self) -> None:
        self.rng = np.random.default_rng()

    def reset(self, seed: int | None = None) -> None:
        self.rng = np.random.default_rng(seed)

    def __call__(self, observation: dict[str, np.ndarray]) -> int:
        return int(self.rng.choice([FORWARD, FORWARD, LEFT, RIGHT]))


class Explorer:
    """The ``greedy`` baseline's exploring (see the module docstring); on its own, it is what ``greedy`` does
    without a map."""

    name = "greedy"
    CELL_M = 2.0
    HEADINGS = 8
    OPEN_M = 8.0
    SEEN_PENALTY_M = 3.0  # free range (m) a direction loses for each time it was already faced from here
    AHEAD_MARGIN = np.radians(5.0)
    TURN_COST_M = 0.5  # per radian of turn to face a direction

    def __init__(self, max_range: float = 20.0) -> None:
        self.max_range = max_range
        self.reset()

    def reset(self, seed: int | None = None) -> None:
        self.pose = np.zeros(3)  # dead-reckoned from the odometry increments, in the episode's own frame
        self.faced: dict[tuple[int, int, int], int] = {}
        self.last_faced: tuple[int, int, int] | None = None

    def __call__(self, observation: dict[str, np.ndarray]) -> int:
        dx, dy, dtheta = np.asarray(observation["odom_delta"], dtype=float) * np.array([1.0, 1.0, np.pi])
        c, s = np.cos(self.pose[2]), np.sin(self.pose[2])
        self.pose = np.array([self.pose[0] + c * dx - s * dy, self.pose[1] + s * dx + c * dy, self.pose[2] + dtheta])
        scan = np.asarray(observation["scan"], dtype=float) * self.max_range
        n = len(scan)
        bearings = sector_bearings(n)
        cell = (int(np.floor(self.pose[0] / self.CELL_M)), int(np.floor(self.pose[1] / self.CELL_M)))
        # open range up to OPEN_M, less a little per radian off ahead: of directions equally open (beyond OPEN_M
        # many are), the one needing the least turning wins, instead of the first sector's (behind the robot)
        score = np.minimum(scan, self.OPEN_M) - self.TURN_COST_M * np.abs(bearings)
        for i, bearing in enumerate(bearings):
            score[i] -= self.SEEN_PENALTY_M * self.faced.get((*cell, self._heading_bin(self.pose[2] + bearing)), 0)
        best = float(bearings[int(np.argmax(score))])
        facing = (*cell, self._heading_bin(self.pose[2]))
        if facing != self.last_faced:  # driving on in one cell and heading faces that way once, not at every step
            self.faced[facing] = self.faced.get(facing, 0) + 1
            self.last_faced = facing
        # within half a turn (and a margin: a best direction half a turn off either way would otherwise have the
        # robot turn back and forth across it) and clear ahead, in the cone and in the lane the body sweeps (with
        # the cone alone it chose forward, stopped by the guard, for the rest of an episode): drive on
        if abs(best) <= np.pi / 8 + self.AHEAD_MARGIN and not sectors_blocked(scan, STOP_RANGE + 0.2):
            return FORWARD
        return LEFT if best > 0 else RIGHT

    def _heading_bin(self, heading: float) -> int:
        return int(np.floor((wrap_angle(heading) + np.pi) / (2 * np.pi) * self.HEADINGS)) % self.HEADINGS


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

    def __init__(self, path: Path) -> None:
        from stable_baselines3 import PPO

        from pimm_env.errors import MissingFileError

        if not Path(path).is_file():
            raise MissingFileError(f"policy {path} does not exist (python -m training policy writes one)")
        self.model: Any = PPO.load(str(path), device="cpu")
        self.name = "trained" if Path(path).resolve() == SHIPPED_POLICY else Path(path).stem

    def reset(self, seed: int | None = None) -> None:
        pass

    def __call__(self, observation: dict[str, np.ndarray]) -> int:
        action, _ = self.model.predict(observation, deterministic=True)
        return int(np.asarray(action).item())


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
    return Trained(SHIPPED_POLICY if name == "trained" else Path(name))
