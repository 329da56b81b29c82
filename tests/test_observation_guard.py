import numpy as np
import pytest

import pimm_agents.observation_guard as observation_guard
from pimm_agents.observation_guard import GuardConfig, ObservationGuard
from pimm_env.errors import ObservationError


def _obs(t: float, odom) -> dict:
    return {"time": np.array([t]), "odom": np.asarray(odom, dtype=np.float32), "scan_time": np.array([t])}


def test_a_one_step_odometry_jump_is_set_aside():
    guard = ObservationGuard()
    taken = [guard.take(_obs(0.1 * k, [0.05 * k + (100.0 if k == 10 else 0.0), 0.0, 0.0])) for k in range(20)]
    assert taken[10] is None and all(o is not None for i, o in enumerate(taken) if i != 10)
    assert np.allclose([o["odom"][0] for o in taken if o is not None], [0.05 * k for k in range(20) if k != 10])


def test_a_lasting_jump_becomes_a_new_base_that_counts_as_no_motion():
    guard = ObservationGuard()
    moved = []
    for k in range(30):
        raw = [0.05 * k + (50.0 if k >= 20 else 0.0), 0.0, 0.0]  # the odometry frame was reset at step 20
        out = guard.take(_obs(0.1 * k, raw))
        moved.append(None if out is None else float(out["odom"][0]))
    assert moved[20:24] == [None] * 4  # five observations in a row must agree first
    assert moved[24] == pytest.approx(0.95 + 4 * 0.05) and moved[29] == pytest.approx(0.95 + 9 * 0.05)


def test_stamps_that_go_back_or_leap_ahead_are_glitches():
    guard = ObservationGuard()
    assert guard.take(_obs(1.0, [0, 0, 0])) is not None
    assert guard.take(_obs(1e9, [0, 0, 0])) is None  # a stamp a billion seconds ahead
    assert guard.take(_obs(0.5, [0, 0, 0])) is None  # back in time
    assert guard.take(_obs(1.1, [0.01, 0, 0])) is not None
    assert guard.set_aside == {"stamp_gap": 1, "stamp_back": 1} and guard.glitches == 2  # counted by kind
    future_scan = guard.take({**_obs(1.2, [0.02, 0, 0]), "scan_time": np.array([99.0])})
    assert future_scan is not None and future_scan["scan_time"][0] == -np.inf  # that scan is not fresh


def test_bad_values_name_the_key_and_shape():
    guard = ObservationGuard()
    with pytest.raises(ValueError, match=r"observation 'odom' \(shape \(3,\)\) has 1 non-finite value"):
        guard.check(_obs(0.0, [0.0, np.nan, 0.0]), ("time", "odom"))
    with pytest.raises(ValueError, match=r"observation 'odom' has shape \(2,\), expected \(3,\)"):
        guard.check(_obs(0.0, [0.0, 0.0]), ("odom",))
    with pytest.raises(ObservationError, match="observation has no 'cloud_time'"):
        guard.check(_obs(0.0, [0, 0, 0]), ("cloud_time",))
    # a transposed cloud is named as such, not reported as a wrong mask
    transposed = {"cloud": np.zeros((3, 14400), np.float32), "cloud_mask": np.ones(14400, np.int8)}
    with pytest.raises(ValueError, match=r"observation 'cloud' has shape \(3, 14400\), expected \(N, 3\) points"):
        guard.cloud(transposed)


def test_the_limits_come_from_each_localizers_params():
    from pimm_agents.factory import make_localizer

    amcl = make_localizer(
        "amcl", map="maps/iilab/occupancy.yaml", sensors="thesis", params={"guard": {"max_speed": 10.0}}
    )
    assert amcl.guard.config == GuardConfig(max_speed=10.0)
    with pytest.raises(ObservationError, match="guard.max_turn_rate must be positive, got 0"):
        GuardConfig(max_turn_rate=0)
    # a faster robot than the limits: each step set aside at the defaults, taken with them raised
    fast = [_obs(1.0 * k, [5.0 * k, 0.0, 0.0]) for k in range(4)]  # 5 m/s
    strict, loose = ObservationGuard(), ObservationGuard(GuardConfig(max_speed=6.0))
    assert [strict.take(o) is None for o in fast] == [False, True, True, True]
    assert [loose.take(o) is None for o in fast] == [False, False, False, False]


def test_odometry_logged_in_bursts_is_taken(monkeypatch):
    # 1 m/s, measured every 0.1 s but stamped in bursts of five 2 ms apart, 0.5 s between bursts
    stamps = [0.5 * (k // 5) + 0.002 * (k % 5) for k in range(40)]
    guard = ObservationGuard()
    taken = [guard.take(_obs(t, [0.1 * k, 0.0, 0.0])) for k, t in enumerate(stamps)]
    assert all(o is not None for o in taken) and guard.glitches == 0
    monkeypatch.setattr(observation_guard, "STAMP_JITTER_S", 0.0)  # no allowance: the bursts are too fast
    tight = ObservationGuard()
    assert sum(tight.take(_obs(t, [0.1 * k, 0.0, 0.0])) is None for k, t in enumerate(stamps)) > 0


@pytest.mark.parametrize(
    "obs,said",
    [
        (None, "a dict of arrays.*NoneType"),
        ([1, 2, 3], "a dict of arrays.*list"),
        ({"odom": "east"}, "'odom' is not an array of numbers: str"),
    ],
)
def test_what_is_not_an_observation_is_an_observation_error_naming_it(obs, said):
    from pimm_agents.localizer import require

    with pytest.raises(ObservationError, match=said):
        require(obs, "odom", (3,))
