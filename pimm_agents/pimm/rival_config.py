"""The rival check's settings (``pimm.rivals`` in a params file): what rivals.py reads, each with the measurement
that set it (docs/design.md)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from pimm_agents.pimm.twins import TwinConfig
from pimm_env.errors import LocalizerError


@dataclass(frozen=True)
class RivalConfig:
    """Ours."""

    enabled: bool = True
    history_scans: int = 150  # measurement updates whose wall points are kept (0.1 m or 0.01 rad apart)
    #: a candidate whose summed tempered log-likelihood over the kept scans is within this of the estimate's is a
    #: rival (ln 1000: the scans favour the estimate by less than 1000 to 1)
    log_ratio: float = float(np.log(1000.0))
    #: a rival stands until the kept scans favour the estimate over it by this much (ln 10^4): a hysteresis, so a
    #: twin whose margin wavers as scans come and go stays a rival instead of flickering. Between exact twins
    #: the margin wanders by several units (the true place scored 5-6 below a twin 20 m off over 115 scans of
    #: a periodic corridor), while scans that tell places apart move it by tens to hundreds. Much of that wander
    #: was a standing rival's fit drifting (``refit_before_drop``); with the refit, ln 10^4 (was ln 10^6) was
    #: as safe on the look-alike development and held-out buildings and right sooner where a twin trails slowly
    #: (docs/design.md)
    drop_log_ratio: float = float(np.log(1e4))
    #: two places are compared scan by scan, and a scan's difference within what a wall drawn this many map cells
    #: off would cost each of its points (temperature x points x (cells x resolution)^2 / (2 sigma_hit^2): 0.094
    #: nats for 60 points, 0.05 m cells, sigma_hit 0.2, temperature 0.2) counts only beyond that. A map's raster
    #: puts walls up to half a cell from where they stand, and a robot that turns on one spot sees the same walls
    #: at every scan: on generic held-out gen-928 (driven by ``greedy``) the true place fitted each of 150 such
    #: scans 0.07 nats worse than a twin one bay (2.8 m) along, no scan by more than 0.12, and the sum (-9.4)
    #: ruled the truth out at ln 10^4: the twin was ``localized`` for 11.8 s. Scan by scan with this allowance the
    #: margin was -0.2. Scans that tell places apart differ by far more (one point 0.5 m off a wall costs 0.4).
    #: Applied where margins decide (admitting, dropping, refitting and following a rival), not to the fits.
    #: 0: the summed evidence as it is
    map_error_cells: float = 0.5
    #: no place is called localized before this many scans are kept since the estimate was last lost or jumped:
    #: the candidates get that long to be found and fitted (10, as ``refine_scans``, with ``veto_only``; the
    #: check's own confirmation counted from the last rival's fall, 20 was needed)
    settle_scans: int = 10
    candidates: int = 2  # new candidates refined per update (the best fits of the newest scans among those offered)
    max_rivals: int = 5
    distinct_m: float = 1.0  # a candidate closer than this (and distinct_deg) to the estimate or a rival is that place
    distinct_deg: float = 10.0
    refine_scans: int = 10  # a candidate is first fitted to the newest scans (coordinate steps of 0.1 m and 2 deg)
    #: the map's own look-alikes of a localized estimate, offered beside the filter's candidates (twins.py)
    twins: TwinConfig = field(default_factory=TwinConfig)
    #: when the kept scans favour a rival over the estimate by ``switch_log_ratio`` (below), move the estimate's
    #: mode there, unless the estimate has been reported localized since it last jumped (a held place is left only
    #: as the filter itself leaves it); False: the check only reports
    switch: bool = True
    #: ... and only when the same rival has been that far ahead at this many updates in a row: over a turn the
    #: margins swing by tens of nats from one update to the next (a heading fitted a degree off carries 15 m of
    #: history 0.25 m), and a switch on one update's margin went back and forth between twins
    switch_updates: int = 10  # as many as a localized reading needs before it is reported (belief.confirm_updates)
    #: the lead (summed log-likelihood, both fitted to convergence) at which a rival counts as ahead for the switch:
    #: ln 1000, the margin that admits a rival. A switch reports nothing by itself (the place left and the other
    #: rivals stand, and must fall by ``drop_log_ratio`` before the new place is called localized), so it needs no
    #: wider margin: at ln 10^6 a look-alike development building (gen-973 route 4) held an estimate 11 m off for
    #: 45 s while the true place led it by 7-13 nats, and called the right place localized at 88 s, not 38 s
    switch_log_ratio: float = float(np.log(1000.0))
    #: score the estimate as the rivals are (its place fitted to the kept scans and carried, a touch per update)
    #: instead of as the filter left it: carried back along 150 scans of drifting odometry, the filter's place
    #: trailed twins fitted to them by 100-500 nats while right to 2 cm (development gen-973 route 4), so the
    #: margins measured the fit, not the place. False: as the filter left it (a bias towards ``ambiguous``)
    fit_estimate: bool = True
    #: a held estimate (reported localized since it last jumped) does not jump to the filter's new best place while
    #: the kept scans rule that place out as they rule out a rival (``drop_log_ratio``) and the newest
    #: ``refine_scans`` do not favour it by ``log_ratio``; the new place's particles are moved onto the held one
    #: (the rival check then scores the new place as any candidate). In a furnished house a window's lintel and
    #: sill made two corners that the map (rightly) lacks; they matched a room 9.5 m away and the filter jumped
    #: there from a place tracked for 100 s, which the kept scans favoured by ~2 000 nats. A kidnap lifts the
    #: hold within a few scans: the held place then fits the newest scans 10-60 nats worse than the ones before
    #: (0.2 better in that house; development kidnaps, gen-970 to 977), or they favour the new place; and the
    #: hold refuses at most ``switch_updates`` jumps before the held place is reported localized again (a kidnap
    #: to a place the scans cannot tell from the held one). False: the filter alone decides (``switch_radius_m``).
    hold: bool = True
    #: the touch every rival (and, with ``fit_estimate``, the estimate's place) gets at each update against the
    #: kept scans: 0.05 m and 1 deg steps, then 0.02 m and 0.3 deg (True), or the first alone (False); a degree
    #: of heading carries 15 m of history 0.26 m
    touch_deep: bool = True
    #: the heading steps of every fit turn a pose about the centre of the scans it is fitted to (their wall points'
    #: mean), not about the robot: turned about the robot, a tenth of a degree swings scans 15 m back by 3 cm, so
    #: heading and sideways offset were one narrow valley that steps along x, y and heading alone could not
    #: follow, and the fits of two exact twins scored 20-100 nats apart from update to update over 150 scans of a
    #: periodic corridor (held-out gen-1047 route 4, traced): rivals fell that the scans could not rule out, and a
    #: place one bay off was ``localized`` for 4.5 s. Turned about the centre, the same twins fitted to within 3
    #: nats (docs/design.md). False: about the robot
    turn_about_scans: bool = True
    #: a new candidate gets up to this many rounds of each touch step and one finer (``ADMIT_STEPS``) against all
    #: the kept scans before it is scored (a standing rival, fitted at every update since it stood, gets one round
    #: of the touch): after one round the truth, offered from 0.3 m off, trailed the estimate's well-fitted place
    #: by 10-240 nats, after three by 1-6 (gen-1047 route 4)
    admit_rounds: int = 3
    #: ... unless its fit to the newest ``refine_scans`` scans trails the estimate's place there by more than this:
    #: such a place is not a rival (it would have to fit the older scans better by almost as much). Over the
    #: 30 639 places offered in one traced trial (held-out gen-1047 route 4), the 2 421 that the full fit
    #: admitted trailed by at most 17.4 on the newest scans, and 69 % of all by more than 50; the full fit of
    #: every one cost 18 ms an update there, 7 times the standing rivals' touch
    admit_screen: float = 50.0
    #: a standing rival whose margin has passed ``drop_log_ratio`` gets a newcomer's fit (``admit_rounds`` of
    #: ``admit_steps``) and is scored again before it falls: fitted a touch per update, a rival drifts behind an
    #: estimate scored as the better of two places. In two rooms whose scans were identical the first room's
    #: margin went from -4.9 to -10.2 over 25 updates, and -1.2 once refitted (tests/test_twins.py). False: a
    #: rival falls on its touched fit
    refit_before_drop: bool = True
    #: True: a rival standing (or too few scans kept) keeps a localized reading from being reported without
    #: restarting its confirmation (``belief.confirm_updates``, counted on the filter's own reading, a switch
    #: counting the updates its rival led), so a place the belief has held that long is localized at the first
    #: update no rival stands; use it with ``twins.looked_from_cells`` 2. False: the confirmation counts from the
    #: update the last rival fell. Before ``refit_before_drop``, True let a wrong place be localized in the gap
    #: between its rivals falling on a drifted fit and coming back (4 s on a held-out building); with the refit it
    #: called right places localized 0.3-12.6 s sooner on 33 of 40 development trials, wrong on none
    #: (docs/design.md)
    veto_only: bool = True

    def __post_init__(self) -> None:
        if self.history_scans < 1 or self.candidates < 0 or self.max_rivals < 0 or self.refine_scans < 1:
            raise LocalizerError("rivals: history_scans and refine_scans must be at least 1, the counts at least 0")
        if self.admit_rounds < 1 or self.admit_screen <= 0:
            raise LocalizerError(
                f"rivals: admit_rounds must be at least 1 ({self.admit_rounds}), admit_screen positive"
                f" ({self.admit_screen})"
            )
        if self.switch_updates < 1:
            raise LocalizerError(f"rivals: switch_updates must be at least 1, got {self.switch_updates}")
        if self.log_ratio <= 0 or self.distinct_m <= 0 or self.distinct_deg <= 0:
            raise LocalizerError("rivals: log_ratio, distinct_m and distinct_deg must be positive")
        if not self.map_error_cells >= 0:
            raise LocalizerError(f"rivals: map_error_cells must be at least 0, got {self.map_error_cells}")
        if self.drop_log_ratio < self.log_ratio or self.settle_scans < 0:
            raise LocalizerError(
                f"rivals: drop_log_ratio ({self.drop_log_ratio}) must be at least log_ratio ({self.log_ratio}),"
                f" settle_scans ({self.settle_scans}) at least 0"
            )
