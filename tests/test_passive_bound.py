"""The passive bound: the first time the truth leads every look-alike of it by the rival check's margin."""

import pytest

from pimm_agents.measurement.passive_bound import passive_bound


@pytest.mark.expensive
def test_the_bound_comes_once_enough_scans_are_kept_where_nothing_looks_alike():
    bound = passive_bound("iilab", "area_a", seed=0)
    # area_a starts in a room of its own: the truth is unrivalled as soon as 20 scans are kept (a few seconds)
    assert bound.bound_s is not None and 1.0 < bound.bound_s < 10.0
    assert bound.pimm_s is not None and bound.pimm_s >= bound.bound_s - 1.0
    # the wider margin at which a standing rival is let go comes no earlier
    assert bound.drop_s is not None and bound.drop_s >= bound.bound_s
