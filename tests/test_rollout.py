import numpy as np
import pytest

from pimm_env.driving.controller import PurePursuit
from pimm_env.driving.rollout import odom_to_map, run
from pimm_env.driving.scenarios import get_scenario, load_scenarios


def test_scenarios_are_available_by_name():
    scenarios = load_scenarios("iilab")
    assert set(scenarios) == {"area_a", "area_b", "a_c_b", "a_c_b_kidnap"}
    assert scenarios["a_c_b_kidnap"].kidnap_to is not None
    assert np.array_equal(scenarios["a_c_b_kidnap"].waypoints, scenarios["a_c_b"].waypoints)
    with pytest.raises(ValueError, match="valid: area_a"):
        get_scenario("area_z")


def drive_kinematically(waypoints: list, steps: int = 4000) -> tuple[PurePursuit, np.ndarray, float]:
    controller = PurePursuit(np.array(waypoints, dtype=float))
    pose, travelled = np.array([0.0, 0.0, 0.0]), 0.0
    for _ in range(steps):
        v, w = controller.command(pose)
        if controller.done:
            break
        pose = pose + 0.032 * np.array([v * np.cos(pose[2]), v * np.sin(pose[2]), w])
        travelled += 0.032 * abs(v)
    return controller, pose, travelled


def test_pure_pursuit_reaches_the_goal_kinematically():
    controller, pose, _ = drive_kinematically([[0, 0], [3, 0], [3, 2]])
    assert controller.done and np.hypot(pose[0] - 3, pose[1] - 2) < 0.15


def test_a_route_that_turns_back_on_itself_is_driven_to_its_end():
    controller, pose, travelled = drive_kinematically([[0, 0], [3, 0], [0, 0.05], [2, 0.1]])
    assert controller.done and np.hypot(pose[0] - 2, pose[1] - 0.1) < 0.15
    assert travelled == pytest.approx(3 + 3 + 2, abs=1.0)  # it turns within 0.2 m of each end


def test_odom_to_map():
    out = odom_to_map(np.array([[1.0, 0.0, 0.0]]), np.array([2.0, 3.0, np.pi / 2]))
    assert out[0] == pytest.approx([2.0, 4.0, np.pi / 2])


@pytest.mark.expensive
@pytest.mark.parametrize("name", ["area_a", "area_b", "a_c_b", "a_c_b_kidnap"])
def test_scenario_rollout_completes_without_touching_anything(name):
    scenario = get_scenario(name)
    result = run(scenario, seed=0, lidar3d=False)
    assert result.completed and not result.collided
    laps = 2 if scenario.kidnap_to is not None else 1
    assert result.length_m == pytest.approx(laps * scenario.thesis_length_m, rel=0.05)
    if laps == 1:
        assert 0.0 < result.drift_percent < 5.0
