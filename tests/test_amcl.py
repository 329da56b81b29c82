from dataclasses import replace

import numpy as np
import pytest

from pimm_agents import available_localizers, make_localizer
from pimm_agents.amcl.localizer import Amcl, AmclConfig, subsample_beams
from pimm_agents.experiments.runner import run_trial
from pimm_agents.scoring.metrics import position_errors
from pimm_agents.scoring.trial import TrialSpec
from pimm_env.driving.rollout import drive
from pimm_env.driving.scenarios import get_scenario
from pimm_env.envs.base_env import SimConfig
from pimm_env.envs.iilab_env import IILabEnv
from pimm_env.errors import ObservationError
from pimm_env.mapping.occupancy import OccupancyGrid
from pimm_env.world.grid import GridSpec
from tests.rooms import box_room, observation


def test_registered_names_and_unknown_ones():
    assert {"amcl", "amcl-recovery", "amcl-recovery-nav2"} <= set(available_localizers())
    with pytest.raises(ValueError, match="valid: .*amcl-recovery"):
        make_localizer("nope")
    with pytest.raises(ValueError, match="unknown key .particles.; valid keys: .*max_particles"):
        make_localizer("amcl", particles=3)


def test_defaults_are_nav2s_and_recovery_differs_only_in_the_averages_and_their_reset():
    a, r = make_localizer("amcl"), make_localizer("amcl-recovery")
    assert a.config == AmclConfig()
    assert (a.config.min_particles, a.config.max_particles, a.config.max_beams, a.config.sigma_hit) == (
        500,
        2000,
        60,
        0.2,
    )
    nav2 = make_localizer("amcl-recovery-nav2").config
    assert nav2 == replace(a.config, recovery_alpha_slow=0.001, recovery_alpha_fast=0.1)
    assert a.config.reset_recovery_averages and nav2.reset_recovery_averages
    assert r.config == replace(nav2, reset_recovery_averages=False)
    assert len(subsample_beams(360, 60)) == 60 and subsample_beams(360, 60)[-1] == 354


def test_reset_spreads_particles_over_free_space_reproducibly():
    amcl = Amcl(box_room())
    amcl.reset(seed=3)
    first = amcl.particles.copy()
    assert len(first) == 2000
    rows, cols, inside = amcl.field.grid.cells_of(first[:, :2])
    assert inside.all() and amcl.free_space is not None
    assert not box_room().occupied[rows, cols].any()
    amcl.reset(seed=3)
    np.testing.assert_array_equal(first, amcl.particles)


def test_bad_input_gives_clear_errors_or_skipped_beams_never_nan():
    amcl = Amcl(box_room(), AmclConfig(max_particles=300, min_particles=100))
    amcl.reset(seed=0)
    with pytest.raises(ValueError, match=r"'scan' has shape \(10,\), expected \(360,\).* 360 beams .*sensors="):
        amcl.update(observation(np.ones(10)))
    with pytest.raises(ObservationError, match="no 'odom'"):
        amcl.update({"scan": np.ones(360)})
    scan = np.full(360, 2.0)
    scan[::3] = np.nan
    scan[1::3] = -1.0
    estimate = amcl.update(observation(scan))
    assert np.all(np.isfinite(estimate.pose)) and np.all(np.isfinite(estimate.covariance))
    all_bad = amcl.update(observation(np.full(360, np.nan), t=0.1))
    assert np.all(np.isfinite(all_bad.pose))
    empty = OccupancyGrid(GridSpec((0, 0), 0.05, (10, 10)), np.zeros((10, 10), bool), np.zeros((10, 10), bool))
    with pytest.raises(ValueError, match="no free cell"):
        Amcl(empty)
    with pytest.raises(ValueError, match="min_particles"):
        AmclConfig(min_particles=10, max_particles=5)


def test_updates_are_gated_by_motion_and_repeated_scans_are_ignored():
    amcl = Amcl(box_room(), AmclConfig(max_particles=300, min_particles=100))
    amcl.reset(seed=0)
    scan = np.full(360, 1.5)
    assert amcl.update(observation(scan)).timings  # the first scan always updates
    assert not amcl.update(observation(scan, t=0.0)).timings  # same scan again
    assert not amcl.update(observation(scan, odom=(0.1, 0.0, 0.0), t=0.1)).timings  # moved too little
    assert amcl.update(observation(scan, odom=(0.3, 0.0, 0.0), t=0.2)).timings
    assert amcl.update(observation(scan, odom=(0.3, 0.0, 0.25), t=0.3)).timings  # turned enough


def area_b_env() -> IILabEnv:
    config = SimConfig()
    return IILabEnv(
        config=replace(config, lidar3d=replace(config.lidar3d, enabled=False)), terminate_on_collision=False
    )


@pytest.mark.expensive
def test_tracks_area_b_from_a_known_pose():
    env, amcl = area_b_env(), make_localizer("amcl")
    scenario = get_scenario("area_b")
    obs, _ = env.reset(seed=0, options={"pose": scenario.start})
    amcl.reset(seed=0, initial_pose=scenario.start, initial_cov=np.diag([0.01, 0.01, 0.001]))
    amcl.update(obs)
    errors, statuses, traces = [], [], []

    def check(obs, info):
        estimate = amcl.update(obs)
        if info["fresh_scan"]:
            errors.append(np.hypot(*(estimate.pose[:2] - info["true_pose"][:2])))
            statuses.append(estimate.status)
            traces.append(np.trace(estimate.covariance[:2, :2]))

    assert drive(env, scenario.waypoints, scenario.speed, check)[0]
    env.close()
    # the status comes from the clusters: not localized before 10 updates have confirmed it, then localized with
    # the cluster's covariance (nav2's), not a whole-map spread
    assert statuses[0] != "localized" and statuses[-1] == "localized"
    assert np.mean([s == "localized" for s in statuses[len(statuses) // 4 :]]) > 0.9
    assert max(traces[len(traces) // 4 :]) < 1.0
    # Measured over seeds 0-3: mean 0.09 m, 95th percentile 0.14-0.23 m; nav2's alpha = 0.2 motion noise spreads
    # the cloud by about 0.1 m per 0.25 m update, which is where the peaks come from. Seed 0 read 0.16 m until
    # the switched-off 3D LiDAR stopped drawing from the env's noise stream; it reads 0.225 m since.
    assert np.mean(errors) < 0.15
    assert np.percentile(errors, 95) < 0.25


@pytest.mark.expensive
def test_converges_globally_in_area_b():
    results = [run_trial(TrialSpec("area_b", "amcl", trial, seed)) for trial, seed in enumerate((0, 3))]
    assert all(r.metrics.converged for r in results)
    assert all(r.metrics.position_error_m < 0.3 for r in results)


@pytest.mark.expensive
def test_plain_amcl_never_recovers_from_the_kidnap():
    result = run_trial(TrialSpec("a_c_b_kidnap", "amcl", 0, 0))
    assert result.log.kidnap_index is not None and not result.metrics.converged


@pytest.mark.expensive
def test_recovery_recovers_from_the_kidnap():
    # amcl-recovery recovered in 10 of 10 kidnap trials (seeds 0-9, 2026-11-23), 20-61 s after the kidnap;
    # seed 3 is the slowest (61 s), so the mean error since convergence still holds the last metres of the search
    result = run_trial(TrialSpec("a_c_b_kidnap", "amcl-recovery", 3, 3))
    assert result.log.kidnap_index is not None and result.metrics.converged
    last = result.log.time >= result.log.time[-1] - 5.0
    assert np.median(position_errors(result.log)[last]) < 0.3  # and it has the pose at the end


def test_recovery_injects_uniform_particles_once_the_scan_stops_fitting():
    # Localized in the room, then the scan fits nowhere (every beam 9.5 m, far beyond the room's walls):
    # w_fast falls below w_slow, and the recovering variants draw fresh uniform particles while plain amcl
    # only resamples its old cloud. nav2 then zeroes both averages, so amcl-recovery-nav2 injects in one burst;
    # amcl-recovery keeps them and goes on injecting while the scans fit badly.
    room = box_room()
    here = np.array([1.0, 1.0, 0.0])
    true_scan = _synthetic_scan(room, here)
    wrong_scan = np.full(360, 9.5)
    injections = {}
    for name in ("amcl", "amcl-recovery-nav2", "amcl-recovery"):
        amcl = Amcl(room, make_localizer(name).config)
        amcl.reset(seed=1, initial_pose=here, initial_cov=np.diag([0.01, 0.01, 0.001]))
        draws = []
        sample = amcl.free_space.sample
        amcl.free_space.sample = lambda n, rng, sample=sample, draws=draws: draws.append(n) or sample(n, rng)
        t = 0.0
        for step in range(60):  # w_fast needs a dozen bad updates to sink below w_slow
            t += 0.1
            scan = true_scan if step < 10 else wrong_scan
            amcl.update(observation(scan, odom=(0.0, 0.0, 0.21 * (step % 2)), t=t))
            if step == 9:
                assert not draws  # while the scan fits, nothing is injected
        injections[name] = draws
    assert injections["amcl"] == []
    assert sum(injections["amcl-recovery-nav2"]) > 50
    assert len(injections["amcl-recovery"]) > 3 * len(injections["amcl-recovery-nav2"])


def _synthetic_scan(room: OccupancyGrid, pose: np.ndarray) -> np.ndarray:
    """Ranges by marching 1 cm steps along each beam until an occupied cell."""
    angles = pose[2] - np.pi + 2 * np.pi * np.arange(360) / 360
    steps = np.arange(1, 1000) * 0.01
    xs = pose[0] + np.cos(angles)[:, None] * steps
    ys = pose[1] + np.sin(angles)[:, None] * steps
    rows, cols, valid = room.grid.cells_of(np.column_stack([xs.ravel(), ys.ravel()]))
    hit = np.ones(len(rows), bool)
    hit[valid] = room.occupied[rows[valid], cols[valid]]
    first = hit.reshape(360, -1).argmax(axis=1)
    return steps[first]


def test_a_100_m_odometry_glitch_and_a_nan_leave_the_estimate_where_it_was():
    room = box_room()
    amcl = Amcl(room, AmclConfig(max_particles=500, min_particles=100))
    amcl.reset(seed=0, initial_pose=np.array([2.0, 2.0, 0.0]))
    scan = np.full(360, 10.0, dtype=np.float32)
    obs = {"odom": np.zeros(3, np.float32), "scan": scan, "time": np.array([0.0]), "scan_time": np.array([0.0]),
           "cloud": np.zeros((1, 3), np.float32), "cloud_mask": np.zeros(1, np.int8)}  # fmt: skip
    before = amcl.update(obs).pose
    glitch = {**obs, "odom": np.array([100.0, 0.0, 0.0], np.float32), "time": np.array([0.032])}
    assert np.array_equal(amcl.update(glitch).pose, before)
    with pytest.raises(ValueError, match="observation 'odom'"):
        amcl.update({**obs, "odom": np.array([np.nan, 0.0, 0.0], np.float32), "time": np.array([0.064])})
    after = amcl.update({**obs, "time": np.array([0.096])})
    assert np.allclose(after.pose, before) and np.all(np.isfinite(after.covariance))


def test_a_single_particle_cluster_is_not_certainty():
    """nav2 reports the heaviest cluster's covariance; one of one particle is zero: reported with a floor."""
    from pimm_agents.factory import make_localizer
    from pimm_agents.localizer import PUBLISHED_FLOOR

    amcl = make_localizer("amcl")
    amcl.reset(seed=0, initial_pose=np.array([-10.0, 4.2, 0.0]), initial_cov=np.zeros((3, 3)))
    amcl.particles[:] = amcl.particles[0]  # every particle on one pose: a degenerate cluster
    _, covariance, _, _ = amcl._read_clusters(update=True)
    assert np.all(np.diag(covariance) >= PUBLISHED_FLOOR**2 - 1e-15)
