"""Property tests (hypothesis): every registered localizer takes any finite, well-shaped observation stream
without raising and never reports a NaN pose.

Hypothesis chooses the stream's structure (time running forwards, backwards or leaping ahead; odometry still,
drifting or jumping; scans empty, short, long, negative, huge; clouds empty, partial, far, at the origin);
a numpy generator seeded by hypothesis fills the arrays of the env's shapes.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from pimm_agents import available_localizers, make_localizer
from pimm_env.envs.base_env import SimConfig
from pimm_env.envs.env_spaces import observation_space

SPACE = observation_space(SimConfig())
CLOUD_N = SPACE["cloud"].shape[0]
BEAMS = SPACE["scan"].shape[0]
FAST = [name for name in available_localizers() if name != "registration"]
_BUILT: dict[str, object] = {}
#: a coarse range table keeps the beam model's one-off cast to seconds; what is tested here does not need 1 degree
QUICK = {"amcl-beam": {"beam_range_headings": 36}}


def localizer(name: str):
    if name not in _BUILT:
        _BUILT[name] = make_localizer(name, world="iilab", **QUICK.get(name, {}))
    return _BUILT[name]


step = st.fixed_dictionaries(
    {
        "dt": st.sampled_from([0.0, 0.032, 0.1, -0.5, 1e6, -1e6]),  # time: repeated, on, backwards, far off
        "odom": st.sampled_from(["still", "drive", "turn", "jump", "huge"]),
        "scan": st.sampled_from(["room", "zeros", "negative", "huge", "tiny"]),
        "cloud": st.sampled_from(["room", "empty", "origin", "far", "sparse"]),
        "fresh": st.booleans(),
    }
)


def observations(seed: int, steps: list[dict]) -> list[dict[str, np.ndarray]]:
    rng = np.random.default_rng(seed)
    t, odom, out = 0.0, np.zeros(3), []
    for s in steps:
        t = max(t + s["dt"], 0.0) if abs(s["dt"]) < 1e5 else abs(s["dt"])
        moves = {
            "still": np.zeros(3),
            "drive": np.array([0.05, 0.0, 0.01]),
            "turn": np.array([0.0, 0.0, 0.3]),
            "jump": rng.normal(0, 50, 3),
            "huge": np.array([1e5, -1e5, 3.0]),
        }
        odom = odom + moves[s["odom"]]
        odom[2] = (odom[2] + np.pi) % (2 * np.pi) - np.pi
        scan = {
            "room": rng.uniform(0.5, 8.0, BEAMS),
            "zeros": np.zeros(BEAMS),
            "negative": -rng.uniform(0, 5, BEAMS),
            "huge": np.full(BEAMS, 1e30),
            "tiny": np.full(BEAMS, 1e-30),
        }[s["scan"]]
        directions = rng.normal(size=(CLOUD_N, 3))
        directions /= np.linalg.norm(directions, axis=1, keepdims=True)
        cloud, mask = {
            "room": (directions * rng.uniform(0.5, 9.0, (CLOUD_N, 1)), np.ones(CLOUD_N)),
            "empty": (np.zeros((CLOUD_N, 3)), np.zeros(CLOUD_N)),
            "origin": (np.zeros((CLOUD_N, 3)), np.ones(CLOUD_N)),
            "far": (directions * 1e6, np.ones(CLOUD_N)),
            "sparse": (directions * 3.0, (rng.random(CLOUD_N) < 0.01).astype(float)),
        }[s["cloud"]]
        stamp = np.array([t])
        out.append(
            {
                "odom": odom.astype(np.float32),
                "scan": scan.astype(np.float32),
                "cloud": cloud.astype(np.float32),
                "cloud_mask": mask.astype(np.int8),
                "time": stamp,
                "scan_time": stamp if s["fresh"] else np.array([0.0]),
                "cloud_time": stamp if s["fresh"] else np.array([0.0]),
            }
        )
    return out


def check_stream(name: str, seed: int, steps: list[dict]) -> None:
    loc = localizer(name)
    loc.reset(seed=seed)  # type: ignore[attr-defined]
    for obs in observations(seed, steps):
        estimate = loc.update(obs)  # type: ignore[attr-defined]
        assert np.all(np.isfinite(estimate.pose)), (name, obs["time"], estimate.pose)
        assert np.all(np.isfinite(estimate.covariance)), name


@pytest.mark.parametrize("name", FAST)
@settings(max_examples=8, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**16), steps=st.lists(step, min_size=1, max_size=5))
def test_any_finite_well_shaped_stream_gives_finite_poses(name, seed, steps):
    check_stream(name, seed, steps)


@pytest.mark.expensive
@settings(max_examples=8, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**16), steps=st.lists(step, min_size=1, max_size=5))
def test_registration_takes_any_finite_well_shaped_stream(seed, steps):
    check_stream("registration", seed, steps)
