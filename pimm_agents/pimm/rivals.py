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
newcomer is before they fall (``refit_before_drop``). While any rival stands, and until ``settle_scans`` scans are
kept, the status is ``ambiguous`` (a veto: the belief's own confirmation goes on counting, ``veto_only``). The filter
is not fed from the check (particles injected at every rival made the estimate wander between twins, docs/design.md),
with one exception: a rival the scans favour over the estimate by ``switch_log_ratio``, both fitted to them to
convergence, at ``switch_updates`` updates in a row takes the mode of an estimate not reported localized since it last
jumped (``switch``; ambiguity.py moves it): by the check's own rule the estimate would be no rival of it were the two
the other way round, and the place left stands as a rival until the scans rule it out.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np

from pimm_agents.particles.likelihood_field import LikelihoodField
from pimm_agents.pimm.scan_evidence import scan_by_scan_evidence, summed_scan_evidence
from pimm_agents.pimm.scan_stack import ScanStack, points_centre, turned
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
                f" ({self.settle_scans}) and {REFINE_SCANS} (the newest scans a candidate is fitted to): with fewer"
                " kept, no place could ever be called localized"
            )
        if not self.log_ratio > 0 or self.drop_log_ratio < self.log_ratio:
            raise LocalizerError(
                f"rivals.drop_log_ratio ({self.drop_log_ratio}) must be at least rivals.log_ratio ({self.log_ratio}),"
                " which must be positive: a rival falls at a wider margin than admits it"
            )


#: The check's fixed choices (ours; each measured, docs/design.md#the-ambiguity-check):
#: a scan's difference between two places within what a wall this many map cells off would cost its points counts
#: as none (the map's raster puts walls up to half a cell from where they stand)
MAP_ERROR_CELLS = 0.5
CANDIDATES = 2  # new candidates refined per update (the best fits of the newest scans among those offered)
MAX_RIVALS = 5
DISTINCT_M, DISTINCT_DEG = 1.0, 10.0  # a candidate closer than this to the estimate or a rival is that place
REFINE_SCANS = 10  # a candidate is first fitted to the newest scans
SWITCH_LOG_RATIO = float(np.log(1000.0))  # the lead at which a rival counts as ahead for the switch
ADMIT_ROUNDS = 3  # rounds of each step a new candidate gets against all the kept scans before it is scored
ADMIT_SCREEN = 50.0  # ... unless its fit to the newest scans trails the estimate's there by more than this

#: Coordinate steps (x m, y m, heading rad) a candidate is refined by, coarse then fine.
REFINE_STEPS = (np.array([0.1, 0.1, np.radians(2.0)]), np.array([0.05, 0.05, np.radians(1.0)]))
#: The fine step alone: the last touch against the whole history.
FINE_STEP = (REFINE_STEPS[1],)
#: Down to 2 cm and 0.3 deg: a fit to convergence, before a rival may take the estimate.
DEEP_STEPS = (*REFINE_STEPS, np.array([0.02, 0.02, np.radians(0.3)]))
#: The fine step and the deepest: a touch that keeps a place fitted to 2 cm and 0.3 deg as it is carried.
DEEP_TOUCH = DEEP_STEPS[1:]
#: The touch and a step of 1 cm and 0.15 deg: a new candidate's (and a new estimate's) fit against all the kept
#: scans before it is first scored. Left on the touch's 2 cm lattice, a twin offered off it ended 1-2 cm from its
#: best place, 9 nats below it on noise-free scans (tests/test_rivals.py), more than the ln 1000 that admits it.
ADMIT_STEPS = (*DEEP_TOUCH, np.array([0.01, 0.01, np.radians(0.15)]))


class RivalTracker:
    def __init__(self, field: LikelihoodField, free: np.ndarray, temperature: float, config: RivalConfig) -> None:
        self.field = field
        self.free = free  # (rows, cols) of the map: a pose outside them is penalized
        self.temperature = temperature
        self.config = config
        self._scans: deque[tuple[np.ndarray, np.ndarray]] = deque(maxlen=config.history_scans)
        self._added = 0  # scans kept so far: with the odometry, says whether the newest-scans stack is current
        self._recent: tuple[tuple[int, bytes], ScanStack] | None = None
        p = field.params
        floor = p.z_rand / p.range_max
        #: per map cell: log pz of a point there, relative to a point on a wall (so 0 at best)
        self.log_pz = np.log(p.z_hit * np.exp(-(field.distance**2) / (2 * p.sigma_hit**2)) + floor) - np.log(
            p.z_hit + floor
        )
        self.log_pz_off = float(
            np.log(p.z_hit * np.exp(-(p.max_distance**2) / (2 * p.sigma_hit**2)) + floor) - np.log(p.z_hit + floor)
        )
        self.rivals = np.zeros((0, 3))
        #: per rival, its summed evidence less the estimate's at the last update (NaN: held, not yet scored)
        self.margins = np.zeros(0)
        self._leader: np.ndarray | None = None  # the rival ahead by switch_log_ratio, and for how many updates
        self._lead = 0
        #: the estimate's place as fitted to the kept scans, carried and fitted a touch at every update like a
        #: rival, so that rivals and estimate are scored alike (None: not fitted yet, or the estimate moved)
        self._anchor: np.ndarray | None = None

    def reset(self) -> None:
        self._scans.clear()
        self._recent = None
        self.forget()

    def forget(self) -> None:
        """Drop the rivals (the kept scans stay)."""
        self.rivals = np.zeros((0, 3))
        self.margins = np.zeros(0)
        self._leader, self._lead = None, 0
        self._anchor = None

    @property
    def settled(self) -> bool:
        """Whether enough scans are kept (``settle_scans``) for the check to call a place unrivalled."""
        return len(self._scans) >= self.config.settle_scans

    def add_scan(self, odom: np.ndarray, wall_points: np.ndarray) -> None:
        """Keep a scan's wall points (M, 2; robot frame) with the odometry at which they were seen."""
        if len(wall_points):
            self._scans.append((np.asarray(odom, dtype=float).copy(), np.asarray(wall_points, dtype=float)))
            self._added += 1

    @property
    def scans_added(self) -> int:
        """How many scans have been kept since the tracker was made (a counter that never goes back)."""
        return self._added

    def newest_scan(self) -> tuple[np.ndarray, np.ndarray] | None:
        """The newest kept scan: the odometry at which it was seen and its wall points (robot frame)."""
        return self._scans[-1] if self._scans else None

    def move(self, odom_then: np.ndarray, odom_now: np.ndarray) -> None:
        """Carry the rivals by the odometry since ``odom_then``."""
        motion = relative_motion(odom_then, odom_now)
        if len(self.rivals):
            self.rivals = carried(self.rivals, motion)
        if self._leader is not None:
            self._leader = carried(self._leader[None, :], motion)[0]
        if self._anchor is not None:
            self._anchor = carried(self._anchor[None, :], motion)[0]

    def stack(
        self, odom_now: np.ndarray, last: int | None = None, extra: tuple[np.ndarray, np.ndarray] | None = None
    ) -> ScanStack:
        """The kept scans (the ``last`` newest) as one array of points, each with its scan's motion from now;
        ``extra`` (odometry, wall points) is taken as one more, newest scan without being kept."""
        scans = list(self._scans) + ([extra] if extra is not None and len(extra[1]) else [])
        scans = scans[-last:] if last else scans
        if not scans:
            return ScanStack(np.zeros((0, 2)), np.zeros(0, dtype=int), np.zeros((0, 3)), np.zeros(2))
        points = np.vstack([points for _, points in scans])
        scan_of = np.repeat(np.arange(len(scans)), [len(points) for _, points in scans])
        motions = np.array([relative_motion(odom_now, odom) for odom, _ in scans])
        return ScanStack(points, scan_of, motions, points_centre(points, scan_of, motions))

    def recent(self, odom_now: np.ndarray) -> ScanStack:
        """``stack`` of the newest ``refine_scans`` scans, built once per update (``headings`` and ``update``
        both score on it)."""
        key = (self._added, np.asarray(odom_now, dtype=float).tobytes())
        if self._recent is None or self._recent[0] != key:
            self._recent = (key, self.stack(odom_now, REFINE_SCANS))
        return self._recent[1]

    def evidence(self, poses: np.ndarray, stack: ScanStack) -> np.ndarray:
        """Summed tempered log-likelihood of the stacked scans for a robot now at each of ``poses`` (K, 3),
        carried back along the odometry to each scan (a pose off the free space costs ln 0.1 a scan)."""
        poses = np.asarray(poses, dtype=float).reshape(-1, 3)
        if len(stack.motions) == 0 or len(poses) == 0:
            return np.zeros(len(poses))
        return summed_scan_evidence(poses, *self._kernel_inputs(stack))

    def evidence_by_scan(self, poses: np.ndarray, stack: ScanStack) -> np.ndarray:
        """``evidence`` kept apart per scan: (K, S), the tempered log-likelihood of each stacked scan for a robot
        now at each of ``poses``."""
        return scan_by_scan_evidence(np.asarray(poses, dtype=float).reshape(-1, 3), *self._kernel_inputs(stack))

    def _kernel_inputs(self, stack: ScanStack) -> tuple:
        """What the compiled evidence loops (scan_evidence.py) take after the poses: the stacked scans, the map's
        per-cell log-likelihood and free cells, the grid, the temperature and the off-free penalty (ln 0.1)."""
        grid = self.field.grid
        return (
            np.ascontiguousarray(stack.motions, dtype=float),
            np.ascontiguousarray(stack.scan_of, dtype=np.int64),
            np.ascontiguousarray(stack.points, dtype=float),
            self.log_pz,
            self.log_pz_off,
            self.free,
            float(grid.origin[0]),
            float(grid.origin[1]),
            float(grid.resolution),
            float(self.temperature),
            float(np.log(0.1)),
        )

    def scan_allowance(self, stack: ScanStack) -> np.ndarray:
        """Per stacked scan (S,): what a wall ``map_error_cells`` cells off costs each of its points, summed and
        tempered (``RivalConfig.map_error_cells``)."""
        offset = MAP_ERROR_CELLS * self.field.grid.resolution
        per_point = offset**2 / (2 * self.field.params.sigma_hit**2)
        points = np.bincount(stack.scan_of, minlength=len(stack.motions))
        return self.temperature * per_point * points

    def margins_over(self, poses: np.ndarray, reference: np.ndarray, stack: ScanStack) -> np.ndarray:
        """How much better the stacked scans fit each of ``poses`` (K, 3) than ``reference`` (3,): the difference
        of the summed evidence (``map_error_cells`` 0), or scan by scan with each scan's difference counted only
        beyond ``scan_allowance`` (a difference the map's raster alone could make counts as none)."""
        poses = np.asarray(poses, dtype=float).reshape(-1, 3)
        reference = np.asarray(reference, dtype=float).reshape(1, 3)
        if not len(poses):
            return np.zeros(0)
        by_scan = self.evidence_by_scan(np.vstack([reference, poses]), stack)
        difference = by_scan[1:] - by_scan[0]
        beyond = np.maximum(np.abs(difference) - self.scan_allowance(stack), 0.0)
        return (np.sign(difference) * beyond).sum(axis=1)

    def refine(
        self, poses: np.ndarray, stack: ScanStack, rounds: int = 4, steps: tuple[np.ndarray, ...] = REFINE_STEPS
    ) -> np.ndarray:
        """Each of ``poses`` (K, 3) moved by coordinate ``steps`` (x, y, heading; by default 0.1 m and 2 deg,
        then half of them), up to ``rounds`` a step size, while the stacked scans fit it better; all poses and
        their six neighbours scored at once. A heading step turns the pose about the scans' centre
        (``turn_about_scans``) or about the robot. A pose none of whose neighbours fitted better is not scored
        again at that step size (its neighbours are the same, and each pose's score does not depend on the
        others scored with it), so the result is that of scoring every pose every round."""
        best = np.asarray(poses, dtype=float).reshape(-1, 3).copy()
        score = self.evidence(best, stack)
        offsets = np.vstack([np.diag([1.0, 1.0, 1.0]), -np.diag([1.0, 1.0, 1.0])])
        centre = stack.centre
        for step in steps:
            moving = np.arange(len(best))
            for _ in range(rounds):
                moved = best[moving, None, :] + offsets[None, :, :] * step
                for k in (2, 5):  # the heading steps, about the centre
                    moved[:, k] = turned(best[moving], centre, offsets[k, 2] * step[2])
                scores = self.evidence(moved.reshape(-1, 3), stack).reshape(len(moving), 6)
                better = scores.max(axis=1) > score[moving]
                if not better.any():
                    break
                pick = np.argmax(scores, axis=1)
                best[moving[better]] = moved[better, pick[better]]
                score[moving[better]] = scores[better, pick[better]]
                moving = moving[better]
        best[:, 2] = wrap_angle(best[:, 2])
        return best

    def fit_new(self, poses: np.ndarray, recent: ScanStack, history: ScanStack) -> np.ndarray:
        """Places newly offered (K, 3) fitted as the check fits a new candidate: to the ``recent`` scans from
        wherever they were offered, then ``admit_rounds`` of ``admit_steps`` against all the kept scans
        (``history``). ``update`` screens the candidates between the two."""
        return self.refine(self.refine(poses, recent, rounds=3), history, rounds=ADMIT_ROUNDS, steps=ADMIT_STEPS)

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
        the newest scans fit best. With ``lead`` (and ``switch``), follow the rival that leads the estimate
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
        # the estimate as the filter left it, and (fit_estimate) its place fitted as the rivals are: scored once each
        places = [estimate, self._fit_estimate(estimate, recent, history)]
        # every one by a touch against all the kept scans it is scored on: fitted to the newest alone, a place a
        # degree off in heading would carry back metres off along 15 m of history and lose a rival; a new one
        # (fitted to the newest scans first, from wherever it was offered, and screened on them) by
        # ``admit_rounds`` of it and a finer step
        refined = np.array(pool[:kept], dtype=float).reshape(-1, 3)
        if kept:
            refined = self.refine(refined, history, rounds=1, steps=DEEP_TOUCH)
        offered = np.array(pool[kept:], dtype=float).reshape(-1, 3)
        if len(offered):
            offered = self.refine(offered, recent, rounds=3)
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
        place, as a new rival, ``admit_rounds`` of it and a finer step).
        Scored unfitted against rivals fitted at every update since they stood, a right estimate trailed its
        twins by up to 500 nats on a development building (gen-970 route 2) and stayed ``ambiguous``."""
        if self._anchor is None or not self._known(self._anchor, [estimate]):  # a new place: fitted as a new rival
            self._anchor = self.fit_new(estimate[None, :], recent, history)[0]
        else:
            self._anchor = self.refine(self._anchor[None, :], history, rounds=1, steps=DEEP_TOUCH)[0]
        return self._anchor

    def _follow_leader(self, estimate: np.ndarray, history: ScanStack) -> None:
        """Count the updates in a row at which the same rival (within ``distinct_m``, ``distinct_deg``) led the
        estimate by ``switch_log_ratio``, both fitted to the kept scans to convergence first (``DEEP_STEPS``). The
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
        """The rival the kept scans have favoured over the estimate by ``switch_log_ratio`` or more at the last
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
