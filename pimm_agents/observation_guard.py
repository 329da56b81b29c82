"""What every localizer does with an observation before it touches its state: check it, and set glitches aside.

- A missing key, a wrong shape or a non-finite value raises ``ValueError`` naming the key (and the shape), before
  any state changes, so the localizer goes on as if the observation had never come.
- A glitch is set aside and the last estimate kept: a stamp that goes back, or jumps further ahead than
  ``max_gap_s``; odometry that moved faster than the robot can (``max_speed``, ``max_turn_rate``) since the last
  observation taken, allowing ``STAMP_JITTER_S`` for stamps that lag the motion (bursty logs). A sensor stamp
  ahead of the observation's own time (``STAMP_SLACK_S``) marks that sensor's data as not fresh.
- A change that lasts is a new base, not a glitch: after ``CONFIRM`` observations in a row agree with each other
  (the odometry frame was reset, a bag paused), they are taken, the odometry re-anchored so that the jump counts
  as no motion.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from pimm_agents.localizer import Observation, PoseEstimate, require
from pimm_env.errors import ObservationError
from pimm_env.geometry import compose, relative_motion

#: A sensor stamp this far (s) ahead of the observation's own time marks that sensor's data as not fresh (ours).
STAMP_SLACK_S = 0.5
#: Observations in a row that agree with each other after a jump make a new base, not a glitch (ours).
CONFIRM = 5
#: Odometry may be stamped this far (s) from when it was measured (robots that log it in bursts a few ms apart):
#: the speed limits allow for that much more time between two observations (measured: docs/design.md#the-guard).
STAMP_JITTER_S = 0.2


@dataclass(frozen=True)
class GuardConfig:
    """Ours; the speed limits are three times the simulated robot's (1 m/s, 2 rad/s). Every localizer takes
    them from its params' ``guard`` section (``pimm.guard.max_speed``, ``amcl.guard.max_speed``, ...)."""

    max_gap_s: float = 30.0  # ours: a stamp further ahead than this is a glitch
    max_speed: float = 3.0  # ours, m/s
    max_turn_rate: float = 6.0  # ours, rad/s

    def __post_init__(self) -> None:
        for name in ("max_gap_s", "max_speed", "max_turn_rate"):
            if not getattr(self, name) > 0:
                raise ObservationError(f"guard.{name} must be positive, got {getattr(self, name)}")


class ObservationGuard:
    """One per localizer; ``take(obs)`` returns the observation to use (odometry re-anchored) or None."""

    def __init__(self, config: GuardConfig | None = None) -> None:
        self.config = config or GuardConfig()
        self.reset()

    def reset(self) -> None:
        self.last_time: float | None = None
        self.last_odom: np.ndarray | None = None  # raw, as the last taken observation had it
        self.offset = np.zeros(3)  # corrected odometry = compose(offset, raw odometry)
        self._pending: list[tuple[float, np.ndarray]] = []  # set-aside observations that agree with each other
        #: observations set aside, by kind: ``stamp_back``, ``stamp_gap`` (beyond max_gap_s), ``too_fast``
        self.set_aside: dict[str, int] = {}
        self.rebases = 0  # lasting jumps taken as a new base (the jump counted as no motion)

    def check(self, obs: Observation, keys: tuple[str, ...]) -> None:
        """Raise ``ValueError`` naming the key unless every one of ``keys`` is present, shaped and finite."""
        shapes = {"odom": (3,), "time": (1,), "cloud_time": (1,), "scan_time": (1,)}
        for key in keys:
            self.finite(key, require(obs, key, shapes.get(key)))

    @staticmethod
    def finite(key: str, value: np.ndarray) -> None:
        """Raise ``ValueError`` naming ``key`` and the shape if ``value`` holds a NaN or an infinity."""
        if not np.all(np.isfinite(value)):
            bad = int(np.count_nonzero(~np.isfinite(value)))
            raise ObservationError(f"observation {key!r} (shape {value.shape}) has {bad} non-finite value(s)")

    def cloud(self, obs: Observation) -> tuple[np.ndarray, np.ndarray]:
        """The observation's 3D cloud as float32 (N, 3) and its mask as bool (N,), checked: a missing key, a
        wrong shape or a non-finite point raises, naming the key and the shape."""
        if "cloud" not in obs:
            raise ObservationError(f"observation has no 'cloud' (keys: {sorted(obs)})")
        cloud = np.asarray(obs["cloud"], dtype=np.float32)  # one conversion, checked here, not twice
        if cloud.ndim != 2 or cloud.shape[1] != 3:
            raise ObservationError(f"observation 'cloud' has shape {cloud.shape}, expected (N, 3) points")
        self.finite("cloud", cloud)
        return cloud, require(obs, "cloud_mask", (len(cloud),)).astype(bool)

    def take(self, obs: Observation) -> Observation | None:
        """The observation with its odometry re-anchored, or None for a glitch (the localizer keeps its estimate)."""
        t = float(np.asarray(obs["time"]).reshape(-1)[0])
        odom = np.asarray(obs["odom"], dtype=float).reshape(3)
        if self.last_time is None or self.last_odom is None:
            return self._accept(obs, t, odom)
        fault = self._fault(self.last_time, self.last_odom, t, odom)
        if fault is None:
            self._pending.clear()
            return self._accept(obs, t, odom)
        self.set_aside[fault] = self.set_aside.get(fault, 0) + 1
        if self._pending and self._fault(*self._pending[-1], t, odom) is not None:
            self._pending.clear()
        self._pending.append((t, odom))
        if len(self._pending) < CONFIRM:
            return None
        # A new base: the jump from the last taken observation to the first of these counts as no motion.
        _, first_odom = self._pending[0]
        before = compose(self.offset, self.last_odom)[0]  # where the corrected odometry stood
        self.offset = compose(before, relative_motion(first_odom, np.zeros(3)))[0]
        self._pending.clear()
        self.rebases += 1
        return self._accept(obs, t, odom)

    def stamped(self, estimate: PoseEstimate) -> PoseEstimate:
        """``estimate`` carrying what the guard has set aside and re-based on so far."""
        return replace(estimate, set_aside=dict(self.set_aside), rebases=self.rebases)

    @property
    def glitches(self) -> int:
        """Observations set aside, of every kind."""
        return sum(self.set_aside.values())

    def _fault(self, t0: float, odom0: np.ndarray, t1: float, odom1: np.ndarray) -> str | None:
        """Why an observation at (t1, odom1) cannot follow one at (t0, odom0); None if it can."""
        c = self.config
        dt = t1 - t0
        if dt < 0:
            return "stamp_back"
        if dt > c.max_gap_s:
            return "stamp_gap"
        step = relative_motion(odom0, odom1)
        slack = 0.05  # m and rad: what a single control step may show at standstill
        allowed = dt + STAMP_JITTER_S
        fast = (
            np.hypot(step[0], step[1]) > c.max_speed * allowed + slack
            or abs(step[2]) > c.max_turn_rate * allowed + slack
        )
        return "too_fast" if fast else None

    def _accept(self, obs: Observation, t: float, odom: np.ndarray) -> Observation:
        self.last_time, self.last_odom = t, odom.copy()
        out = dict(obs)
        if np.any(self.offset):
            out["odom"] = compose(self.offset, odom)[0].astype(np.asarray(obs["odom"]).dtype)
        for key in ("cloud_time", "scan_time"):
            if key in out and float(np.asarray(out[key]).reshape(-1)[0]) > t + STAMP_SLACK_S:
                out[key] = np.array([-np.inf])  # stamped in the future: not a fresh reading
        return out
