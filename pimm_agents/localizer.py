"""What every localizer reports, and the small surface every localizer has."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from pimm_env.errors import LocalizerError, ObservationError

Observation = dict[str, np.ndarray]


#: What a localizer says of its own estimate: it does not know where it is, it holds several places that fit
#: alike, or it holds one. A localizer that reports no status counts as ``localized`` whenever it gives a pose.
STATUSES = ("lost", "ambiguous", "localized")


@dataclass(frozen=True)
class Hypothesis:
    """One mode of a localizer's belief: a pose in the map frame, its share of the belief and its covariance."""

    x: float
    y: float
    theta: float
    weight: float
    covariance: np.ndarray


@dataclass(frozen=True)
class PoseEstimate:
    """A pose in the map frame with its 3 x 3 covariance (x, y, theta) and per-stage timings in ms.

    ``stamp`` is the sim time of the observation the estimate was made from. ``status`` is one of ``STATUSES``;
    ``hypotheses`` are the belief's best modes, heaviest first (empty for a localizer that keeps none).
    ``set_aside`` counts the observations its input guard set aside since its reset, by kind, and ``rebases`` the
    odometry jumps it re-based on. ``inside`` is what the localizer shows of its inner state, for figures, replays
    and bounds, each where it has it: ``particles`` (N, 3; at most ``INSIDE_PARTICLES``), ``corners`` (K, 2; the
    features measured at this update, placed at its estimate) and ``suggestions`` (M, 2; positions it was told to
    look at), all in the map frame, and ``walls`` (M, 2): the wall points this update weighed, in the robot frame.
    """

    x: float
    y: float
    theta: float
    covariance: np.ndarray
    stamp: float = 0.0
    timings: dict[str, float] = field(default_factory=dict)
    status: str = "localized"
    hypotheses: tuple[Hypothesis, ...] = ()
    set_aside: dict[str, int] = field(default_factory=dict)
    rebases: int = 0
    inside: dict[str, np.ndarray] = field(default_factory=dict)

    def __post_init__(self) -> None:
        values = np.array([self.x, self.y, self.theta])
        if not np.all(np.isfinite(values)):
            raise LocalizerError(f"pose estimate is not finite: {values}")
        if np.shape(self.covariance) != (3, 3):
            raise LocalizerError(f"covariance must be 3 x 3, got shape {np.shape(self.covariance)}")
        if self.status not in STATUSES:
            raise LocalizerError(f"status {self.status!r}: expected one of {', '.join(STATUSES)}")

    @property
    def pose(self) -> np.ndarray:
        return np.array([self.x, self.y, self.theta])


class Localizer(Protocol):
    """Built from a world's maps and one config object; consumes the env's observations one at a time.

    ``sensors`` names the observation keys it reads (``odom``, ``scan``, ``cloud``): an evaluation switches
    off a simulated LiDAR that no localizer reads.
    """

    name: str

    @property
    def sensors(self) -> tuple[str, ...]:
        """Observation keys it reads (a read-only property or a class attribute)."""
        ...

    def reset(
        self, seed: int | None = None, initial_pose: np.ndarray | None = None, initial_cov: np.ndarray | None = None
    ) -> None:
        """Forget everything. With no ``initial_pose`` the pose is unknown (global localization); with one, the
        localizer starts from it with covariance ``initial_cov`` (None: nav2's 0.5 m, 0.5 m, pi/12 rad)."""

    def update(self, obs: Observation) -> PoseEstimate:
        """Consume one observation and return the current estimate."""
        ...


#: At most this many particles in an estimate's ``inside`` (a picture needs no more).
INSIDE_PARTICLES = 500


def particle_sample(particles: np.ndarray, max_particles: int) -> np.ndarray:
    """Every k-th particle, at most ``max_particles`` (a picture needs no more)."""
    step = max(1, int(np.ceil(len(particles) / max(1, max_particles))))
    return np.array(particles[::step, :3], dtype=float)


def require(obs: Observation, key: str, shape: tuple[int, ...] | None = None) -> np.ndarray:
    """``obs[key]`` as a float array, with a clear error if it is missing or has the wrong shape."""
    if not isinstance(obs, Mapping):
        raise ObservationError(f"an observation is a dict of arrays (the env's), got {type(obs).__name__}")
    if key not in obs:
        raise ObservationError(f"observation has no {key!r} (keys: {sorted(obs)})")
    try:
        value = np.asarray(obs[key], dtype=float)
    except (TypeError, ValueError):
        raise ObservationError(f"observation {key!r} is not an array of numbers: {type(obs[key]).__name__}") from None
    if shape is not None and value.shape != shape:
        raise ObservationError(f"observation {key!r} has shape {value.shape}, expected {shape}")
    return value


#: The least standard deviation a published covariance carries (m, m, rad): a pose is never certain to the
#: millimetre, and a zero covariance tells a consumer exactly that (nav2's consumers divide by it).
PUBLISHED_FLOOR = np.array([0.01, 0.01, 0.005])
#: ... and while the status is not ``localized``: a localizer that does not say it is localized does not claim
#: its pose right (within 1 m and 10 deg, the metrics' rightness, scoring/honesty.py), so its ellipse is never
#: smaller than that, even when its particles have collapsed onto one place it still doubts.
UNSURE_FLOOR = np.array([1.0, 1.0, np.radians(10.0)])


def published_covariance(estimate: PoseEstimate) -> np.ndarray:
    """The 3 x 3 covariance a consumer that reads no status should see (``amcl_pose``, a results row's ``pub_*``).

    While ``localized``: the chosen mode's own, floored at ``PUBLISHED_FLOOR``. Otherwise it must cover every live
    place: the larger (by trace) of the covariance of the mixture of ``hypotheses`` and the spread of the shown
    ``particles``, both about the published pose, floored at ``UNSURE_FLOOR``, so that a reader of the ellipse
    alone is never shown a small one around a place the localizer itself doubts. Angles are wrapped before they
    are squared.
    """
    from pimm_env.geometry import wrap_angle

    floor = np.diag(PUBLISHED_FLOOR**2)
    own = np.asarray(estimate.covariance, dtype=float)
    own = np.where(np.isfinite(own), own, 0.0)
    own = own + np.diag(np.maximum(np.diag(floor) - np.diag(own), 0.0))
    if estimate.status == "localized":
        return own
    mean = estimate.pose
    candidates = [own]
    if estimate.hypotheses:
        weights = np.array([max(h.weight, 0.0) for h in estimate.hypotheses], dtype=float)
        weights = weights / weights.sum() if weights.sum() > 0 else np.full(len(weights), 1 / len(weights))
        mixture = np.zeros((3, 3))
        for weight, h in zip(weights, estimate.hypotheses, strict=True):
            d = np.array([h.x - mean[0], h.y - mean[1], wrap_angle(h.theta - mean[2])])
            mixture += weight * (np.asarray(h.covariance, dtype=float) + np.outer(d, d))
        candidates.append(mixture)
    particles = estimate.inside.get("particles")
    if particles is not None and len(particles) > 1:
        d = np.asarray(particles, dtype=float)[:, :3] - mean
        d[:, 2] = wrap_angle(d[:, 2])
        candidates.append(d.T @ d / len(d))
    widest = max(candidates, key=lambda c: float(np.trace(c[:2, :2])))
    widest = (widest + widest.T) / 2
    return widest + np.diag(np.maximum(UNSURE_FLOOR**2 - np.diag(widest), 0.0))
