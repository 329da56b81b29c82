import numpy as np
import pytest

from pimm_agents.measurement.corner_quality import _in_sight, visible_corners
from pimm_env.envs.iilab_env import IILabEnv
from pimm_env.mapping.derived_maps import load_derived_maps


def test_a_corner_whose_face_is_glass_is_not_counted_visible():
    """From corridor C, the west end's south-west corner (-28.8, 8.9) is in sight, but its south face is the
    glass pane (clutter): no wall plane to find there. The north-west corner's faces are walls."""
    env = IILabEnv()
    try:
        corners = load_derived_maps(env.world).corners
        l3 = env.config.lidar3d
        origin = np.array([-26.5, 10.8, env.world.floor_z + l3.height])
        half_fov = np.radians(l3.vertical_fov_deg) / 2
        index = {tuple(np.round(xy, 2)): k for k, xy in enumerate(corners.xy)}
        south_west, north_west = index[(-28.8, 8.9)], index[(-28.8, 11.7)]
        in_view = visible_corners(env.caster, origin, corners, l3.max_range, half_fov, faces=False)
        counted = visible_corners(env.caster, origin, corners, l3.max_range, half_fov, faces=True)
        assert {south_west, north_west} <= set(in_view)
        assert north_west in counted and south_west not in counted
        on_glass = np.array([-27.6, 8.86, corners.z[south_west] - 1.0])
        assert _in_sight(env.caster, origin, on_glass, l3.max_range, half_fov, 0.1)
        assert not _in_sight(env.caster, origin, on_glass, l3.max_range, half_fov, 0.1, on_wall=True)
    finally:
        env.close()


def test_perception_reports_segmentation_where_the_corner_map_is_empty():
    """A world without corners (no ceiling over its walls): corner quality cannot be measured, the rest is."""
    import dataclasses

    from pimm_agents.measurement.corner_quality import collect_scans
    from pimm_agents.measurement.perception_quality import perception_report
    from pimm_agents.perception.files import load_perception
    from pimm_env.mapping.corner_map import CornerMap

    # the iilab's scans, with no corner in sight: what collect_scans gives in a world whose corner map is empty
    scans = [dataclasses.replace(s, seen=np.zeros(0, dtype=int)) for s in collect_scans("iilab", 2, 3)]
    segmenter, _ = load_perception("iilab")
    empty = CornerMap(xy=np.zeros((0, 2)), z=np.zeros(0), theta=np.zeros(0))
    report = perception_report(scans, empty, segmenter)
    assert 0.5 < report["segmentation"]["miou"] <= 1.0
    for which in ("true_labels", "predicted_labels"):
        assert report["corners"][which]["recall"] is None  # nothing in sight to find
        assert report["corners"][which]["precision"] in (0.0, None)  # whatever was detected matches nothing


@pytest.mark.expensive
def test_corner_recall_in_the_iilab_does_not_drop_below_what_it_is():
    """The corner detector on the shipped network's labels, 50 fresh iiLab scans (seed 1, as `evaluate.py
    perception`): measured precision 0.971, recall 0.851 (57 of the 67 corners in sight); a change that costs
    one of them fails here (the goal is 0.8 at precision 0.95, docs/perception.md)."""
    from pimm_agents.measurement.corner_quality import collect_scans, corner_stats
    from pimm_agents.perception.files import load_perception
    from pimm_env.mapping.derived_maps import ensure_derived_maps
    from pimm_env.world.files import load_world

    scans = collect_scans("iilab", 50, 1)
    segmenter, _ = load_perception("iilab")
    corners = ensure_derived_maps(load_world("iilab")).corners
    stats = corner_stats([s.corner_input(segmenter.segment(s.cloud, s.mask).labels) for s in scans], corners)
    assert stats.precision >= 0.95 and stats.recall >= 0.85, (stats.precision, stats.recall)
