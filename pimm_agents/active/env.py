"""``pimm/ActiveLocalization-v0``: drive so that a localizer becomes right and sure, quickly.

The task env wraps the simulator (:class:`pimm_env.envs.iilab_env.IILabEnv`) and a localizer (by name, as
``make_localizer`` builds it). Each step drives one motion primitive (:mod:`pimm_agents.active.primitives`),
feeding every control step's observation to the localizer; the policy then sees what a robot would know.

Observation (``spaces.Dict``, fixed shapes, every value in [-1, 1] or [0, 1]; the truth never appears):

- ``hypotheses`` (K, 6): the localizer's best K hypotheses (heaviest first, zero rows when fewer), each relative
  to its current estimate (the robot's own belief of where it is): offset x and y in the estimate's frame over
  ``max_offset_m`` (clipped), sine and cosine of the heading difference, weight, and the log of the position
  standard deviation over 5 (clipped). A rival place the filter holds no particles at has weight 0;
- ``status``: one-hot ``lost``, ``ambiguous``, ``localized``;
- ``scan``: the 2D LiDAR's ranges over ``scan_beams`` equal sectors (the nearest in each), over its maximum range;
- ``odom_delta``: the last primitive's wheel-odometry motion in the robot's frame at its start (x and y over 1 m,
  heading over pi);
- ``guide``: where to drive to tell the hypotheses apart, from the map and the belief (guide.py): sine and
  cosine of the bearing of the next waypoint toward the place that tells the estimate from the most of its
  twins (or, when none does, the nearby place whose predicted views differ most between the hypotheses), the
  share of twins that place tells apart (or its gain; 0..1), and 1 when there is such a place (all 0 when the
  status is not ``ambiguous`` or no place tells anything apart);
- ``explore``: one-hot, the primitive that heads for the most open direction the robot has not yet faced from
  about where it is (explorer.py; from the scan and the odometry increments alone): where to look when the guide
  shows nothing;
- ``last_action``: one-hot, the primitive just driven (all 0 at the start of an episode).

``explore`` and ``last_action`` are the memory a policy over this one observation lacks: the ``greedy`` baseline
keeps both itself (what it has faced, and which way it last turned), and a policy imitating it without them chose
as it did in 87 % of its steps.

Action: ``Discrete(3)``, the primitives forward 0.5 m, turn left about 45 deg, turn right about 45 deg, a turn
squared up with the walls the 2D scan sees (why primitives, and why squared: see primitives.py).

Reward per step, with the weights of :class:`ActiveConfig` (the truth is used here, never in the observation):

- ``progress`` x the change of the belief's weight near the truth (hypotheses within 1 m and 10 deg of it);
- ``+localized_bonus`` the first time the status is ``localized`` while right (within 1 m and 10 deg);
- ``-false_localized`` per second reported ``localized`` while wrong;
- ``-collision`` on touching an obstacle (the episode ends);
- ``-time`` per simulated second;
- ``+distance`` per metre driven: both LiDARs see all around, so only moving shows the scans anything new (a
  turn on the spot shows the same room); without it, a policy trained for 7 680 steps learned to turn on the
  spot, which is safe and lets the localizer settle in some buildings, and drove 0.05 m a minute.

An episode starts at a random free pose (``reset(seed=...)``), or, with ``options={"kidnap": True}`` (or
``ActiveConfig.kidnap``), with the localizer holding the pose it started at for ``hold_s`` and the robot then
carried to another random free pose. It ends (terminated) when a right ``localized`` has held for ``hold_s`` or
on a collision, and is truncated at ``time_limit_s`` of simulated time.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from pimm_agents.active.explorer import Explorer
from pimm_agents.active.guide import GUIDE_SIZE, Guide
from pimm_agents.active.primitives import PRIMITIVES, drive
from pimm_agents.localizer import PoseEstimate
from pimm_agents.scoring.honesty import RIGHT_ANGLE_DEG, RIGHT_POSITION_M
from pimm_env.errors import EnvError
from pimm_env.geometry import relative_motion, wrap_angle

STATUS_ORDER = ("lost", "ambiguous", "localized")
RIGHT_M = RIGHT_POSITION_M  # a pose within this (and RIGHT_DEG) of the truth is right, as the honest metrics say
RIGHT_DEG = RIGHT_ANGLE_DEG


@dataclass(frozen=True)
class ActiveConfig:
    """Ours."""

    hypotheses: int = 5  # K: the belief's best modes the policy sees
    scan_beams: int = 60
    max_offset_m: float = 30.0
    time_limit_s: float = 60.0  # the "within 60 s"
    hold_s: float = 2.0  # a right localized held this long ends the episode
    kidnap: bool = False
    progress: float = 1.0
    localized_bonus: float = 10.0
    false_localized: float = 1.0  # per second
    collision: float = 10.0
    time: float = 0.1  # per second
    distance: float = 0.2  # per metre driven: a full forward primitive (0.5 m) makes up for its second

    def __post_init__(self) -> None:
        if self.hypotheses < 1 or self.scan_beams < 1:
            raise EnvError("active: hypotheses and scan_beams must be at least 1")
        if self.time_limit_s <= 0 or self.hold_s < 0 or self.max_offset_m <= 0:
            raise EnvError("active: time_limit_s and max_offset_m must be positive, hold_s at least 0")


def right(pose: np.ndarray, truth: np.ndarray) -> bool:
    """Whether ``pose`` (x, y, theta) is within 1 m and 10 deg of ``truth``."""
    return bool(
        np.hypot(pose[0] - truth[0], pose[1] - truth[1]) <= RIGHT_M
        and abs(wrap_angle(pose[2] - truth[2])) <= np.radians(RIGHT_DEG)
    )


def weight_near(estimate: PoseEstimate, truth: np.ndarray) -> float:
    """The share of the belief within 1 m and 10 deg of the truth (the estimate itself when it keeps no modes)."""
    if not estimate.hypotheses:
        return float(right(np.array([estimate.x, estimate.y, estimate.theta]), truth))
    total = sum(h.weight for h in estimate.hypotheses)
    near = sum(h.weight for h in estimate.hypotheses if right(np.array([h.x, h.y, h.theta]), truth))
    return float(near / total) if total > 0 else 0.0


def belief_features(estimate: PoseEstimate | None, k: int, max_offset: float) -> np.ndarray:
    """The ``hypotheses`` observation (K, 6) of an estimate (see the module docstring)."""
    out = np.zeros((k, 6), dtype=np.float32)
    if estimate is None:
        return out
    hypotheses = estimate.hypotheses or ()
    if not hypotheses:
        from pimm_agents.localizer import Hypothesis

        hypotheses = (Hypothesis(estimate.x, estimate.y, estimate.theta, 1.0, estimate.covariance),)
    c, s = np.cos(estimate.theta), np.sin(estimate.theta)
    for i, h in enumerate(hypotheses[:k]):
        dx, dy = h.x - estimate.x, h.y - estimate.y
        turn = wrap_angle(h.theta - estimate.theta)
        spread = float(np.sqrt(max(np.trace(np.asarray(h.covariance)[:2, :2]) / 2.0, 1e-12)))
        out[i] = (
            np.clip((c * dx + s * dy) / max_offset, -1, 1),
            np.clip((-s * dx + c * dy) / max_offset, -1, 1),
            np.sin(turn),
            np.cos(turn),
            np.clip(h.weight, 0, 1),
            np.clip(np.log(spread) / 5.0, -1, 1),
        )
    return out


def scan_sectors(scan: np.ndarray, beams: int, max_range: float) -> np.ndarray:
    """The nearest range in each of ``beams`` equal sectors of the scan, over the maximum range."""
    edges = np.linspace(0, len(scan), beams + 1).round().astype(int)
    nearest = np.array([scan[a:b].min() if b > a else max_range for a, b in itertools.pairwise(edges)])
    return np.clip(nearest / max_range, 0.0, 1.0).astype(np.float32)


def active_observation(
    estimate: PoseEstimate | None,
    scan: np.ndarray,
    delta: np.ndarray,
    config: ActiveConfig,
    max_range: float,
    guide: np.ndarray | None = None,
    explorer: Explorer | None = None,
    last_action: int | None = None,
) -> dict[str, np.ndarray]:
    """The env's observation (see the module docstring) from a localizer's ``estimate``, the 2D ``scan``
    (ranges), the last primitive's odometry ``delta`` (x, y, heading in the robot's frame at its start), the
    ``guide`` (guide.py's :class:`~pimm_agents.active.guide.Guide`; none shown when None), the episode's
    ``explorer`` (called once here, it moves on by ``delta``; no ``explore`` shown when None) and the primitive
    just driven (None at an episode's start)."""
    status = np.zeros(len(STATUS_ORDER), dtype=np.float32)
    if estimate is not None:
        status[STATUS_ORDER.index(estimate.status)] = 1.0
    observation = {
        "hypotheses": belief_features(estimate, config.hypotheses, config.max_offset_m),
        "status": status,
        "scan": scan_sectors(np.asarray(scan, dtype=float), config.scan_beams, max_range),
        "odom_delta": np.clip(np.array([delta[0], delta[1], delta[2] / np.pi]), -1, 1).astype(np.float32),
        "guide": np.zeros(GUIDE_SIZE, dtype=np.float32) if guide is None else np.asarray(guide, dtype=np.float32),
    }
    observation["explore"] = one_hot(None if explorer is None else explorer(observation))
    observation["last_action"] = one_hot(last_action)
    return observation


def one_hot(action: int | None) -> np.ndarray:
    """A primitive as a one-hot vector (all 0 for None)."""
    out = np.zeros(len(PRIMITIVES), dtype=np.float32)
    if action is not None:
        out[action] = 1.0
    return out


class ActiveLocalizationEnv(gym.Env):
    """See the module docstring."""

    metadata = {"render_modes": []}

    def __init__(
        self,
        world: Any = "iilab",
        localizer: str = "pimm",
        config: ActiveConfig | None = None,
        params: dict[str, Any] | None = None,
    ) -> None:
        from pimm_agents.factory import make_localizer
        from pimm_env.envs.base_env import SimConfig
        from pimm_env.envs.iilab_env import IILabEnv
        from pimm_env.sim.lidar import beam_bearings_2d
        from pimm_env.world.files import World, load_world

        self.config = config or ActiveConfig()
        loaded = world if isinstance(world, World) else load_world(world)
        self.localizer = make_localizer(localizer, loaded, params=params)
        sim_config = SimConfig()
        if "cloud" not in getattr(self.localizer, "sensors", ("cloud",)):
            from dataclasses import replace

            sim_config = replace(sim_config, lidar3d=replace(sim_config.lidar3d, enabled=False))
        self.sim = IILabEnv(world=loaded, config=sim_config, terminate_on_collision=False)
        self._bearings = beam_bearings_2d(sim_config.lidar2d)
        self._max_range = float(sim_config.lidar2d.max_range)
        k, c = self.config.hypotheses, self.config
        self.action_space = spaces.Discrete(len(PRIMITIVES))
        self.observation_space = spaces.Dict(
            {
                "hypotheses": spaces.Box(-1.0, 1.0, (k, 6), np.float32),
                "status": spaces.Box(0.0, 1.0, (len(STATUS_ORDER),), np.float32),
                "scan": spaces.Box(0.0, 1.0, (c.scan_beams,), np.float32),
                "odom_delta": spaces.Box(-1.0, 1.0, (3,), np.float32),
                "guide": spaces.Box(-1.0, 1.0, (GUIDE_SIZE,), np.float32),
                "explore": spaces.Box(0.0, 1.0, (len(PRIMITIVES),), np.float32),
                "last_action": spaces.Box(0.0, 1.0, (len(PRIMITIVES),), np.float32),
            }
        )
        self.guide = Guide(self.sim.maps.occupancy)
        self.explorer = Explorer(self._max_range)
        self._last_action: int | None = None
        self._obs: dict[str, np.ndarray] = {}
        self._estimate: PoseEstimate | None = None
        self._truth = np.zeros(3)
        self._start_time = 0.0
        self._held_since: float | None = None
        self._rewarded = False
        self._near = 0.0
        self._false_s = 0.0  # seconds reported localized while wrong, this episode
        self._first_right: float | None = None  # episode time of the first right localized
        self._travelled0 = 0.0

    @property
    def scan_range(self) -> float:
        """The 2D LiDAR's maximum range (m): the ``scan`` observation's 1.0."""
        return self._max_range

    # ------------------------------------------------------------------ gymnasium API
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        options = dict(options or {})
        unknown = set(options) - {"kidnap", "pose"}
        if unknown:
            raise EnvError(f"unknown reset option(s) {sorted(unknown)}; valid: ['kidnap', 'pose']")
        sim_seed = int(self.np_random.integers(2**31))
        obs, info = self.sim.reset(seed=sim_seed, options={"pose": options["pose"]} if "pose" in options else None)
        kidnap = options.get("kidnap", self.config.kidnap)
        if not isinstance(kidnap, (bool, np.bool_)):  # "false" is a truthy string: refused, not taken as yes
            raise EnvError(f"reset option 'kidnap' is True or False, got {kidnap!r}")
        if kidnap:  # the localizer holds the start pose, then the robot is carried elsewhere
            self.localizer.reset(seed=sim_seed, initial_pose=np.asarray(info["true_pose"], dtype=float))
            for _ in range(max(1, round(self.config.hold_s / self.sim.config.robot.control_dt))):
                obs, _, _, _, info = self.sim.step(np.zeros(2, dtype=np.float32))
                self._estimate = self.localizer.update(obs)
            obs, info = self.sim.reset(options={"kidnap": True})
        else:
            self.localizer.reset(seed=sim_seed)
        self._estimate = self.localizer.update(obs)
        self._obs, self._truth = obs, np.asarray(info["true_pose"], dtype=float)
        self._start_time = self.sim.sim_time
        self._held_since, self._rewarded = None, False
        self._false_s, self._first_right = 0.0, None
        self._travelled0 = float(info["travelled"])
        self.guide.reset()
        self.explorer.reset()
        self._last_action = None
        self._near = weight_near(self._estimate, self._truth)
        return self._observation(np.zeros(3)), self._info(info)

    def step(self, action: Any):
        value: Any = np.asarray(action).item() if np.size(action) == 1 else None
        whole = isinstance(value, (int, np.integer)) or (isinstance(value, float) and value.is_integer())
        if not whole or not self.action_space.contains(int(value)):  # 1.7 is no primitive, not primitive 1
            raise EnvError(
                f"action {action!r}: must be one of 0..{len(PRIMITIVES) - 1} ({', '.join(p.name for p in PRIMITIVES)})"
            )
        self._last_action = int(value)
        primitive = PRIMITIVES[self._last_action]
        c, dt = self.config, self.sim.config.robot.control_dt
        odom_start = np.asarray(self._obs["odom"], dtype=float).copy()
        travelled_before = self.sim.robot.travelled
        false_s, collided = 0.0, False
        done = False

        def on_step(obs: dict[str, np.ndarray], info: dict[str, Any]) -> bool:
            nonlocal false_s, collided, done
            self._estimate = self.localizer.update(obs)
            self._truth = np.asarray(info["true_pose"], dtype=float)
            pose = np.array([self._estimate.x, self._estimate.y, self._estimate.theta])
            localized = self._estimate.status == "localized"
            if localized and not right(pose, self._truth):
                false_s += dt
            if localized and right(pose, self._truth):
                self._held_since = self.sim.sim_time if self._held_since is None else self._held_since
                self._first_right = self._elapsed() if self._first_right is None else self._first_right
            else:
                self._held_since = None
            collided = collided or bool(info["collision"])
            done = collided or self._held_long_enough() or self._elapsed() >= c.time_limit_s
            return done

        obs, info, _, _ = drive(self.sim, primitive, self._obs, on_step, self._bearings)
        self._obs = obs
        near = weight_near(self._estimate, self._truth) if self._estimate is not None else 0.0
        driven = self.sim.robot.travelled - travelled_before
        reward = (
            c.progress * (near - self._near)
            - c.time * primitive.duration
            - c.false_localized * false_s
            + c.distance * driven
        )
        self._near = near
        self._false_s += false_s
        if self._held_since is not None and not self._rewarded:
            reward += c.localized_bonus
            self._rewarded = True
        if collided:
            reward -= c.collision
        terminated = collided or self._held_long_enough()
        truncated = not terminated and self._elapsed() >= c.time_limit_s
        delta = relative_motion(odom_start, np.asarray(obs["odom"], dtype=float))
        return self._observation(delta), float(reward), bool(terminated), bool(truncated), self._info(info)

    def close(self) -> None:
        self.sim.close()

    # ------------------------------------------------------------------ internals
    def _elapsed(self) -> float:
        return self.sim.sim_time - self._start_time

    def _held_long_enough(self) -> bool:
        return self._held_since is not None and self.sim.sim_time - self._held_since >= self.config.hold_s

    def _observation(self, delta: np.ndarray) -> dict[str, np.ndarray]:
        scan = np.asarray(self._obs["scan"], dtype=float)
        guide = self.guide(self._estimate, scan, self._bearings, delta)
        return active_observation(
            self._estimate, scan, delta, self.config, self._max_range, guide, self.explorer, self._last_action
        )

    def _info(self, sim_info: dict[str, Any]) -> dict[str, Any]:
        estimate = self._estimate
        return {
            "true_pose": np.asarray(sim_info["true_pose"], dtype=float).copy(),
            "collision": bool(sim_info.get("collision", False)),
            "status": None if estimate is None else estimate.status,
            "estimate": None if estimate is None else np.array([estimate.x, estimate.y, estimate.theta]),
            "elapsed_s": self._elapsed(),
            "right_localized": self._held_since is not None,
            "first_right_localized_s": self._first_right,
            "false_localized_s": self._false_s,
            "distance_m": self.sim.robot.travelled - self._travelled0,
        }
