"""The active bound: how soon a driver free to go anywhere could have shown the robot where it is."""

import pytest

import pimm_env.mapping.twins as twins_module
from pimm_agents.measurement.active_bound import active_bounds
from pimm_agents.measurement.passive_bound import BOUND_DISTINCT_TURN_DEG, BOUND_TWINS


def test_the_bound_looks_for_twins_as_the_passive_bound_does(monkeypatch: pytest.MonkeyPatch):
    asked = []
    real = twins_module.MapTwins

    def recording(occupancy, config):
        asked.append(config)
        return real(occupancy, config)

    monkeypatch.setattr(twins_module, "MapTwins", recording)
    (bound,) = active_bounds("iilab", ["area_a"])
    # a place turned half round is kept beside a match facing the other way (it was left out, and the bound early)
    assert [(c.max_twins, c.distinct_turn_deg) for c in asked] == [(BOUND_TWINS, BOUND_DISTINCT_TURN_DEG)]
    # area_a's start is a room of its own: its surroundings already tell it from every twin
    assert bound.scenario == "area_a" and bound.twins > 0 and bound.bound_s == 0.0
