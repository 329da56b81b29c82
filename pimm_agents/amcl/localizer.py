"""AMCL as nav2_amcl runs it: its three laser models, odometry motion model, KLD-sampling, recovery.

The thesis's baseline. Defaults are nav2's, which is what the thesis ran. ``amcl-recovery-nav2`` turns on
nav2's recovery with the averages its documentation recommends; nav2 zeroes both averages after every
injection, so it injects one burst and stops. ``amcl-recovery`` keeps them, as Augmented MCL is specified
(Probabilistic Robotics, table 8.3), and injects for as long as the scans fit badly.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, fields

import numpy as np

from pimm_agents.localizer import (
    INSIDE_PARTICLES,
    PUBLISHED_FLOOR,
    Hypothesis,
    Observation,
    PoseEstimate,
    particle_sample,
    require,
)
from pimm_agents.observation_guard import GuardConfig, ObservationGuard
from pimm_agents.particles.beam_model import BeamModel, BeamModelParams
from pimm_agents.particles.belief import BeliefConfig, Confirmation, belief_status, hypotheses_of, read_belief
from pimm_agents.particles.free_space import FreeSpace
from pimm_agents.particles.initial_pose import gaussian_poses
from pimm_agents.particles.kld import bin_keys, kld_sample_count
from pimm_agents.particles.likelihood_field import BeamSkip, LikelihoodField, LikelihoodFieldParams
from pimm_agents.particles.motion_model import odometry_delta, sample_differential
from pimm_agents.particles.resampling import multinomial_resample
from pimm_env.errors import LocalizerError, ObservationError
from pimm_env.geometry import carry, wrap_angle
from pimm_env.mapping.occupancy import OccupancyGrid
from pimm_env.sim.lidar import Lidar2DConfig, beam_bearings_2d

#: nav2's laser_model_type values.
LASER_MODELS = ("likelihood_field", "beam", "likelihood_field_prob")


@dataclass(frozen=True)
class AmclConfig:
    """nav2_amcl's parameters, with its defaults (the values the thesis ran)."""

    #: nav2's laser_model_type: likelihood_field (its default), beam, or likelihood_field_prob
    laser_model_type: str = "likelihood_field"
    min_particles: int = 500
    max_particles: int = 2000
    pf_err: float = 0.05
    pf_z: float = 0.99
    z_hit: float = 0.5
    z_rand: float = 0.5
    sigma_hit: float = 0.2
    laser_likelihood_max_dist: float = 2.0
    max_beams: int = 60
    # the beam model's (nav2 defaults); z_hit, z_rand and sigma_hit are shared with the likelihood fields
    z_short: float = 0.05
    z_max: float = 0.05
    lambda_short: float = 0.1
    #: the beam model's expected ranges: looked up in a table of this many headings per free cell (360: 1 degree;
    #: nav2 casts every beam, from the particle's cell, at its own heading); 0 casts every beam exactly (slower)
    beam_range_headings: int = 360
    # likelihood_field_prob's beam skipping (nav2 defaults; off unless asked, as in nav2)
    do_beamskip: bool = False
    beam_skip_distance: float = 0.5
    beam_skip_threshold: float = 0.3
    beam_skip_error_threshold: float = 0.9
    alpha1: float = 0.2
    alpha2: float = 0.2
    alpha3: float = 0.2
    alpha4: float = 0.2
    update_min_d: float = 0.25
    update_min_a: float = 0.2
    resample_interval: int = 1
    recovery_alpha_slow: float = 0.0
    recovery_alpha_fast: float = 0.0
    #: nav2 zeroes w_slow and w_fast after every resampling that injected particles; the textbook's Augmented
    #: MCL (Probabilistic Robotics, table 8.3) keeps them, so injection goes on while the scans fit badly.
    reset_recovery_averages: bool = True
    #: KLD and cluster bins: nav2's 0.5 m x 0.5 m x 10 deg.
    bin_xy: float = 0.5
    bin_theta: float = np.radians(10.0)
    #: ours: how the clusters are read as hypotheses and a status (particles/belief.py); nav2 has no status
    belief: BeliefConfig = field(default_factory=BeliefConfig)
    #: ours: which observations are set aside as glitches (observation_guard.py); nav2 has no such check
    guard: GuardConfig = field(default_factory=GuardConfig)

    def __post_init__(self) -> None:
        if self.laser_model_type not in LASER_MODELS:
            raise LocalizerError(
                f"AmclConfig.laser_model_type must be one of {', '.join(LASER_MODELS)}, got {self.laser_model_type!r}"
            )
        for f in fields(self):
            value = getattr(self, f.name)
            if isinstance(value, str | BeliefConfig | GuardConfig):
                continue
            if not np.isfinite(value) or value < 0:
                raise LocalizerError(f"AmclConfig.{f.name} must be finite and non-negative, got {value!r}")
        if not 1 <= self.min_particles <= self.max_particles:
            raise LocalizerError(
                f"AmclConfig: need 1 <= min_particles <= max_particles, got {self.min_particles}, {self.max_particles}"
            )
        for name in ("max_beams", "resample_interval", "sigma_hit", "pf_err", "bin_xy", "bin_theta"):
            if getattr(self, name) <= 0:
                raise LocalizerError(f"AmclConfig.{name} must be positive, got {getattr(self, name)!r}")

    @property
    def alphas(self) -> tuple[float, float, float, float]:
        return (self.alpha1, self.alpha2, self.alpha3, self.alpha4)


#: nav2's recovery with the averages its documentation recommends, and nav2's reset after each injection.
AMCL_RECOVERY_NAV2: dict[str, float | bool] = {"recovery_alpha_slow": 0.001, "recovery_alpha_fast": 0.1}
#: nav2's other two laser models, with their defaults; beam skipping on for likelihood_field_prob (what it adds).
AMCL_BEAM: dict[str, float | bool | str] = {"laser_model_type": "beam"}
AMCL_LFP: dict[str, float | bool | str] = {"laser_model_type": "likelihood_field_prob", "do_beamskip": True}
#: The recovery as the issue specifies it and the textbook's Augmented MCL runs it: the same averages, kept
#: after an injection, so that particles keep coming while the scans fit badly.
AMCL_RECOVERY: dict[str, float | bool] = {**AMCL_RECOVERY_NAV2, "reset_recovery_averages": False}


def subsample_beams(count: int, max_beams: int) -> np.ndarray:
    """Indices of up to ``max_beams`` beams evenly spread over ``count`` (nav2: step (count-1)/(max_beams-1))."""
    if max_beams >= count or max_beams < 2:
        return np.arange(count) if max_beams >= count else np.array([0])
    step = (count - 1) // (max_beams - 1)
    return np.arange(max_beams) * step


class Amcl:
    """Adaptive Monte Carlo localization from the 2D scan and wheel odometry.

    ``update`` runs the filter on each fresh scan once the odometry has moved ``update_min_d`` or turned
    ``update_min_a`` since the last filter update (the first scan always updates). Between updates the
    estimate follows the odometry, as nav2's map -> odom transform makes it.
    """

    #: Observation keys it reads: the 3D cloud is not among them, so evaluations may switch it off.
    sensors = ("odom", "scan")

    def __init__(
        self,
        occupancy: OccupancyGrid,
        config: AmclConfig | None = None,
        lidar: Lidar2DConfig | None = None,
        name: str = "amcl",
    ) -> None:
        self.name = name
        self.config = config or AmclConfig()
        self.lidar = lidar or Lidar2DConfig()
        c = self.config
        self.free_space = FreeSpace(occupancy)
        self.field = LikelihoodField(
            occupancy,
            LikelihoodFieldParams(c.z_hit, c.z_rand, c.sigma_hit, c.laser_likelihood_max_dist, self.lidar.max_range),
        )
        self.beam_model = (
            BeamModel(
                occupancy,
                self.lidar.max_range,
                BeamModelParams(c.z_hit, c.z_short, c.z_max, c.z_rand, c.sigma_hit, c.lambda_short),
                c.beam_range_headings,
            )
            if c.laser_model_type == "beam"
            else None
        )
        self.beam_skip = (
            BeamSkip(c.beam_skip_distance, c.beam_skip_threshold, c.beam_skip_error_threshold)
            if c.do_beamskip
            else None
        )
        self._beams = subsample_beams(self.lidar.beams, c.max_beams)
        self.guard = ObservationGuard(c.guard)
        self._bearings = beam_bearings_2d(self.lidar)[self._beams]  # in the robot's frame
        self._mount = (self.lidar.mount_x, self.lidar.mount_y)
        self.reset()

    # ------------------------------------------------------------------ the contract
    def reset(
        self, seed: int | None = None, initial_pose: np.ndarray | None = None, initial_cov: np.ndarray | None = None
    ) -> None:
        """Global localization (particles uniform over free space), or a Gaussian about ``initial_pose``."""
        self.rng = np.random.default_rng(seed)
        self.guard.reset()
        n = self.config.max_particles
        if initial_pose is None:
            self.particles = self.free_space.sample(n, self.rng)
        else:
            self.particles = gaussian_poses(initial_pose, initial_cov, n, self.rng)
        self.weights = np.full(n, 1.0 / n)
        self.w_slow = self.w_fast = 0.0
        self._updates = 0
        self._last_scan_time: float | None = None
        self._odom_at_update: np.ndarray | None = None
        self.confirmation = Confirmation(self.config.belief.confirm_updates)
        self._pose_at_update = self._read_clusters()
        self._estimate: PoseEstimate | None = None

    def update(self, obs: Observation) -> PoseEstimate:
        self.guard.check(obs, ("odom", "time", "scan_time"))
        if "scan" in obs and np.shape(obs["scan"]) != (self.lidar.beams,):
            raise ObservationError(
                f"observation 'scan' has shape {np.shape(obs['scan'])}, expected ({self.lidar.beams},): this"
                f" localizer was built for a 2D LiDAR of {self.lidar.beams} beams from {self.lidar.angle_min_deg:g}"
                f" to {self.lidar.angle_max_deg:g} deg; give the scan's layout with sensors= (make_localizer) or"
                " --sensors (a sensors file or preset)"
            )
        scan = require(obs, "scan", (self.lidar.beams,))  # NaN or out-of-range beams are skipped (REP 117)
        taken = self.guard.take(obs)
        if taken is None and self._estimate is not None:  # a glitch: keep the estimate
            self._estimate = self.guard.stamped(self._estimate)
            return self._estimate
        obs = taken or obs
        odom = require(obs, "odom", (3,))
        scan_time = float(require(obs, "scan_time", (1,))[0])
        stamp = float(require(obs, "time", (1,))[0])
        timings: dict[str, float] = {}
        if np.isfinite(scan_time) and scan_time != self._last_scan_time:
            self._last_scan_time = scan_time
            if self._odom_at_update is None:
                self.filter_update(odom, scan, None, timings)
            else:
                d = odom - self._odom_at_update
                dtheta = abs(float(wrap_angle(d[2])))
                if (
                    abs(d[0]) > self.config.update_min_d
                    or abs(d[1]) > self.config.update_min_d
                    or (dtheta > self.config.update_min_a)
                ):
                    self.filter_update(odom, scan, odometry_delta(self._odom_at_update, odom), timings)
        self._estimate = self.guard.stamped(self._report(odom, stamp, timings))
        return self._estimate

    # ------------------------------------------------------------------ the filter
    def filter_update(
        self, odom: np.ndarray, scan: np.ndarray, delta: tuple[float, float, float] | None, timings: dict[str, float]
    ) -> None:
        """One filter step at a fresh scan: motion by ``delta`` (None: none), measurement, resampling every
        ``resample_interval`` steps, and the heaviest cluster's pose; stage times (ms) go into ``timings``."""
        start = time.perf_counter()
        if delta is not None:
            self.particles = sample_differential(self.particles, delta, self.config.alphas, self.rng)
        moved = time.perf_counter()
        self.measurement_update(scan)
        sensed = time.perf_counter()
        self._updates += 1
        if self._updates % self.config.resample_interval == 0:
            self._resample()
        resampled = time.perf_counter()
        carried = None if self._odom_at_update is None else carry(self._pose_at_update[0], self._odom_at_update, odom)
        self._odom_at_update = odom.copy()
        self._pose_at_update = self._read_clusters(update=True, previous=carried)
        done = time.perf_counter()
        timings.update(
            motion=1000 * (moved - start),
            sensor=1000 * (sensed - moved),
            resample=1000 * (resampled - sensed),
            estimate=1000 * (done - resampled),
            total=1000 * (done - start),
        )

    def measurement_update(self, scan: np.ndarray) -> None:
        """Weigh the particles by the laser model of ``scan`` (all its beams, the configured subset used)
        and update the recovery averages."""
        factors = self.scan_factors(scan)
        weights = self.weights * factors
        total = float(weights.sum())
        if not np.isfinite(total) or total <= 0:  # only the product of likelihood_field_prob can underflow
            weights, total = np.full(len(weights), 1.0 / len(weights)), 1.0
        self.weights = weights / total
        w_avg = total / len(weights)
        c = self.config
        self.w_slow = w_avg if self.w_slow == 0 else self.w_slow + c.recovery_alpha_slow * (w_avg - self.w_slow)
        self.w_fast = w_avg if self.w_fast == 0 else self.w_fast + c.recovery_alpha_fast * (w_avg - self.w_fast)

    def scan_factors(self, scan: np.ndarray) -> np.ndarray:
        """Each particle's weight factor from ``scan`` under ``laser_model_type``.

        The likelihood fields skip beams with no return (inf or NaN, REP 117) and those at or past
        ``range_max``, as nav2 does. The beam model weighs a no-return as a max-range reading (nav2 maps
        readings under ``range_min`` to ``range_max`` as well, which is what amcl_node does before any model),
        and skips NaN beams only."""
        ranges, bearings, lidar = scan[self._beams], self._bearings, self.lidar
        if self.beam_model is not None:
            keep = ~np.isnan(ranges)
            readings = np.where(ranges[keep] <= lidar.min_range, lidar.max_range, ranges[keep])
            return self.beam_model.weight_factors(self.particles, readings, bearings[keep], self._mount)
        usable = np.isfinite(ranges) & (ranges >= lidar.min_range) & (ranges < lidar.max_range)
        if self.config.laser_model_type == "likelihood_field_prob":
            return self.field.prob_factors(
                self.particles, ranges[usable], bearings[usable], self._mount, self.beam_skip
            )
        return self.field.weight_factors(self.particles, ranges[usable], bearings[usable], self._mount)

    def _resample(self) -> None:
        """Draw with replacement, mixing in uniform particles with probability 1 - w_fast/w_slow (augmented
        MCL), until KLD's bound for the bins the new set occupies is met."""
        c = self.config
        w_diff = max(0.0, 1.0 - self.w_fast / self.w_slow) if self.w_slow > 0 else 0.0
        m = c.max_particles
        drawn = self.particles[multinomial_resample(self.weights, self.rng, m)]
        injected = self.rng.random(m) < w_diff
        if injected.any():
            drawn[injected] = self.free_space.sample(int(injected.sum()), self.rng)
        keys = bin_keys(drawn, c.bin_xy, c.bin_theta)
        n = kld_sample_count(keys, c.pf_err, c.pf_z, c.min_particles, c.max_particles)
        self.particles = drawn[:n]
        self.weights = np.full(n, 1.0 / n)
        if w_diff > 0 and c.reset_recovery_averages:  # nav2: so as not to spiral into complete randomness
            self.w_slow = self.w_fast = 0.0

    def _read_clusters(
        self, update: bool = False, previous: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray, str, tuple[Hypothesis, ...]]:
        """nav2's estimate (the heaviest cluster's mean and covariance), with the status and hypotheses the
        clusters give (particles/belief.py); ``update``: read at a measurement update (the status's
        confirmation counts it), ``previous`` the last estimate carried to it by the odometry."""
        belief = read_belief(self.particles, self.weights)
        best = belief.modes[0]
        status = belief_status(belief, 0, self.config.belief)
        if update:
            moved = previous is None or np.hypot(*(best.mean[:2] - previous[:2])) > 0.5
            status = self.confirmation(status, bool(moved))
        else:
            status = "lost"  # no scan weighed yet
        # nav2 reports the heaviest cluster's covariance; one of a single particle is zero, which is not certainty
        floor = np.diag(PUBLISHED_FLOOR**2)
        covariance = best.covariance + np.diag(np.maximum(np.diag(floor) - np.diag(best.covariance), 0.0))
        return best.mean, covariance, status, hypotheses_of(belief, self.config.belief.hypotheses)

    def _report(self, odom: np.ndarray, stamp: float, timings: dict[str, float]) -> PoseEstimate:
        """The last filter pose carried forward by the odometry since that update."""
        mean, cov, status, hypotheses = self._pose_at_update
        if self._odom_at_update is None:
            pose = mean
        else:
            pose = carry(mean, self._odom_at_update, odom)
        inside = {"particles": particle_sample(self.particles, INSIDE_PARTICLES)}
        return PoseEstimate(
            float(pose[0]), float(pose[1]), float(pose[2]), cov.copy(), stamp, timings, status, hypotheses,
            inside=inside,
        )  # fmt: skip

    @property
    def particle_count(self) -> int:
        return len(self.particles)
