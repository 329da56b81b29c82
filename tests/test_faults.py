"""Faults as wrappers: LiDAR dropout, odometry slip, kidnaps at set times, and how a trial records them."""

from dataclasses import replace

import numpy as np
import pytest
from typer.testing import CliRunner

import evaluate
from pimm_agents.experiments.recorder import LocalizationRecorder
from pimm_agents.scoring.metrics import kidnap_recoveries
from pimm_agents.scoring.trial_log import TrialLog
from pimm_env.driving.rollout import drive, run
from pimm_env.driving.scenarios import get_scenario
from pimm_env.envs.base_env import SimConfig
from pimm_env.envs.faults import (
    KIDNAP_WINDOW_S,
    Fault,
    Kidnaps,
    LidarDropout,
    OdometrySlip,
    kidnap_trial_fault,
    parse_faults,
    with_faults,
)
from pimm_env.envs.iilab_env import IILabEnv
from pimm_env.geometry import relative_motion
from tests.plugins.dead_reckoning import DeadReckoning

START = [-10.0, 4.2, 0.0]  # area_b's corridor: 8 m straight ahead are free


def env_2d() -> IILabEnv:
    config = SimConfig()
    return IILabEnv(
        config=replace(config, lidar3d=replace(config.lidar3d, enabled=False)), terminate_on_collision=False
    )


def time_of(obs) -> float:
    return float(obs["time"][0])


def test_fault_specs_parse_and_bad_ones_name_the_item():
    assert parse_faults("dropout@30:5, slip@20:3,kidnap@40,kidnap@70") == [
        Fault("dropout", 30.0, 5.0),
        Fault("slip", 20.0, 3.0),
        Fault("kidnap", 40.0),
        Fault("kidnap", 70.0),
    ]
    assert parse_faults("") == []
    for bad, message in [
        ("fog@3:1", "'fog@3:1'.*one of dropout, slip, kidnap"),
        ("dropout@30", "needs a duration"),
        ("slip@x:2", "must be numbers"),
        ("kidnap@-4", "START must be >= 0"),
    ]:
        with pytest.raises(ValueError, match=message):
            parse_faults(bad)
    result = CliRunner().invoke(evaluate.app, ["run", "--fault", "fog@3:1", "--trials", "1"])
    assert result.exit_code == 1 and "error: fault 'fog@3:1'" in result.output


def test_dropout_blanks_both_lidars_in_its_window_only():
    config = SimConfig()
    env = LidarDropout(IILabEnv(config=config, terminate_on_collision=False), [Fault("dropout", 0.2, 0.3)])
    obs, _ = env.reset(seed=0, options={"pose": START})
    seen = {"in": 0, "out": 0}
    while time_of(obs) < 0.7:
        obs, *_, info = env.step(np.array([0.2, 0.0], dtype=np.float32))
        if 0.2 <= time_of(obs) < 0.5:
            assert not obs["cloud_mask"].any() and np.all(obs["scan"] == config.lidar2d.max_range)
            assert info["fault"] == "dropout"
            seen["in"] += 1
        elif time_of(obs) >= 0.5 and obs["cloud_mask"].any():
            assert (obs["scan"] < config.lidar2d.max_range).any() and "fault" not in info
            seen["out"] += 1
    env.close()
    assert seen["in"] > 5 and seen["out"] > 0


def test_slip_over_reports_distance_and_leaves_the_heading_wrong():
    base = env_2d()
    env = OdometrySlip(base, [Fault("slip", 0.5, 1.0)], scale=0.3, yaw_rate=0.1)
    obs, _ = env.reset(seed=0, options={"pose": START})
    inner_start, outer_start = base.robot.odom.copy(), np.asarray(obs["odom"], float)
    while time_of(obs) < 2.0:
        before_inner, before_outer = base.robot.odom.copy(), np.asarray(obs["odom"], float)
        obs, *_ = env.step(np.array([0.4, 0.0], dtype=np.float32))
        inner = relative_motion(before_inner, base.robot.odom)
        outer = relative_motion(before_outer, np.asarray(obs["odom"], float))
        if time_of(obs) < 0.5 or time_of(obs) >= 1.5:  # outside the burst: the env's increments exactly
            np.testing.assert_allclose(outer[:2], inner[:2], atol=1e-5)
    env.close()
    inner_total = relative_motion(inner_start, base.robot.odom)
    outer_total = relative_motion(outer_start, np.asarray(obs["odom"], float))
    # 1 s of the 2 s at 0.4 m/s over-reported by 30 %: about 0.12 m more, and 0.1 rad of heading that stays
    assert 0.08 < np.hypot(*outer_total[:2]) - np.hypot(*inner_total[:2]) < 0.16
    assert outer_total[2] - inner_total[2] == pytest.approx(0.1, abs=0.01)


def test_kidnaps_land_on_the_route_and_the_trial_records_each():
    scenario = get_scenario("area_b")
    env = Kidnaps(env_2d(), parse_faults("kidnap@1,kidnap@2"), route=scenario.waypoints)
    recorder = LocalizationRecorder(env, DeadReckoning())
    obs, info = recorder.reset(seed=0, options={"pose": scenario.start})
    poses, odoms, kidnaps = [info["true_pose"]], [obs["odom"]], []
    while time_of(obs) < 2.5:
        obs, *_, info = recorder.step(np.array([0.3, 0.0], dtype=np.float32))
        if info.get("kidnapped"):
            kidnaps.append(len(poses))
        poses.append(info["true_pose"])
        odoms.append(obs["odom"])
    env.close()
    assert len(kidnaps) == 2
    for k in kidnaps:
        assert np.hypot(*(poses[k][:2] - poses[k - 1][:2])) > 0.5  # teleported ...
        assert np.hypot(*(odoms[k][:2] - odoms[k - 1][:2])) < 0.05  # ... and the odometry did not see it
        path = np.asarray(scenario.waypoints)
        gaps = [np.hypot(*(poses[k][:2] - p)) for p in np.linspace(path[:-1], path[1:], 50).reshape(-1, 2)]
        assert min(gaps) < 0.1  # on the route
    log = recorder.trial_log()
    assert len(log.kidnap_rows) == 2 and log.kidnap_index == log.kidnap_rows[-1]
    again = Kidnaps(env_2d(), parse_faults("kidnap@1,kidnap@2"), route=scenario.waypoints)
    again.reset(seed=0, options={"pose": scenario.start})
    while True:
        obs, *_, info = again.step(np.array([0.3, 0.0], dtype=np.float32))
        if info.get("kidnapped"):
            np.testing.assert_allclose(info["true_pose"], poses[kidnaps[0]])  # seeded: the same landing
            break
    again.close()


def test_kidnap_recoveries_time_each_kidnap_until_the_error_stays_small():
    t = np.arange(10.0)
    true = np.zeros((10, 3))
    est = np.zeros((10, 3))
    est[[3, 4, 7, 8, 9], 0] = 5.0  # kidnap at row 3 recovered at row 5; kidnap at row 7 never
    log = TrialLog(t, t, true, est, np.zeros((10, 3)), 7, kidnap_rows=(3, 7))
    assert kidnap_recoveries(log) == [2.0, None]
    assert TrialLog(t, t, true, est, np.zeros((10, 3)), 3).kidnap_rows == (3,)


def test_with_faults_stacks_one_wrapper_per_kind():
    env = with_faults(env_2d(), parse_faults("slip@1:1,dropout@2:1,kidnap@3"), route=np.array([[0, 0], [1, 0]]))
    assert isinstance(env, Kidnaps) and isinstance(env.env, LidarDropout) and isinstance(env.env.env, OdometrySlip)
    env.close()


def test_the_driver_carries_on_from_where_a_kidnap_put_the_robot():
    scenario = get_scenario("area_b")
    env = Kidnaps(env_2d(), parse_faults("kidnap@5,kidnap@15"), route=scenario.waypoints)
    env.reset(seed=1, options={"pose": scenario.start})
    completed, collided, poses, _ = drive(env, scenario.waypoints, scenario.speed)
    env.close()
    assert completed and not collided
    assert np.hypot(*(poses[-1][:2] - np.asarray(scenario.waypoints)[-1])) < 0.2


def test_a_kidnap_may_land_anywhere_and_the_driver_gets_a_route_from_there():
    assert parse_faults("kidnap@40:anywhere") == [Fault("kidnap", 40.0, 0.0, "anywhere")]
    with pytest.raises(ValueError, match="lands on one of route, anywhere"):
        parse_faults("kidnap@40:moon")
    scenario = get_scenario("area_b")
    env = with_faults(env_2d(), parse_faults(kidnap_trial_fault(3)), route=scenario.waypoints)
    seen = {}

    def watch(obs, info):
        if info.get("kidnapped"):
            seen.update(info, time=time_of(obs))

    result = run(scenario, seed=3, env=env, on_step=watch)
    assert seen["landing"] in ("twin", "free") and KIDNAP_WINDOW_S[0] <= seen["time"] <= KIDNAP_WINDOW_S[1] + 0.2
    jump = result.true_path[np.argmax(np.hypot(*np.diff(result.true_path[:, :2], axis=0).T)) + 1]
    np.testing.assert_allclose(jump[:2], seen["route"][0], atol=1e-6)  # the route starts where it landed
    assert result.completed and not result.collided  # ... and the robot drove it to its end
    assert np.hypot(*(result.true_path[-1, :2] - seen["route"][-1])) < 0.5


def test_landings_go_into_twins_turned_and_elsewhere_far_enough():
    from pimm_env.driving.landings import TWIN_TURN_DEG, Landings
    from pimm_env.mapping.derived_maps import load_derived_maps
    from pimm_env.mapping.twins import MapTwins, TwinConfig
    from pimm_env.world.files import load_world

    occupancy = load_derived_maps(load_world("iilab")).occupancy
    twins = MapTwins(occupancy, TwinConfig())
    landings = Landings(occupancy, twins)
    place = np.array([-10.0, 4.2, 0.0])
    kinds = set()
    for seed in range(8):
        pose, route, kind = landings.draw(place, np.random.default_rng(seed))
        kinds.add(kind)
        assert np.hypot(*(pose[:2] - place[:2])) >= 5.0 and np.hypot(*(route[0] - pose[:2])) < 1e-9
        assert np.hypot(*np.diff(route, axis=0).T).sum() >= 15.0
        if kind == "twin":  # near one of the place's twins, turned away from its heading
            near = twins.of(place)[np.argmin(np.hypot(*(twins.of(place)[:, :2] - pose[:2]).T))]
            assert np.hypot(*(near[:2] - pose[:2])) <= 0.2
            assert abs(np.degrees(np.angle(np.exp(1j * (pose[2] - near[2]))))) >= TWIN_TURN_DEG - 1e-6
    assert kinds == {"twin", "free"}
