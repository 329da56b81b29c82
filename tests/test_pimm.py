import dataclasses

import numpy as np
import pytest

from pimm_agents import make_localizer
from pimm_agents.pimm.localizer import PimmLocalizer
from pimm_env.envs.iilab_env import IILabEnv


@pytest.fixture(scope="module")
def pimm() -> PimmLocalizer:
    localizer = make_localizer("pimm", filter={"num_particles": 2000})
    assert isinstance(localizer, PimmLocalizer)
    return localizer


def test_pimm_reports_finite_estimates_with_stage_timings(pimm):
    env = IILabEnv()
    obs, _ = env.reset(seed=0, options={"pose": [-18.5, 14.0, 1.57]})
    pimm.reset(seed=0)
    stages, checked = set(), 0
    for _ in range(40):
        estimate = pimm.update(obs)
        assert np.isfinite(estimate.pose).all() and np.isfinite(estimate.covariance).all()
        stages |= set(estimate.timings)
        if "rival_check" in estimate.timings:  # a part of the measurement update, timed inside it
            assert 0 <= estimate.timings["rival_check"] <= estimate.timings["measurement_update"]
            checked += estimate.timings["rival_check"] > 0
        obs, *_ = env.step(np.array([0.3, 0.0], dtype=np.float32))
    env.close()
    assert {"segmentation", "corners", "pose_inference", "measurement_update", "rival_check", "total"} <= stages
    assert checked > 0


def test_pimm_survives_scans_with_no_returns(pimm):
    env = IILabEnv()
    obs, _ = env.reset(seed=1)
    env.close()
    pimm.reset(seed=1)
    empty = dict(obs, cloud_mask=np.zeros_like(obs["cloud_mask"]))
    for k in range(5):
        moved = dict(empty, odom=obs["odom"] + np.array([0.2 * k, 0.0, 0.0], dtype=np.float32))
        moved["time"] = moved["cloud_time"] = np.array([0.1 * k])
        estimate = pimm.update(moved)
        assert np.isfinite(estimate.pose).all()
    assert pimm.filter.weights.sum() == pytest.approx(1.0)


def test_a_stamp_from_the_future_and_a_nan_do_not_stop_pimm(pimm):
    env = IILabEnv()
    obs, _ = env.reset(seed=2, options={"pose": [-18.5, 14.0, 1.57]})
    pimm.reset(seed=2)
    perceived_after = weighed_after = 0
    for step in range(70):
        if step == 10:  # one observation stamped a billion seconds ahead: set aside
            future = dict(obs, time=obs["time"] + 1e9, cloud_time=obs["cloud_time"] + 1e9)
            assert np.isfinite(pimm.update(future).pose).all()
        if step == 12:  # a NaN in the odometry: a clear error, and nothing of the filter touched
            with pytest.raises(ValueError, match="observation 'odom'"):
                pimm.update(dict(obs, odom=np.array([np.nan, 0.0, 0.0], dtype=np.float32)))
        estimate = pimm.update(obs)
        assert np.isfinite(estimate.pose).all()
        perceived_after += step > 12 and "segmentation" in estimate.timings
        weighed_after += step > 12 and "measurement_update" in estimate.timings
        obs, *_ = env.step(np.array([0.3, 0.0], dtype=np.float32))
    env.close()
    assert perceived_after == weighed_after >= 4  # later 3D scans were still taken, each before it weighed
    assert pimm.guard.glitches == 1


def test_each_scan_weighs_the_particles_once(pimm, monkeypatch):
    """Motion updates between two scans move the particles but do not weigh them with the same scan again."""
    env = IILabEnv()
    obs, _ = env.reset(seed=2, options={"pose": [-18.5, 14.0, 1.57]})
    env.close()
    pimm.reset(seed=2)
    weighed = []
    original = pimm.filter.weigh
    monkeypatch.setattr(pimm.filter, "weigh", lambda *a, **k: weighed.append(1) or original(*a, **k))
    for k in range(6):  # 0.2 m a step, well past the motion threshold; a new scan every third step
        moved = dict(obs, odom=obs["odom"] + np.array([0.2 * k, 0.0, 0.0], dtype=np.float32))
        moved["time"] = np.array([0.1 * k])
        moved["cloud_time"] = np.array([0.1 * (k - k % 3)])
        pimm.update(moved)
    assert len(weighed) == 2  # steps 1 and 3 (step 0 only sets the odometry reference; 2, 4, 5 reuse a scan)


def test_unknown_pimm_setting_lists_the_valid_ones():
    with pytest.raises(ValueError, match="pimm: unknown key 'particles'; valid keys: belief, corners, filter"):
        make_localizer("pimm", particles=10)
    with pytest.raises(ValueError, match="pimm.filter: unknown key 'particles'; valid keys: .*num_particles"):
        make_localizer("pimm", filter={"particles": 10})


def test_reset_returns_to_a_uniform_cloud(pimm):
    pimm.reset(seed=3)
    first = pimm.filter.particles.copy()
    pimm.reset(seed=3)
    assert np.array_equal(first, pimm.filter.particles)
    assert np.allclose(pimm.filter.weights, 1.0 / len(first))
    assert np.ptp(first[:, 0]) > 20 and np.ptp(first[:, 1]) > 15  # spread over the whole building


@pytest.mark.expensive
def test_pimm_converges_in_area_b():
    from pimm_agents.experiments.runner import run_trial
    from pimm_agents.scoring.trial import TrialSpec

    result = run_trial(TrialSpec(scenario="area_b", localizer="pimm", trial=0, seed=0))
    assert result.metrics.converged, result.metrics
    # the trial log keeps the corners PIMM detected, placed at its estimate: once converged, on the map's corners
    from pimm_env.mapping.derived_maps import ensure_derived_maps
    from pimm_env.world.files import load_world

    corners = result.log.corners
    late = corners[result.log.time[corners[:, 0].astype(int)] >= result.log.time[0] + 20.0]
    assert len(late) > 20
    map_xy = ensure_derived_maps(load_world("iilab")).corners.xy
    nearest = np.min(np.linalg.norm(late[:, None, 1:] - map_xy[None], axis=2), axis=1)
    assert np.median(nearest) < 0.3


def test_pimm_reads_an_os0_64_through_the_networks_layout():
    pimm = make_localizer("pimm", filter={"num_particles": 1000}, sensors="os0-64")
    env = IILabEnv(sensors="os0-64")
    obs, _ = env.reset(seed=0, options={"pose": [-18.5, 14.0, 1.57]})
    assert obs["cloud"].shape == (64 * 1024, 3)
    pimm.reset(seed=0)
    perceived = 0
    for _ in range(25):  # a scan is perceived when the filter weighs with it (every 0.1 m or 0.01 rad)
        estimate = pimm.update(obs)
        assert np.isfinite(estimate.pose).all()
        perceived += "segmentation" in estimate.timings
        obs, *_ = env.step(np.array([0.3, 0.0], dtype=np.float32))
    env.close()
    assert perceived >= 2 and len(pimm.last_estimate.inside["corners"]) > 0  # scans segmented, corners found


def test_an_empty_corner_map_leaves_pimm_its_walls_and_fingerprints():
    import warnings

    from pimm_agents.perception.files import load_perception
    from pimm_agents.pimm.config import PRESETS, PimmConfig
    from pimm_env.errors import LocalizerError
    from pimm_env.mapping.corner_map import CornerMap
    from pimm_env.mapping.derived_maps import ensure_derived_maps
    from pimm_env.world.files import load_world

    world = load_world("iilab")
    maps, (segmenter, fingerprints) = ensure_derived_maps(world), load_perception(world)
    empty = CornerMap(xy=np.zeros((0, 2)), z=np.zeros(0), theta=np.zeros(0))
    with warnings.catch_warnings(record=True) as heard:
        warnings.simplefilter("always")
        pimm = PimmLocalizer(maps.occupancy, empty, segmenter, fingerprints, PimmConfig())
    assert len(heard) == 1 and "corner map is empty" in str(heard[0].message)
    env = IILabEnv()
    obs, _ = env.reset(seed=0, options={"pose": [-18.5, 14.0, 1.57]})
    pimm.reset(seed=0, initial_pose=np.array([-18.5, 14.0, 1.57]), initial_cov=np.diag([0.25, 0.25, 0.07]))
    truth = np.array([-18.5, 14.0, 1.57])
    for _ in range(60):
        estimate = pimm.update(obs)
        assert np.isfinite(estimate.pose).all()
        assert np.hypot(*(estimate.pose[:2] - truth[:2])) < 0.5  # tracked on the wall field
        obs, _, _, _, info = env.step(np.array([0.3, 0.0], dtype=np.float32))
        truth = info["true_pose"]
    env.close()
    off = PRESETS["pimm-thesis"]  # corners and suggestions only
    with pytest.raises(LocalizerError, match="rivals.enabled needs pimm.wall_field.enabled"):
        PimmConfig(wall_field=dataclasses.replace(PimmConfig().wall_field, enabled=False))
    with pytest.raises(LocalizerError, match="corner map is empty and the wall field is off"):
        PimmLocalizer(maps.occupancy, empty, segmenter, fingerprints, off)
