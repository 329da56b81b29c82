"""How soon could any driver have shown the robot where it is? A bound for active localization's time.

From a route's start, the map's twins of the start (twins.py, as PIMM's rival check finds them, but up to
``max_twins`` of them rather than the check's six best, and a match turned half round kept beside one facing the
other way, as in the passive bound) each predict
the view at any offset from where they are; at the start itself they predict what the robot sees. The robot
cannot tell its place from a twin's until it stands where the two views differ (the guide's comparison,
views.py: at least ``min_share`` of the bearings more than 1 m apart, or the twin's place not passable). The
nearest place that tells the start from every twin, along the shortest path, over the forward primitive's speed
(0.5 m/s), is a lower bound on the time any policy needs to be right and sure: it ignores turning, the
localizer's own time to rule the twins out, and that the policy does not know which twin it is at (it would have
to try several ways). It uses the truth, so it measures a start in a building, not a policy.
``python evaluate.py active-bound WORLD``.
"""

from __future__ import annotations

from dataclasses import dataclass

from pimm_agents.active.primitives import PRIMITIVES
from pimm_agents.measurement.passive_bound import BOUND_TWINS, bound_twin_config

#: the forward primitive's speed (m/s)
FORWARD_SPEED = PRIMITIVES[0].linear


@dataclass(frozen=True)
class ActiveBound:
    world: str
    scenario: str
    #: the map's twins of the start
    twins: int
    #: path length (m) to the nearest place that tells the start from every twin; None: none within reach
    distance_m: float | None
    #: that over the forward speed (s)
    bound_s: float | None


def active_bounds(
    world: str,
    scenarios: list[str] | None = None,
    reach_m: float = 60.0,
    min_share: float = 0.1,
    max_twins: int = BOUND_TWINS,
) -> list[ActiveBound]:
    """The bound of each route's start in ``world`` (its scenarios without a kidnap, or ``scenarios``)."""
    from pimm_agents.active.views import ViewPredictor
    from pimm_env.driving.scenarios import load_scenarios
    from pimm_env.errors import ExperimentError
    from pimm_env.mapping.derived_maps import load_derived_maps
    from pimm_env.mapping.twins import MapTwins, TwinConfig
    from pimm_env.world.files import load_world

    loaded = load_world(world)
    occupancy = load_derived_maps(loaded).occupancy
    known = load_scenarios(world)
    names = scenarios or [n for n, s in known.items() if s.kidnap_to is None]
    unknown = [n for n in names if n not in known]
    if unknown:
        raise ExperimentError(f"{world}: no scenario {', '.join(unknown)} (it has {', '.join(known)})")
    twins = MapTwins(occupancy, bound_twin_config(TwinConfig(), max_twins))
    views = ViewPredictor(occupancy)
    out = []
    for name in names:
        start = known[name].start
        found = twins.of(start)
        distance = views.nearest_telling(start, found, reach_m, min_share)
        bound = None if distance is None else distance / FORWARD_SPEED
        out.append(ActiveBound(loaded.name, name, len(found), distance, bound))
    return out
