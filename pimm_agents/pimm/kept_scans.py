"""The wall scans the ambiguity check keeps, and how well a place fits them.

The check keeps the wall points of the last ``history`` measurement updates with the odometry at each. A place
now is carried back along the odometry to every kept scan, and the scans' tempered log-likelihoods there (the
filter's wall field) are summed (``evidence``, compiled in scan_evidence.py). Two places are compared scan by scan,
a scan's difference counting only beyond what a wall drawn ``MAP_ERROR_CELLS`` off would cost it
(``margins_over``); places are fitted to the scans by coordinate steps (``refine``), a heading turning a place
about the scans' centre rather than the robot.
"""

from __future__ import annotations

from collections import deque

import numpy as np

from pimm_agents.particles.likelihood_field import LikelihoodField
from pimm_agents.pimm.scan_evidence import scan_by_scan_evidence, summed_scan_evidence
from pimm_agents.pimm.scan_stack import ScanStack, points_centre, turned
from pimm_env.geometry import relative_motion, wrap_angle

#: Fixed choices of the fit (ours; each measured, docs/design.md#the-ambiguity-check): a scan's difference between
#: two places within what a wall this many map cells off would cost its points counts as none (the map's raster
#: puts walls up to half a cell from where they stand)
MAP_ERROR_CELLS = 0.5
REFINE_SCANS = 10  # a candidate is first fitted to the newest scans
ADMIT_ROUNDS = 3  # rounds of each step a new candidate gets against all the kept scans before it is scored
#: rounds of each step a new candidate gets against the newest scans, from wherever it was offered: up to 1.5 m and
#: 30 deg back to its place (a filter mode's mean heading lay 13 deg off its place's, and 3 rounds left the true place
#: screened out while a wrong one was called localized: docs/design.md#the-ambiguity-check)
OFFER_ROUNDS = 10

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


class KeptScans:
    """The newest ``history`` wall scans (robot frame, with the odometry at each) and the fit of places to them;
    ``settled`` once ``settle`` are kept."""

    def __init__(self, field: LikelihoodField, free: np.ndarray, temperature: float, history: int, settle: int) -> None:
        self.field = field
        self.free = free  # (rows, cols) of the map: a pose outside them is penalized
        self.temperature = temperature
        self.settle = settle
        self._scans: deque[tuple[np.ndarray, np.ndarray]] = deque(maxlen=history)
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

    def drop_scans(self) -> None:
        self._scans.clear()
        self._recent = None

    @property
    def settled(self) -> bool:
        """Whether enough scans are kept (``settle``) for the check to call a place unrivalled."""
        return len(self._scans) >= self.settle

    @property
    def scans_added(self) -> int:
        """How many scans have been kept since the tracker was made (a counter that never goes back)."""
        return self._added

    def add_scan(self, odom: np.ndarray, wall_points: np.ndarray) -> None:
        """Keep a scan's wall points (M, 2; robot frame) with the odometry at which they were seen."""
        if len(wall_points):
            self._scans.append((np.asarray(odom, dtype=float).copy(), np.asarray(wall_points, dtype=float)))
            self._added += 1

    def newest_scan(self) -> tuple[np.ndarray, np.ndarray] | None:
        """The newest kept scan: the odometry at which it was seen and its wall points (robot frame)."""
        return self._scans[-1] if self._scans else None

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
        """Per stacked scan (S,): what a wall ``MAP_ERROR_CELLS`` cells off costs each of its points, summed and
        tempered."""
        offset = MAP_ERROR_CELLS * self.field.grid.resolution
        per_point = offset**2 / (2 * self.field.params.sigma_hit**2)
        points = np.bincount(stack.scan_of, minlength=len(stack.motions))
        return self.temperature * per_point * points

    def margins_over(self, poses: np.ndarray, reference: np.ndarray, stack: ScanStack) -> np.ndarray:
        """How much better the stacked scans fit each of ``poses`` (K, 3) than ``reference`` (3,): the difference
        of the summed evidence (``MAP_ERROR_CELLS`` 0), or scan by scan with each scan's difference counted only
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
        (not about the robot). A pose none of whose neighbours fitted better is not scored
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
        wherever they were offered, then ``ADMIT_ROUNDS`` of ``ADMIT_STEPS`` against all the kept scans
        (``history``). ``update`` screens the candidates between the two."""
        fitted = self.refine(poses, recent, rounds=OFFER_ROUNDS)
        return self.refine(fitted, history, rounds=ADMIT_ROUNDS, steps=ADMIT_STEPS)
