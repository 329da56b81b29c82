"""Every twin of a place, looked at in turns: what must be ruled out before the place is called localized.

A floor of repeated rooms along corridors gives a place hundreds of twins (``pimm_env/mapping/twins.py``; median
191 a place on a real KTH floor), more than the ambiguity check can fit in one update, and the one the robot is
really at need not be among those whose walls match best (after a kidnap on such a floor, the true place was the
70th of 402). So once a place is estimated after a jump, its twins are queued, the ones the newest scans fit best
first, carried by the odometry with the robot, and ``BATCH`` of them are looked at per update: fitted to the newest
scans (a twin's pose is the map's to a quarter metre and ten degrees) and the best ``OFFERED`` of each batch handed to
the check, which fits and scores them as any candidate. The place may be called localized only once the queue is
empty (``examined``): no twin was left out because there were too many to look at.
"""

from __future__ import annotations

import numpy as np

from pimm_agents.pimm.rivals import RivalTracker, carried
from pimm_env.geometry import relative_motion

#: Ours (measured: docs/design.md#the-maps-twins): twins fitted to the newest scans per update (400 twins take the
#: ten updates a status is confirmed over) and the best of them offered to the check.
BATCH, OFFERED = 40, 2
NEWEST_SCANS = 3  # the newest scans a queued twin is fitted to before it is ranked


class TwinQueue:
    """The twins of one place still to be looked at (``start``, ``take``), carried by ``move``."""

    def __init__(self) -> None:
        self.pending = np.zeros((0, 3))
        self.started = False

    def clear(self) -> None:
        self.pending = np.zeros((0, 3))
        self.started = False

    @property
    def examined(self) -> bool:
        """Whether every twin of the place has been looked at (False before ``start``)."""
        return self.started and not len(self.pending)

    def start(self, twins: np.ndarray, tracker: RivalTracker, odom: np.ndarray) -> None:
        """Queue ``twins`` (K, 3), the ones the newest scans fit best (as they are) first."""
        twins = np.asarray(twins, dtype=float).reshape(-1, 3)
        if len(twins):
            fit = tracker.evidence(twins, tracker.stack(odom, NEWEST_SCANS))
            twins = twins[np.argsort(-fit, kind="stable")]
        self.pending, self.started = twins, True

    def move(self, odom_then: np.ndarray, odom_now: np.ndarray) -> None:
        """Carry the queued twins by the odometry since ``odom_then``, as the robot moved."""
        if len(self.pending):
            self.pending = carried(self.pending, relative_motion(odom_then, odom_now))

    def take(self, tracker: RivalTracker, odom: np.ndarray) -> np.ndarray:
        """The next ``BATCH`` twins, fitted to the newest scans; the ``OFFERED`` best of them (K, 3)."""
        batch, self.pending = self.pending[:BATCH], self.pending[BATCH:]
        if not len(batch):
            return batch
        newest = tracker.stack(odom, NEWEST_SCANS)
        fitted = tracker.refine(batch, newest, rounds=3)
        return fitted[np.argsort(-tracker.evidence(fitted, newest), kind="stable")[:OFFERED]]
