"""How soon could any localizer that only watches have known where it was? A bound for ``time_to_localized_s``.

Along a trial, a tracker of its own keeps the wall scans PIMM weighs (the newest ``history_scans``, never dropped
at a jump as PIMM's are) and, once it holds ``settle_scans`` of them, scores the *true* pose against the map's
twins of it (twins.py; the ``BOUND_TWINS`` best, a place turned about distinct from one beside it facing another
way), each fitted to the kept scans as the rival check fits its rivals and compared as it compares them
(``kept_scans.MAP_ERROR_CELLS``). The first time every twin trails the truth
by ``log_ratio`` (the margin at which the rival check calls a candidate no rival) is the time a perfect rival
check, offered the right place, could have called it localized: on a route that shows nothing that tells the twins
apart until late, no passive localizer can be right and sure earlier, and only driving elsewhere (active
localization) helps. The first time every twin trails by ``drop_log_ratio`` (the wider margin at which the check
lets a standing rival go) is reported beside it: between the two lies what PIMM's hysteresis costs where the twins
stood as rivals.

It uses the truth, so it measures a route, not a localizer; it shares PIMM's wall points and scan model, so it is
the bound for localizers that see the walls as PIMM does. ``python evaluate.py passive-bound WORLD SCENARIO``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

import numpy as np

from pimm_env.geometry import wrap_angle

if TYPE_CHECKING:
    from pimm_env.mapping.twins import TwinConfig

#: the twins of the truth scored: the 20 best (as the active-localization guide takes them, against the rival
#: check's 6), two matches less than 1.5 m apart counting as one only when their turns differ by at most 30 deg
#: (with position alone, a place turned half round beside a better match facing the other way was left out:
#: ``TwinConfig.distinct_turn_deg``)
BOUND_TWINS = 20
BOUND_DISTINCT_TURN_DEG = 30.0


def bound_twin_config(twins: TwinConfig, max_twins: int = BOUND_TWINS) -> TwinConfig:
    """``twins`` as both bounds look for twins: ``max_twins`` of them, turned twins kept apart."""
    return replace(twins, max_twins=max_twins, distinct_turn_deg=BOUND_DISTINCT_TURN_DEG)


@dataclass(frozen=True)
class PassiveBound:
    world: str
    scenario: str
    seed: int
    #: the first time (s from the start) the truth led every twin by ``log_ratio``; None: never in the trial
    bound_s: float | None
    #: the first time the truth led every twin by ``drop_log_ratio`` (None: never in the trial)
    drop_s: float | None
    #: PIMM's ``time_to_localized_s`` in the same trial (the first time it was localized and right)
    pimm_s: float | None


def passive_bound(world: str, scenario: str, seed: int = 0) -> PassiveBound:
    """The bound of one trial (see the module docstring), beside PIMM's first right ``localized`` time."""
    from pimm_agents.experiments.runner import run_shared
    from pimm_agents.particles.likelihood_field import LikelihoodField
    from pimm_agents.pimm.config import PimmConfig
    from pimm_agents.pimm.rivals import RivalTracker
    from pimm_agents.scoring.trial import TrialSpec
    from pimm_env.mapping.derived_maps import load_derived_maps
    from pimm_env.mapping.twins import MapTwins, TwinConfig
    from pimm_env.world.files import load_world

    occupancy = load_derived_maps(load_world(world)).occupancy
    config = PimmConfig()  # the wall field and the rival check PIMM scores with
    field = LikelihoodField(occupancy, config.wall_field.field_params())
    ours = RivalTracker(field, occupancy.free, config.wall_field.temperature, config.rivals)
    twin_finder = MapTwins(occupancy, bound_twin_config(TwinConfig()))
    state: dict[str, Any] = {"bound": None, "drop": None, "t0": None, "right": None}

    def watch(localizers: Sequence[Any], obs: dict[str, Any], info: dict[str, Any]) -> None:
        t = float(obs["time"][0])
        state["t0"] = t if state["t0"] is None else state["t0"]
        truth = np.asarray(info["true_pose"], dtype=float)
        estimate = localizers[0].last_estimate
        if state["right"] is None and estimate is not None and estimate.status == "localized":
            if np.hypot(estimate.x - truth[0], estimate.y - truth[1]) < 1.0 and abs(
                wrap_angle(estimate.theta - truth[2])
            ) < np.radians(10.0):
                state["right"] = t - state["t0"]
        points = None if estimate is None else estimate.inside.get("walls")  # the wall points PIMM weighed
        if points is None or not len(points):
            return
        odom = np.asarray(obs["odom"], dtype=float)
        ours.add_scan(odom, points)
        if state["drop"] is not None or not ours.settled:
            return
        twins = twin_finder.of(truth)
        lead = np.inf  # how far the truth leads its nearest twin over the kept scans
        if len(twins):
            history = ours.stack(odom)
            twins = ours.fit_new(twins, ours.recent(odom), history)
            lead = -float(ours.margins_over(twins, truth, history).max())
        if state["bound"] is None and lead >= ours.config.log_ratio:
            state["bound"] = t - state["t0"]
        if lead >= ours.config.drop_log_ratio:
            state["drop"] = t - state["t0"]

    run_shared([TrialSpec(scenario, "pimm", 0, seed, world=world)], watch)
    return PassiveBound(str(world), scenario, seed, state["bound"], state["drop"], state["right"])
