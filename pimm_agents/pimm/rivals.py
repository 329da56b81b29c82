"""Look-alike places the recent scans cannot tell from the estimate: the check behind PIMM's ``ambiguous``.

A particle filter's weights say how well each place fitted the scans *while particles were there*; a twin place
that lost its particles early (sampling luck at a global start, or a resampling step) can no longer win weight,
however well it fits. So the weights alone cannot say whether the estimate is the only place that explains what
the robot saw. This module asks the scans directly: it keeps the wall points of the last ``history_scans`` measurement
updates with the odometry at each, and for a candidate place carries the candidate back along the odometry to every
kept scan and sums the scans' tempered log-likelihoods there (the filter's wall field). Candidates are the filter's
own (its other compact modes and its best particles away from the estimate; the injection puts some near every place
the fingerprints suggest) and, for a localized estimate, the map's own look-alikes of it (twins.py), which the map
cannot miss the way the filter can. A candidate is a *rival* while its summed evidence is within ``log_ratio`` of the
estimate's; rivals are kept, carried by the odometry and re-scored at every update, until the scans favour the
estimate over them by ``drop_log_ratio`` (a wider margin, so that a twin does not flicker in and out), fitted as a
newcomer is before they fall. While any rival stands, and until ``settle_scans`` scans are
kept, the status is ``ambiguous`` (a veto: the belief's own confirmation goes on counting). The filter
is not fed from the check (particles injected at every rival made the estimate wander between twins, docs/design.md),
with one exception: a rival the scans favour over the estimate by ``SWITCH_LOG_RATIO``, both fitted to them to
convergence, at ``switch_updates`` updates in a row takes the mode of an estimate not reported localized since it last
jumped (the step moves it): by the check's own rule the estimate would be no rival of it were the two
the other way round, and the place left stands as a rival until the scans rule it out.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pimm_agents.particles.likelihood_field import LikelihoodField
from pimm_agents.pimm.kept_scans import (
    ADMIT_ROUNDS,
    ADMIT_STEPS,
    DEEP_STEPS,
    DEEP_TOUCH,
    FINE_STEP,
    OFFER_ROUNDS,
    REFINE_SCANS,
    KeptScans,
)
from pimm_agents.pimm.scan_stack import ScanStack
from pimm_env.errors import LocalizerError
from pimm_env.geometry import relative_motion, wrap_angle


@dataclass(frozen=True)
class RivalConfig:
    """The ambiguity check's settings (``pimm.rivals``; ours, each measured: docs/design.md#the-ambiguity-check)."""

    enabled: bool = True  # the check beside the filter; off: the filter's own status, 5 ms an update less
    history_scans: int = 150  # measured: the scans kept (one per measurement update)
    log_ratio: float = float(np.log(1000.0))  # measured: a candidate within this of the estimate is a rival
    drop_log_ratio: float = float(np.log(1e4))  # measured: a rival stands until it trails by this (hysteresis)
    settle_scans: int = 10  # measured: no place is localized before this many scans are kept since a jump
    switch_updates: int = 10  # measured: updates in a row a rival must lead decisively to take the estimate

    def __post_init__(self) -> None:
        if self.history_scans < 1 or self.switch_updates < 1 or self.settle_scans < 0:
            raise LocalizerError(
                f"rivals: history_scans and switch_updates must be at least 1, settle_scans at least 0; got"
                f" {self.history_scans}, {self.switch_updates}, {self.settle_scans}"
            )
        if self.history_scans < max(self.settle_scans, REFINE_SCANS):
            raise LocalizerError(
                f"rivals.history_scans ({self.history_scans}) must be at least rivals.settle_scans"
                f" ({self.settle_scans}) and {REFINE_SCANS} (the newest scans a candidate is fitted to): with"
                " fewer kept, no place could ever be called localized"
            )
        if not self.log_ratio > 0 or self.drop_log_ratio < self.log_ratio:
            raise LocalizerError(
                f"rivals.drop_log_ratio ({self.drop_log_ratio}) must be at least rivals.log_ratio ({self.log_ratio}),"
                " which must be positive: a rival falls at a wider margin than admits it"
            )


#: The check's fixed choices (ours; each measured, docs/design.md#the-ambiguity-check):
CANDIDATES = 2  # new candidates refined per update (the best fits of the newest scans among those offered)
MAX_RIVALS = 5
DISTINCT_M, DISTINCT_DEG = 1.0, 10.0  # a candidate closer than this to the estimate or a rival is that place
SWITCH_LOG_RATIO = float(np.log(1000.0))  # the lead at which a rival counts as ahead for the switch
ADMIT_SCREEN = 50.0  # a new candidate whose fit to the newest scans trails the estimate's by more is no rival


class RivalTracker(KeptScans):
    """The rivals of an estimate over the scans it keeps (``KeptScans``): ``update`` re-scores them and the new
    candidates, ``decisive`` names the one that has led decisively, ``holds`` says whether a held place stays."""

    def __init__(self, field: LikelihoodField, free: np.ndarray, temperature: float, config: RivalConfig) -> None:
        super().__init__(field, free, temperature, config.history_scans, config.settle_scans)
        self.config = config
        self.rivals = np.zeros((0, 3))
        #: per rival, its summed evidence less the estimate's at the last update (NaN: held, not yet scored)
        self.margins = np.zeros(0)
        self._leader: np.ndarray | None = None  # the rival ahead by SWITCH_LOG_RATIO, and for how many updates
        self._lead = 0
        #: the estimate's place as fitted to the kept scans, carried and fitted a touch at every update like a
        #: rival, so that rivals and estimate are scored alike (None: not fitted yet, or the estimate moved)
        self._anchor: np.ndarray | None = None

    def reset(self) -> None:
        self.drop_scans()
        self.forget()

    def forget(self) -> None:
        """Drop the rivals (the kept scans stay)."""
        self.rivals = np.zeros((0, 3))
        self.margins = np.zeros(0)
        self._leader, self._lead = None, 0
        self._anchor = None

    def move(self, odom_then: np.ndarray, odom_now: np.ndarray) -> None:
        """Carry the rivals by the odometry since ``odom_then``."""
        motion = relative_motion(odom_then, odom_now)
        if len(self.rivals):
            self.rivals = carried(self.rivals, motion)
        if self._leader is not None:
            self._leader = carried(self._leader[None, :], motion)[0]
        if self._anchor is not None:
            self._anchor = carried(self._anchor[None, :], motion)[0]

    def holds(
        self, held: np.ndarray, new: np.ndarray, odom_now: np.ndarray, wall_points: np.ndarray | None = None
    ) -> bool:
        """Whether a held place should stay rather than give way to ``new`` (see ``RivalConfig.hold``), judged on
        the kept scans and this update's ``wall_points`` (robot frame now; the scan that moved the filter, not
        kept yet): both fitted to the newest ``refine_scans``, these do not favour ``new`` by ``log_ratio``, nor
        do the ``refine_scans`` before them favour ``held`` over itself now by ``log_ratio`` (its fit collapsing
        is a kidnap's mark), and all of them (``held`` and ``new`` fitted a touch more) favour ``held`` by
        ``drop_log_ratio``. False with fewer than ``settle_scans`` kept."""
        c = self.config
        if len(self._scans) < max(c.settle_scans, REFINE_SCANS):
            return False
        if wall_points is not None:
            wall_points = np.asarray(wall_points, dtype=float).reshape(-1, 2)
        extra = None if wall_points is None else (np.asarray(odom_now, dtype=float), wall_points)
        recent = self.stack(odom_now, REFINE_SCANS, extra)
        places = self.refine(np.vstack([held, new]), recent, rounds=2)
        newest = self.evidence(places, recent)
        if newest[1] - newest[0] >= c.log_ratio:
            return False
        # a kidnap: the held place explains the newest scans far worse than the ones before them
        before = self.evidence(places[:1], self.stack(odom_now, 2 * REFINE_SCANS, extra))[0] - newest[0]
        if before - newest[0] >= c.log_ratio:
            return False
        history = self.stack(odom_now, None, extra)
        places = self.refine(places, history, rounds=1, steps=FINE_STEP)
        kept = self.evidence(places, history)
        return bool(kept[0] - kept[1] >= c.drop_log_ratio)

    def promote(self, index: int) -> np.ndarray:
        """Take rival ``index`` out of the rivals (it becomes the estimate) and return it; the other rivals stand,
        their margins to be scored against the new estimate at the next update."""
        place, others = self.rivals[index].copy(), np.delete(self.rivals, index, axis=0)
        self.forget()
        self.rivals, self.margins = others, np.full(len(others), np.nan)
        return place

    def keep(self, place: np.ndarray) -> None:
        """Hold ``place`` (3,) as a rival until the scans rule it out (the place an estimate jumped away from)."""
        self.rivals = np.vstack([self.rivals, np.asarray(place, dtype=float).reshape(1, 3)])
        self.margins = np.append(self.margins, np.nan)

    def headings(self, positions: np.ndarray, odom_now: np.ndarray) -> np.ndarray:
        """For each position (M, 2), the pose whose heading (every 10 deg) the newest scans fit best."""
        positions = np.asarray(positions, dtype=float).reshape(-1, 2)
        if not len(positions) or len(self._scans) < REFINE_SCANS:
            return np.zeros((0, 3))
        angles = np.radians(np.arange(-180.0, 180.0, 10.0))
        poses = np.column_stack([np.repeat(positions, len(angles), axis=0), np.tile(angles, len(positions))])
        scores = self.evidence(poses, self.recent(odom_now)).reshape(len(positions), -1)
        return poses.reshape(len(positions), len(angles), 3)[np.arange(len(positions)), np.argmax(scores, axis=1)]

    def update(
        self,
        estimate: np.ndarray,
        odom_now: np.ndarray,
        candidates: np.ndarray,
        first: np.ndarray | None = None,
        lead: bool = True,
    ) -> int:
        """Re-score the kept rivals and the new ``candidates`` (M, 3) against ``estimate``; keep the new ones within
        ``log_ratio`` and the kept ones within ``drop_log_ratio``. ``first`` (the filter's heaviest other modes)
        are tried whatever the newest scans say of them unrefined; of the other candidates, the ``candidates``
        the newest scans fit best. With ``lead``, follow the rival that leads the estimate
        (``decisive``; off for a held estimate, which no rival may take). Returns how many rivals stand; with
        fewer than ``refine_scans`` scans kept (just after a jump) the kept rivals stand unscored."""
        c = self.config
        if len(self._scans) < REFINE_SCANS:
            return len(self.rivals)
        recent = self.recent(odom_now)
        pool = [p for p in self.rivals]
        for q in np.zeros((0, 3)) if first is None else np.asarray(first, dtype=float).reshape(-1, 3):
            if not self._known(q, [estimate, *pool]):
                pool.append(q)
        tried = len(pool)
        fresh = [q for q in np.asarray(candidates, dtype=float).reshape(-1, 3) if not self._known(q, [estimate, *pool])]
        if fresh:  # the ones the newest scans like best
            order = np.argsort(-self.evidence(np.array(fresh), recent), kind="stable")
            for i in order:
                if len(pool) >= tried + CANDIDATES:
                    break
                if not self._known(fresh[i], pool):
                    pool.append(fresh[i])
        if not pool:
            self.forget()
            return 0
        kept = len(self.rivals)
        history = self.stack(odom_now)
        # the estimate as the filter left it, and its place fitted as the rivals are: scored once each
        places = [estimate, self._fit_estimate(estimate, recent, history)]
        # every one by a touch against all the kept scans it is scored on: fitted to the newest alone, a place a
        # degree off in heading would carry back metres off along 15 m of history and lose a rival; a new one
        # (fitted to the newest scans first, from wherever it was offered, and screened on them) by
        # ``ADMIT_ROUNDS`` of it and a finer step
        refined = np.array(pool[:kept], dtype=float).reshape(-1, 3)
        if kept:
            refined = self.refine(refined, history, rounds=1, steps=DEEP_TOUCH)
        offered = np.array(pool[kept:], dtype=float).reshape(-1, 3)
        if len(offered):
            offered = self.refine(offered, recent, rounds=OFFER_ROUNDS)
            newest = self.evidence(np.vstack([*places, offered]), recent)
            offered = offered[newest[len(places) :] >= newest[: len(places)].max() - ADMIT_SCREEN]
            if len(offered):
                offered = self.refine(offered, history, rounds=ADMIT_ROUNDS, steps=ADMIT_STEPS)
        refined = np.vstack([refined, offered])
        # against the better scored of the estimate's places
        reference = places[int(np.argmax(self.evidence(np.array(places), history)))]
        margins = self.margins_over(refined, reference, history)
        # a standing rival about to fall is fitted as a newcomer and scored again
        falling = np.flatnonzero((np.arange(len(refined)) < kept) & (margins <= -c.drop_log_ratio))
        if len(falling):
            refined[falling] = self.refine(refined[falling], history, ADMIT_ROUNDS, ADMIT_STEPS)
            margins[falling] = self.margins_over(refined[falling], reference, history)
        unique: list[int] = []
        limits = np.where(np.arange(len(refined)) < kept, c.drop_log_ratio, c.log_ratio)
        for i in np.argsort(-margins):
            if margins[i] <= -limits[i] or self._known(refined[i], places):
                continue
            if not self._known(refined[i], [refined[j] for j in unique]):
                unique.append(int(i))
        unique = unique[:MAX_RIVALS]
        self.rivals = refined[unique].reshape(-1, 3)
        self.margins = margins[unique]
        if lead:
            self._follow_leader(estimate, history)
        elif self._leader is not None:
            self._leader, self._lead = None, 0
        return len(unique)

    def _fit_estimate(self, estimate: np.ndarray, recent: ScanStack, history: ScanStack) -> np.ndarray:
        """The estimate's place fitted as the rivals are: from where it was fitted last (carried), if the
        estimate is still there, else fitted to the newest scans first; then a touch against all kept scans (a new
        place, as a new rival, ``ADMIT_ROUNDS`` of it and a finer step).
        Scored unfitted against rivals fitted at every update since they stood, a right estimate trailed its
        twins by up to 500 nats on a development building (gen-970 route 2) and stayed ``ambiguous``."""
        if self._anchor is None or not self._known(self._anchor, [estimate]):  # a new place: fitted as a new rival
            self._anchor = self.fit_new(estimate[None, :], recent, history)[0]
        else:
            self._anchor = self.refine(self._anchor[None, :], history, rounds=1, steps=DEEP_TOUCH)[0]
        return self._anchor

    def _follow_leader(self, estimate: np.ndarray, history: ScanStack) -> None:
        """Count the updates in a row at which the same rival (within ``distinct_m``, ``distinct_deg``) led the
        estimate by ``SWITCH_LOG_RATIO``, both fitted to the kept scans to convergence first (``DEEP_STEPS``). The
        margins of the check compare rivals, fitted a touch at every update since they stood, with the estimate
        as the filter left it: enough for a status, which errs towards ``ambiguous``, but on a development
        building (gen-970 route 3) the right estimate then trailed its twins by 15-70 nats over 150 scans, and
        by 20-150 nats the other way once both were fitted to convergence."""
        ahead = np.flatnonzero(np.nan_to_num(self.margins, nan=-np.inf) >= SWITCH_LOG_RATIO)
        best = self.rivals[ahead[np.argmax(self.margins[ahead])]] if len(ahead) else None
        if best is not None:
            fitted = self.refine(np.vstack([estimate, best]), history, rounds=30, steps=DEEP_STEPS)
            if self.margins_over(fitted[1:], fitted[0], history)[0] < SWITCH_LOG_RATIO:
                best = None
        if best is None:
            self._leader, self._lead = None, 0
            return
        same = self._leader is not None and self._known(best, [self._leader])
        self._leader, self._lead = best.copy(), self._lead + 1 if same else 1

    def decisive(self) -> int | None:
        """The rival the kept scans have favoured over the estimate by ``SWITCH_LOG_RATIO`` or more at the last
        ``switch_updates`` updates; None if there is none."""
        if self._leader is None or self._lead < self.config.switch_updates or not self.settled:
            return None
        for i, rival in enumerate(self.rivals):
            if self._known(rival, [self._leader]):
                return i
        return None

    def _known(self, pose: np.ndarray, places: list[np.ndarray]) -> bool:
        return any(
            np.hypot(pose[0] - q[0], pose[1] - q[1]) < DISTINCT_M
            and abs(wrap_angle(pose[2] - q[2])) < np.radians(DISTINCT_DEG)
            for q in places
        )


def carried(poses: np.ndarray, motion: np.ndarray) -> np.ndarray:
    """Each pose (K, 3) moved by ``motion`` (3,), given in the pose's own frame."""
    m = np.asarray(motion, dtype=float)
    c, s = np.cos(poses[:, 2]), np.sin(poses[:, 2])
    return np.column_stack(
        [poses[:, 0] + c * m[0] - s * m[1], poses[:, 1] + s * m[0] + c * m[1], wrap_angle(poses[:, 2] + m[2])]
    )
