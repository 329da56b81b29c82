"""Faults as Gymnasium wrappers: what breaks on a real robot, at set times of a run.

- ``LidarDropout``: both LiDARs return nothing for a while (cloud all masked, scan at maximum range, the
  stamps still advancing, as a driver that publishes empty scans does).
- ``OdometrySlip``: for a while the wheels slip: the odometry over-reports the distance driven by
  ``scale`` and turns by ``yaw_rate`` rad/s more than the robot does, so the heading it carries stays wrong.
- ``Kidnaps``: at each given time the robot is teleported without the odometry knowing
  (``reset(options={"kidnap": ...})`` of the env): given the route it is driving, to a random point of it at
  least 5 m (along the route) from where the robot is, heading along the route, and the driver carries on
  from there (``driving.rollout.drive``); without one, to a random free pose. ``kidnap@T:anywhere`` lands
  anywhere in the free space, half the time in a twin of the place left (``driving/landings.py``), and gives
  the driver a route from there (``info["route"]``). ``info["kidnapped"]`` marks the step, so a recorder can
  count the metrics from it.

``parse_faults("dropout@30:5,slip@20:3,kidnap@40,kidnap@70:anywhere")`` reads the command line's form:
NAME@START[:DURATION] (a kidnap's second part: where it lands, ``route`` or ``anywhere``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np

from pimm_env.errors import EnvError
from pimm_env.geometry import compose, relative_motion, wrap_angle
from pimm_env.world.polyline import nearest_on_path

FAULTS = ("dropout", "slip", "kidnap")
LANDINGS = ("route", "anywhere")


@dataclass(frozen=True)
class Fault:
    kind: str  # one of FAULTS
    start_s: float
    duration_s: float = 0.0
    landing: str = "route"  # a kidnap's: one of LANDINGS

    def active(self, t: float) -> bool:
        return self.start_s <= t < self.start_s + self.duration_s


def parse_faults(text: str) -> list[Fault]:
    """Faults from ``NAME@START[:DURATION]`` items separated by commas (dropout and slip need a duration)."""
    faults = []
    for item in filter(None, (part.strip() for part in text.split(","))):
        name, _, when = item.partition("@")
        if name not in FAULTS or not when:
            raise EnvError(f"fault {item!r}: expected NAME@START[:DURATION] with NAME one of {', '.join(FAULTS)}")
        start, _, duration = when.partition(":")
        landing = "route"
        if name == "kidnap" and duration:
            if duration not in LANDINGS:
                where = ", ".join(LANDINGS)
                raise EnvError(f"fault {item!r}: a kidnap lands on one of {where}, e.g. kidnap@40:anywhere")
            landing, duration = duration, ""
        try:
            fault = Fault(name, float(start), float(duration) if duration else 0.0, landing)
        except ValueError:
            raise EnvError(f"fault {item!r}: START and DURATION must be numbers (seconds)") from None
        if not (np.isfinite(fault.start_s) and fault.start_s >= 0 and np.isfinite(fault.duration_s)):
            raise EnvError(f"fault {item!r}: START must be >= 0 s and DURATION finite")
        if name in ("dropout", "slip") and fault.duration_s <= 0:
            raise EnvError(f"fault {item!r}: a {name} needs a duration, e.g. {name}@30:5")
        faults.append(fault)
    return faults


#: a kidnap trial's kidnap comes at a seeded time in this window (s): after a global start has been localized
#: (PIMM's median is under 10 s) and while the shortest generated route (30 m at 0.5 m/s) is still driven
KIDNAP_WINDOW_S = (20.0, 35.0)


def kidnap_trial_fault(seed: int) -> str:
    """The fault of a kidnap trial with ``seed``: one kidnap, landing anywhere, at a time drawn from ``seed``."""
    start = np.random.default_rng([seed, 7]).uniform(*KIDNAP_WINDOW_S)
    return f"kidnap@{start:.1f}:anywhere"


def with_faults(env: gym.Env, faults: list[Fault], route: np.ndarray | None = None) -> gym.Env:
    """``env`` wrapped in one wrapper per kind of fault asked for (kidnaps land on ``route`` if given)."""
    by_kind = {kind: [f for f in faults if f.kind == kind] for kind in FAULTS}
    if by_kind["slip"]:
        env = OdometrySlip(env, by_kind["slip"])
    if by_kind["dropout"]:
        env = LidarDropout(env, by_kind["dropout"])
    if by_kind["kidnap"]:
        env = Kidnaps(env, by_kind["kidnap"], route)
    return env


def _time(obs: dict[str, np.ndarray]) -> float:
    return float(np.asarray(obs["time"]).reshape(-1)[0])


class LidarDropout(gym.Wrapper):
    def __init__(self, env: gym.Env, windows: list[Fault]) -> None:
        super().__init__(env)
        self.windows = windows
        self.max_range = float(env.observation_space["scan"].high.max())  # type: ignore[index]

    def _blank(self, obs: dict[str, np.ndarray], info: dict[str, Any]) -> dict[str, np.ndarray]:
        if not any(w.active(_time(obs)) for w in self.windows):
            return obs
        info["fault"] = "dropout"
        obs = dict(obs)
        obs["cloud"] = np.zeros_like(obs["cloud"])
        obs["cloud_mask"] = np.zeros_like(obs["cloud_mask"])
        obs["scan"] = np.full_like(obs["scan"], self.max_range)
        return obs

    def reset(self, **kwargs: Any):
        obs, info = self.env.reset(**kwargs)
        return self._blank(obs, info), info

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        return self._blank(obs, info), reward, terminated, truncated, info


class OdometrySlip(gym.Wrapper):
    def __init__(self, env: gym.Env, bursts: list[Fault], scale: float = 0.3, yaw_rate: float = 0.1) -> None:
        super().__init__(env)
        self.bursts, self.scale, self.yaw_rate = bursts, scale, yaw_rate
        self._inner: np.ndarray | None = None  # the env's odometry at the last step
        self._odom = np.zeros(3)  # what we report
        self._time = 0.0

    def reset(self, **kwargs: Any):
        obs, info = self.env.reset(**kwargs)
        options = kwargs.get("options") or {}
        if options.get("kidnap") in (None, False):  # a full reset: the odometry starts again
            self._odom = np.asarray(obs["odom"], dtype=float).copy()
        self._inner, self._time = np.asarray(obs["odom"], dtype=float).copy(), _time(obs)
        return self._report(obs), info

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        inner, t = np.asarray(obs["odom"], dtype=float), _time(obs)
        delta = relative_motion(self._inner, inner) if self._inner is not None else np.zeros(3)
        if any(b.active(t) for b in self.bursts):
            info["fault"] = "slip"
            delta = delta * [1 + self.scale, 1 + self.scale, 1.0]
            delta[2] += self.yaw_rate * max(t - self._time, 0.0)
        self._odom = compose(self._odom, delta)[0]
        self._odom[2] = wrap_angle(self._odom[2])
        self._inner, self._time = inner.copy(), t
        return self._report(obs), reward, terminated, truncated, info

    def _report(self, obs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        obs = dict(obs)
        obs["odom"] = self._odom.astype(obs["odom"].dtype)
        return obs


class Kidnaps(gym.Wrapper):
    #: the least distance along the route between where the robot was and where it lands
    MIN_JUMP_M = 5.0

    def __init__(self, env: gym.Env, kidnaps: list[Fault], route: np.ndarray | None = None) -> None:
        super().__init__(env)
        self.kidnaps = sorted(kidnaps, key=lambda f: f.start_s)
        self.route = None if route is None else np.asarray(route, dtype=float).reshape(-1, 2)
        self._next = 0
        self._landings: Any = None  # driving.landings.Landings, made at the first kidnap that lands anywhere

    def reset(self, **kwargs: Any):
        options = kwargs.get("options") or {}
        if options.get("kidnap") in (None, False):
            self._next = 0
        return self.env.reset(**kwargs)

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        if self._next < len(self.kidnaps) and _time(obs) >= self.kidnaps[self._next].start_s:
            fault = self.kidnaps[self._next]
            self._next += 1
            pose, route = np.asarray(info["true_pose"], dtype=float), {}
            if fault.landing == "anywhere":
                target, waypoints, kind = self._anywhere(pose)
                route = {"route": waypoints, "landing": kind}
            else:
                target = True if self.route is None else self._along_route(pose)
            obs, kidnapped = self.env.reset(options={"kidnap": target})
            info = {**info, **kidnapped, **route, "kidnapped": True}
        return obs, reward, terminated, truncated, info

    def _anywhere(self, pose: np.ndarray) -> tuple[list[float], np.ndarray, str]:
        """A landing anywhere (``driving.landings``), drawn from the env's seeded generator."""
        if self._landings is None:
            from pimm_env.driving.landings import Landings
            from pimm_env.mapping.twins import world_twins

            base = self.env.unwrapped
            twins, _ = world_twins(base.world, base.maps.occupancy)  # type: ignore[attr-defined]
            self._landings = Landings(base.maps.occupancy, twins)  # type: ignore[attr-defined]
        target, waypoints, kind = self._landings.draw(pose, self.env.unwrapped.np_random)
        return [float(v) for v in target], waypoints, kind

    def _along_route(self, pose: np.ndarray) -> list[float]:
        """A random pose on the route, at least ``MIN_JUMP_M`` along it from the robot, heading along it."""
        assert self.route is not None
        a, ab = self.route[:-1], np.diff(self.route, axis=0)
        lengths = np.hypot(ab[:, 0], ab[:, 1])
        ends = np.cumsum(lengths)
        _, _, at = nearest_on_path(self.route, pose)
        rng = self.env.unwrapped.np_random  # the env's seeded generator: the same trial lands in the same place
        s = float(rng.uniform(0, ends[-1]))
        for _ in range(20):
            if abs(s - at) >= self.MIN_JUMP_M:
                break
            s = float(rng.uniform(0, ends[-1]))
        j = int(np.clip(np.searchsorted(ends, s), 0, len(lengths) - 1))
        point = a[j] + (s - (ends[j] - lengths[j])) / max(lengths[j], 1e-12) * ab[j]
        return [float(point[0]), float(point[1]), float(np.arctan2(ab[j, 1], ab[j, 0]))]
