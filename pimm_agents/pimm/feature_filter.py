"""PIMM's particle filter (thesis 3.4): odometry motion, corner matching, ESS resampling, smart injection.

All particles are handled at once with numpy; nothing loops over particles. Features come in the robot frame
*at the current time* (the localizer compensates their latency before handing them over).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pimm_agents.corners.lookup import NearestCornerGrid
from pimm_agents.particles.belief import (
    BIN_THETA,
    BIN_XY,
    Belief,
    BeliefConfig,
    BeliefReading,
    BeliefView,
    belief_status,
    compact_modes,
    covariance_about,
    hypotheses_of,
    read_belief,
    weigh_modes,
)
from pimm_agents.particles.free_space import FreeSpace
from pimm_agents.particles.initial_pose import gaussian_poses
from pimm_agents.particles.kld import bin_keys, kld_sample_count
from pimm_agents.particles.likelihood_field import LikelihoodField
from pimm_agents.particles.pose_clusters import cluster_labels, heaviest_mean, weight_near, weighted_covariance
from pimm_agents.particles.resampling import mode_draws, residual_resample
from pimm_agents.pimm.corner_evidence import corner_likelihoods
from pimm_env.errors import LocalizerError
from pimm_env.geometry import moved_rigidly, relative_motion, wrap_angle
from pimm_env.mapping.occupancy import OccupancyGrid

#: Ours (nav2's values where they are nav2's; each measured in docs/design.md#the-particle-filter):
SMART_SHARE = 0.5  # of the replaced particles, the share placed around the fingerprint suggestions
OCCUPIED_PENALTY = 0.1  # weight factor for a particle in an occupied or unknown cell
ESTIMATE_BIN_THETA = float(np.radians(10.0))  # the estimate's cluster bins: nav2's
ESTIMATE_BIN_XY = 0.5
#: a converged estimate further than this (m) from the last one, carried by odometry, replaces it only if the
#: particles within this distance (and 30 deg) of it weigh more than those about the last one
SWITCH_RADIUS_M = 1.0
SWITCH_ANGLE = float(np.radians(30.0))
KLD_ERR, KLD_Z = 0.05, 0.99  # nav2's pf_err and pf_z; KLD's bins are nav2's pose-cluster bins
MODE_MIN_PARTICLES = 100  # at resampling, a mode weighing MODE_KEEP_RATIO of the heaviest keeps this many
MODE_KEEP_RATIO = 0.01
LOOKUP_ORIENTATION_BINS = 8  # heading bins of the nearest-corner grid (45 deg; corners/lookup.py)


@dataclass(frozen=True)
class FeatureFilterConfig:
    """PIMM's particle filter. ``thesis`` runs it as the thesis published it; the default adds what measurement
    chose (docs/design.md#the-particle-filter): KLD-sampling, per-mode budgets, each compact mode weighed at its
    mean, the estimate over its heaviest cluster, a switch radius, corners matched by heading, one weighing per
    scan."""

    num_particles: int = 10_000  # thesis table 3.5 (with KLD-sampling: the most it holds)
    min_particles: int = 1000  # measured: KLD's floor (docs/design.md#the-particle-filter)
    motion_threshold_m: float = 0.1  # thesis table 3.5
    motion_threshold_rad: float = 0.01  # thesis table 3.5
    motion_variance: float = 0.001  # thesis table 3.5 (x and y; heading the same)
    resample_ess_threshold: float = 0.3  # thesis table 3.5
    alpha: float = 0.8  # thesis table 3.5
    replace_worst_fraction: float = 0.05  # thesis table 3.5
    smart_sigma_m: float = 0.5  # thesis table 3.5
    estimate_num_particles: int = 100  # thesis section 3.4
    min_sigma_pos_m: float = 0.3  # measured: floor on a corner's position uncertainty (docs/design.md#corners)
    min_sigma_theta_rad: float = 0.2  # measured: and on its heading's
    thesis: bool = False  # the filter as the thesis published it (the ``thesis`` preset)

    def __post_init__(self) -> None:
        if self.num_particles < 1:
            raise LocalizerError(f"filter.num_particles must be at least 1, got {self.num_particles}")
        if self.min_particles < 1:  # above num_particles it is num_particles: a small set is kept whole
            raise LocalizerError(f"filter.min_particles must be at least 1, got {self.min_particles}")
        if not 0 < self.alpha <= 1:
            raise LocalizerError(f"filter.alpha must be in (0, 1], got {self.alpha}")
        for name in ("motion_variance", "smart_sigma_m", "min_sigma_pos_m", "min_sigma_theta_rad"):
            if not getattr(self, name) > 0:
                raise LocalizerError(f"filter.{name} must be positive, got {getattr(self, name)}")
        if self.estimate_num_particles < 1:
            raise LocalizerError(f"filter.estimate_num_particles must be at least 1, got {self.estimate_num_particles}")
        for name in ("resample_ess_threshold", "replace_worst_fraction"):
            if not 0 <= getattr(self, name) <= 1:
                raise LocalizerError(f"filter.{name} must be in [0, 1], got {getattr(self, name)}")

    # What ``thesis`` selects (each the thesis's value, or ours):
    @property
    def adaptive(self) -> bool:
        """KLD-sampling at each resampling (the thesis's future work; nav2's), or a fixed set."""
        return not self.thesis

    @property
    def mode_min_particles(self) -> int:
        """The particles each kept mode is given at resampling (0: resampled as one set, the thesis's)."""
        return 0 if self.thesis else MODE_MIN_PARTICLES

    @property
    def mode_evidence(self) -> str:
        """``mean``: a compact mode weighed by the measurement at its mean pose; ``sum``: by its particles'."""
        return "sum" if self.thesis else "mean"

    @property
    def estimate_bin_xy(self) -> float:
        """The estimate's cluster bins (0: the mean of all the heaviest particles, the thesis's)."""
        return 0.0 if self.thesis else ESTIMATE_BIN_XY

    @property
    def switch_radius_m(self) -> float:
        """How far a new estimate may lie from the last before it must outweigh it (0: no test, the thesis's)."""
        return 0.0 if self.thesis else SWITCH_RADIUS_M

    @property
    def orientation_bins(self) -> int:
        """Heading bins of the corner lookup (1: the nearest corner, the thesis's)."""
        return 1 if self.thesis else LOOKUP_ORIENTATION_BINS


def injected(
    suggestions: np.ndarray, count: int, sigma: float, free_space: FreeSpace, rng: np.random.Generator
) -> np.ndarray:
    """``count`` new particles (thesis 3.4.4): ``SMART_SHARE`` of them about the suggested positions (Gaussian,
    ``sigma``, random heading), the rest uniform over free space."""
    suggestions = np.asarray(suggestions, dtype=float).reshape(-1, 2)
    smart = round(SMART_SHARE * count) if len(suggestions) else 0
    new = np.empty((count, 3))
    if smart:
        centres = suggestions[rng.integers(0, len(suggestions), smart)]
        new[:smart, :2] = centres + rng.normal(0, sigma, (smart, 2))
        new[:smart, 2] = rng.uniform(-np.pi, np.pi, smart)
    new[smart:] = free_space.sample(count - smart, rng)
    return new


#: Columns of the feature array the filter takes: x, y, theta (robot frame), sigma_pos (m), sigma_theta (rad).
FEATURE_COLUMNS = ("x", "y", "theta", "sigma_pos", "sigma_theta")


class FeatureFilter:
    def __init__(
        self,
        occupancy: OccupancyGrid,
        corners: NearestCornerGrid | None,
        config: FeatureFilterConfig = FeatureFilterConfig(),
        wall_field: LikelihoodField | None = None,
        wall_temperature: float = 0.2,
        belief: BeliefConfig = BeliefConfig(),
    ) -> None:
        self.config = config
        self.belief_config = belief
        self.corners = corners
        self.wall_field = wall_field
        self.wall_temperature = wall_temperature  # the tempered product of the points' likelihoods
        self.free_space = FreeSpace(occupancy)
        self.rng = np.random.default_rng()
        self.particles = np.zeros((config.num_particles, 3))
        self.weights = np.full(config.num_particles, 1.0 / config.num_particles)
        self.ess = float(config.num_particles)
        self.informed = False  # whether the last measurement update had anything to weigh with
        self.belief: Belief | None = None  # the modes after the last measurement update
        self._odom_ref: np.ndarray | None = None

    # ------------------------------------------------------------------ life cycle
    def reset(
        self, rng: np.random.Generator, initial_pose: np.ndarray | None = None, initial_cov: np.ndarray | None = None
    ) -> None:
        """Particles uniform over free space (or about ``initial_pose``) with equal weights; forget the odometry
        reference."""
        self.rng = rng
        n = self.config.num_particles
        self.particles = (
            self.free_space.sample(n, rng)
            if initial_pose is None
            else gaussian_poses(initial_pose, initial_cov, n, rng)
        )
        self.weights = np.full(self.config.num_particles, 1.0 / self.config.num_particles)
        self.ess = float(self.config.num_particles)
        self._odom_ref = None
        self.belief = None

    # ------------------------------------------------------------------ motion
    def motion_update(self, odom: np.ndarray) -> bool:
        """Move every particle by the odometry since the last motion update, with Gaussian noise, if that
        motion passes the threshold. Returns whether it did (the measurement update may follow only then)."""
        odom = np.asarray(odom, dtype=float)
        if self._odom_ref is None:
            self._odom_ref = odom.copy()
            return False
        delta = relative_motion(self._odom_ref, odom)
        c = self.config
        if np.hypot(delta[0], delta[1]) < c.motion_threshold_m and abs(delta[2]) < c.motion_threshold_rad:
            return False
        n = len(self.particles)
        std = np.sqrt([c.motion_variance, c.motion_variance, c.motion_variance])
        noisy = delta + self.rng.standard_normal((n, 3)) * std
        cos, sin = np.cos(self.particles[:, 2]), np.sin(self.particles[:, 2])
        self.particles[:, 0] += cos * noisy[:, 0] - sin * noisy[:, 1]
        self.particles[:, 1] += sin * noisy[:, 0] + cos * noisy[:, 1]
        self.particles[:, 2] = wrap_angle(self.particles[:, 2] + noisy[:, 2])
        self._odom_ref = odom.copy()
        return True

    # ------------------------------------------------------------------ measurement
    def likelihoods(self, features: np.ndarray, poses: np.ndarray | None = None) -> np.ndarray:
        """Eq. 3.15 summed as cubes over the features, for every particle (or each of ``poses``): L_total (N,)."""
        if self.corners is None:
            raise LocalizerError("the filter has no corner map to weigh corner features with")
        return corner_likelihoods(self.corners, features, self.particles if poses is None else poses)

    def measurement_update(
        self, features: np.ndarray, wall_points: np.ndarray | None = None, labels: np.ndarray | None = None
    ) -> None:
        """Weights by eq. 3.16, then, given ``wall_points`` (M, 2; robot frame now) and a wall field, by the
        likelihood field, tempered: exp(temperature x sum of log pz); with neither only the occupied-cell
        penalty applies. Given the particles' cluster ``labels`` and
        ``mode_evidence`` "mean", each compact mode is then weighed by the measurement at its mean pose
        (``weigh_modes``). Normalized; the ESS."""
        features = np.asarray(features, dtype=float).reshape(-1, len(FEATURE_COLUMNS))
        if not np.isfinite(features).all() or np.any(features[:, 3:] <= 0):
            raise LocalizerError("features must be finite with positive sigma_pos and sigma_theta")
        use_walls = self.wall_field is not None and wall_points is not None and len(wall_points) > 0
        self.informed = bool(len(features)) or use_walls
        n = len(self.particles)
        modes = None
        if labels is not None and self.config.mode_evidence == "mean" and self.informed:
            modes = compact_modes(self.particles, self.weights, labels)
        poses = self.particles if modes is None else np.vstack([self.particles, modes[1]])
        factors = self.measurement_factors(poses, features, wall_points if use_walls else None)
        w = self.weights * factors[:n]
        if modes is not None and labels is not None:
            w = weigh_modes(self.weights, w, labels, modes[0], factors[n:])
        total = w.sum()
        if not np.isfinite(total) or total <= 0:
            w, total = np.ones_like(w), float(len(w))  # every particle penalized to nothing: start level again
        self.weights = w / total
        self.ess = float(1.0 / np.sum(self.weights**2))

    def measurement_factors(
        self, poses: np.ndarray, features: np.ndarray, wall_points: np.ndarray | None
    ) -> np.ndarray:
        """What one measurement multiplies the weight of a particle at each of ``poses`` by (see
        ``measurement_update``); the wall field's factors are relative to the best of ``poses``."""
        factors = np.ones(len(poses))
        if len(features) and self.corners is not None:
            alpha = self.config.alpha
            factors = alpha * self.likelihoods(features, poses) + (1 - alpha)
        if wall_points is not None and self.wall_field is not None:
            points = np.asarray(wall_points, dtype=float).reshape(-1, 2)
            ranges, bearings = np.hypot(points[:, 0], points[:, 1]), np.arctan2(points[:, 1], points[:, 0])
            log_l = self.wall_field.log_likelihoods(poses, ranges, bearings)
            factors = factors * np.exp(self.wall_temperature * (log_l - log_l.max()))
        return np.where(self.free_space.contains(poses), factors, factors * OCCUPIED_PENALTY)

    # ------------------------------------------------------------------ resampling and injection
    def resample_if_degenerate(self) -> bool:
        """Residual resampling when ESS <= tau * N (eq. 3.17); with ``adaptive``, as many particles as KLD's bound
        keeps of num_particles draws; with ``mode_min_particles``, drawn mode by mode (``mode_draws``).
        Returns whether it resampled."""
        n = len(self.particles)
        c = self.config
        if self.ess > c.resample_ess_threshold * n:
            return False
        if c.adaptive:
            drawn = self.particles[self.rng.permutation(residual_resample(self.weights, self.rng, c.num_particles))]
            keys = bin_keys(drawn, BIN_XY, BIN_THETA)
            n = kld_sample_count(keys, KLD_ERR, KLD_Z, c.min_particles, c.num_particles)
            if c.mode_min_particles == 0 or self.belief is None:
                self.particles, self.weights = drawn[:n], np.full(n, 1.0 / n)
                return True
        elif c.mode_min_particles == 0 or self.belief is None:
            self.particles, self.weights = (
                self.particles[residual_resample(self.weights, self.rng)],
                np.full(n, 1.0 / n),
            )
            return True
        assert self.belief is not None
        index, weights = mode_draws(self.weights, self.belief, n, c.mode_min_particles, MODE_KEEP_RATIO, self.rng)
        self.particles, self.weights = self.particles[index], weights
        return True

    def inject(self, suggestions: np.ndarray) -> np.ndarray:
        """Replace the worst ``replace_worst_fraction`` of the particles: ``smart_share`` of them around the
        suggested positions (Gaussian, ``smart_sigma_m``, random heading), the rest uniform over free space.
        They take the mean weight. Returns the indices replaced (with ``adaptive`` and a set smaller than
        num_particles, the indices of the particles added instead)."""
        c = self.config
        n = len(self.particles)
        count = round(c.replace_worst_fraction * (c.num_particles if c.adaptive else n))
        if count == 0:
            return np.zeros(0, dtype=int)
        grow = c.adaptive and n + count <= c.num_particles
        if grow:  # a shrunk set: the new particles join it
            self.particles = np.vstack([self.particles, np.zeros((count, 3))])
            self.weights = np.concatenate([self.weights, np.zeros(count)])
            worst = np.arange(n, n + count)
            n += count
        else:
            count = min(count, n)
            worst = np.argpartition(self.weights, count - 1)[:count]
        self.particles[worst] = injected(suggestions, count, c.smart_sigma_m, self.free_space, self.rng)
        self.weights[worst] = 1.0 / n
        self.weights /= self.weights.sum()
        return worst

    def weigh(self, features: np.ndarray, wall_points: np.ndarray | None = None) -> None:
        """One measurement after a motion update (eq. 3.16 and the wall field): weigh the particles, each
        compact mode as one, and read the belief's modes from the new weights."""
        labels = cluster_labels(self.particles, BIN_XY, BIN_THETA)
        self.measurement_update(features, wall_points, labels)
        self.belief = read_belief(self.particles, self.weights, labels)

    def estimate(self, previous: np.ndarray | None) -> np.ndarray | None:
        """The best-particles mean if the filter has converged by the ESS test and, when it jumps away from
        ``previous`` (the last estimate carried to now, ``jumps``), holds more weight than it; else None (the
        caller carries its last estimate by odometry). Read while the weights still say something: before
        ``resample_and_inject``."""
        estimate = self.best_mean() if self.converged() else None
        if estimate is None or previous is None or not self.jumps(previous, estimate):
            return estimate
        r = self.config.switch_radius_m
        near_new, near_old = (
            weight_near(self.particles, self.weights, p, r, SWITCH_ANGLE) for p in (estimate, previous)
        )
        return estimate if near_new > near_old else None

    def jumps(self, previous: np.ndarray, estimate: np.ndarray) -> bool:
        """Whether ``estimate`` lies away from ``previous`` by more than ``switch_radius_m`` (0: never)."""
        r = self.config.switch_radius_m
        return r > 0 and bool(np.hypot(*(estimate[:2] - previous[:2])) > r)

    def move_mode(self, pose: np.ndarray, target: np.ndarray) -> None:
        """Move the particles of the mode ``pose`` lies in (those within 1 m and 30 deg of it if it is in none)
        rigidly from ``pose`` to ``target``, and read the belief again: how a decision to hold a place, or to
        move to one, is applied (pimm/ambiguity.py)."""
        assert self.belief is not None
        chosen = self.belief.mode_of(pose, self.particles)
        if chosen >= 0:
            members = self.belief.particle_mode == chosen
        else:
            d = self.particles - pose
            members = (np.hypot(d[:, 0], d[:, 1]) <= 1.0) & (np.abs(wrap_angle(d[:, 2])) <= np.radians(30.0))
        self.particles[members] = moved_rigidly(self.particles[members], pose, target)
        self.belief = read_belief(self.particles, self.weights)

    def resample_and_inject(self, suggestions: np.ndarray) -> None:
        """The end of a measurement step: resample if degenerate, then inject around ``suggestions``.

        Injection follows only an update that weighed something: with nothing measured the weights say
        nothing about which particles are worst, and replacing an arbitrary 5 % per step would wear the
        tracked cluster away while the robot drives through a stretch with no corners."""
        self.resample_if_degenerate()
        if self.informed:
            self.inject(suggestions)

    def view(self) -> BeliefView:
        """The belief as it stands, for a reviewer that must not change it (pimm/ambiguity.py)."""
        assert self.belief is not None
        return BeliefView(self.particles, self.weights, self.belief)

    # ------------------------------------------------------------------ estimate
    def read(self, pose: np.ndarray | None) -> BeliefReading:
        """The status, covariance and hypotheses of the belief for an estimate at ``pose`` (None: no estimate
        yet, lost), from the modes of the last measurement update."""
        if self.belief is None:
            self.belief = read_belief(self.particles, self.weights)
        hypotheses = hypotheses_of(self.belief, self.belief_config.hypotheses)
        if pose is None:
            return BeliefReading("lost", self.covariance(self.best_mean()), hypotheses)
        chosen = self.belief.mode_of(pose, self.particles)
        status = belief_status(self.belief, chosen, self.belief_config)
        cov = covariance_about(self.belief.modes[chosen], pose) if chosen >= 0 else self.covariance(pose)
        return BeliefReading(status, cov, hypotheses, chosen)

    def converged(self) -> bool:
        """The thesis's test for the dual-mode estimate: the last measurement left ESS <= tau * N."""
        return self.ess <= self.config.resample_ess_threshold * len(self.particles)

    def best_mean(self) -> np.ndarray:
        """The mean of the ``estimate_num_particles`` heaviest particles, over their heaviest cluster
        (``estimate_bin_xy``; 0: over all of them, the thesis's estimate)."""
        c = self.config
        return heaviest_mean(
            self.particles, self.weights, c.estimate_num_particles, c.estimate_bin_xy, ESTIMATE_BIN_THETA
        )

    def covariance(self, around: np.ndarray) -> np.ndarray:
        """Weighted covariance of all particles about ``around`` (angles wrapped)."""
        return weighted_covariance(self.particles, self.weights, around)
