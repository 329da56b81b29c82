"""A particle belief read as a navigation stack needs it: its modes, the chosen mode's covariance, a status.

The particles are grouped into modes by nav2's pose clusters (bins that touch). A mode is *compact* when its
position and heading spreads are within ``BeliefConfig``'s limits: a place, not a cloud still searching. The
status of an estimate that lies in mode ``chosen``:

- ``lost``: the chosen mode is not compact, or holds less than ``localized_min_weight`` of the belief;
- ``ambiguous``: another compact mode weighs at least ``rival_ratio`` of the chosen one (a look-alike place
  the evidence has not ruled out, or a heavier mode the estimate has not moved to yet);
- ``localized``: otherwise, once that has held for ``confirm_updates`` measurement updates in a row with the
  estimate in one place (``Confirmation``): a mode the first scans favour is often a wrong one whose rival has
  no particles yet, and the next scans rule it out.

``compact_modes`` and ``weigh_modes`` let a filter weigh each compact mode as one hypothesis (PIMM's
the default preset's ``FeatureFilterConfig.mode_evidence``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pimm_agents.localizer import Hypothesis
from pimm_agents.particles.pose_clusters import PoseCluster, cluster_labels, cluster_statistics
from pimm_env.errors import LocalizerError
from pimm_env.geometry import wrap_angle

#: nav2's pose-cluster bins (m, rad): particles in touching bins are one mode
BIN_XY, BIN_THETA = 0.5, float(np.radians(10.0))
#: a compact mode with at least this share of the chosen mode's weight keeps the status ambiguous (measured:
#: docs/design.md#statuses)
RIVAL_RATIO = 0.1
#: a mode is compact (a place, not a cloud still searching) when its largest position standard deviation and its
#: heading's are under these: nav2's AMCL tracks right with a cluster of 0.4-0.5 m and 13-16 deg
COMPACT_STD_M, COMPACT_STD_DEG = 1.0, 20.0
MODES_EXAMINED = 20  # the heaviest modes looked at for rivals (a rival is among them)


@dataclass(frozen=True)
class BeliefConfig:
    """How a particle belief is read as a status (ours: nav2 reports its heaviest cluster only, with no status)."""

    hypotheses: int = 3  # ours: modes reported, heaviest first
    localized_min_weight: float = 0.5  # ours: the chosen mode's share of the belief below which it is lost
    confirm_updates: int = 10  # measured: updates in a row a localized reading needs (docs/design.md#statuses)

    def __post_init__(self) -> None:
        if self.confirm_updates < 0:
            raise LocalizerError(f"belief.confirm_updates must be at least 0, got {self.confirm_updates}")
        if self.hypotheses < 1:
            raise LocalizerError(f"belief.hypotheses must be at least 1, got {self.hypotheses}")
        if not 0 <= self.localized_min_weight <= 1:
            raise LocalizerError(f"belief.localized_min_weight must be in [0, 1], got {self.localized_min_weight}")


@dataclass(frozen=True)
class Belief:
    """The modes of a particle set, heaviest first, and each particle's mode index."""

    modes: list[PoseCluster]
    particle_mode: np.ndarray  # (N,) index into ``modes``; -1 for a mode past ``modes_examined``

    def mode_of(self, pose: np.ndarray, particles: np.ndarray) -> int:
        """The mode of the particle nearest ``pose`` (heading weighed as 1 m a radian); -1 past the examined."""
        d = particles - pose
        distance = d[:, 0] ** 2 + d[:, 1] ** 2 + wrap_angle(d[:, 2]) ** 2
        return int(self.particle_mode[int(np.argmin(distance))])


@dataclass(frozen=True)
class BeliefView:
    """A filter's particles, weights and modes after a measurement, for a reviewer: read-only by agreement."""

    particles: np.ndarray
    weights: np.ndarray
    belief: Belief


def read_belief(particles: np.ndarray, weights: np.ndarray, labels: np.ndarray | None = None) -> Belief:
    """Cluster the weighted particles into modes (heaviest first, ``modes_examined`` of them); ``labels``: the
    particles' clusters if they are known already (``cluster_labels`` with nav2's bins)."""
    if labels is None:
        labels = cluster_labels(particles, BIN_XY, BIN_THETA)
    total = np.bincount(labels, weights)
    order = np.argsort(-total, kind="stable")[:MODES_EXAMINED]
    rank = np.full(len(total), -1)
    rank[order] = np.arange(len(order))
    modes = cluster_statistics(particles, weights, labels, limit=MODES_EXAMINED)
    return Belief(modes, rank[labels])


def is_compact(mode: PoseCluster) -> bool:
    """Whether the mode's largest position spread and its heading spread are within the compact limits."""
    largest = float(np.linalg.eigvalsh(mode.covariance[:2, :2])[-1])
    return largest <= COMPACT_STD_M**2 and mode.covariance[2, 2] <= np.radians(COMPACT_STD_DEG) ** 2


def belief_status(belief: Belief, chosen: int, config: BeliefConfig) -> str:
    """``lost``, ``ambiguous`` or ``localized`` for an estimate in mode ``chosen`` (see the module's text)."""
    if chosen < 0:
        return "lost"
    mode = belief.modes[chosen]
    if not is_compact(mode) or mode.weight < config.localized_min_weight:
        return "lost"
    for index, other in enumerate(belief.modes):
        if index != chosen and other.weight >= RIVAL_RATIO * mode.weight and is_compact(other):
            return "ambiguous"
    return "localized"


def covariance_about(mode: PoseCluster, pose: np.ndarray) -> np.ndarray:
    """The mode's covariance about ``pose`` rather than its mean: its spread plus the offset between them."""
    offset = np.array([pose[0] - mode.mean[0], pose[1] - mode.mean[1], wrap_angle(pose[2] - mode.mean[2])])
    cov = mode.covariance + np.outer(offset, offset)
    cov[2, :2] = cov[:2, 2] = 0.0
    return cov


def hypotheses_of(belief: Belief, count: int) -> tuple[Hypothesis, ...]:
    """The ``count`` heaviest modes as hypotheses."""
    return tuple(
        Hypothesis(float(m.mean[0]), float(m.mean[1]), float(m.mean[2]), m.weight, m.covariance.copy())
        for m in belief.modes[:count]
    )


class Confirmation:
    """Holds back ``localized`` until it has been read at ``updates`` measurement updates in a row with the
    estimate staying in one place; until then the status is ``ambiguous``."""

    def __init__(self, updates: int) -> None:
        self.updates = updates
        self.streak = 0

    def reset(self) -> None:
        self.streak = 0

    def __call__(self, status: str, moved_place: bool, earned: int = 0) -> str:
        """The status to report for a reading ``status`` at an update; ``moved_place``: the estimate jumped to
        another place at this update, which has already held for ``earned`` updates (a rival that led that
        long, ``pimm/ambiguity.py``)."""
        if status != "localized":
            self.streak = 0
            return status
        self.streak = 1 + earned if moved_place else self.streak + 1
        return "localized" if self.streak >= self.updates else "ambiguous"


def compact_modes(particles: np.ndarray, weights: np.ndarray, labels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The clusters that are compact modes (more than one particle, weighed, spreads within the compact
    limits; position by the trace of its covariance) and their weighted mean poses (K, 3)."""
    count = int(labels.max()) + 1
    members = np.bincount(labels, minlength=count)
    total = np.bincount(labels, weights, minlength=count)
    share = weights / np.where(total[labels] > 0, total[labels], 1.0)
    x, y, theta = particles.T
    mx, my, mxx, myy, mc, ms = (
        np.bincount(labels, share * v, minlength=count) for v in (x, y, x * x, y * y, np.cos(theta), np.sin(theta))
    )
    trace = (mxx - mx**2) + (myy - my**2)
    theta_var = -2.0 * np.log(np.clip(np.hypot(mc, ms), 1e-12, 1.0))
    compact = (members > 1) & (total > 0) & (trace <= COMPACT_STD_M**2)
    compact &= theta_var <= np.radians(COMPACT_STD_DEG) ** 2
    ids = np.flatnonzero(compact)
    return ids, np.column_stack([mx[ids], my[ids], np.arctan2(ms[ids], mc[ids])])


def weigh_modes(
    prior: np.ndarray, posterior: np.ndarray, labels: np.ndarray, modes: np.ndarray, mode_factors: np.ndarray
) -> np.ndarray:
    """``posterior`` (unnormalized weights) with each mode in ``modes`` (cluster ids) given its prior total times
    ``mode_factors`` (the measurement at its mean); its particles keep their shares of it."""
    count = int(labels.max()) + 1
    prior_total = np.bincount(labels, prior, minlength=count)
    posterior_total = np.bincount(labels, posterior, minlength=count)
    target = posterior_total.copy()
    target[modes] = prior_total[modes] * mode_factors
    with np.errstate(divide="ignore", invalid="ignore"):
        scale = np.where(posterior_total > 0, target / posterior_total, 0.0)
    return posterior * scale[labels]


@dataclass(frozen=True)
class BeliefReading:
    """What the filter's belief says of an estimate: its status, covariance (of the estimate's mode, about the
    estimate) and the belief's heaviest modes."""

    status: str
    covariance: np.ndarray
    hypotheses: tuple[Hypothesis, ...]
    chosen: int = -1  # the estimate's mode in the belief (-1: none)
