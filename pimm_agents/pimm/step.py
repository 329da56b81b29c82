"""One measurement step of PIMM: the thesis's filter weighs, the ambiguity check reviews its belief beside it,
and the localizer's step applies the check's decision through the filter's public methods.

Order of one step (after a motion update): the filter weighs the particles (``FeatureFilter.weigh``) and proposes
an estimate; a held estimate about to jump away is kept if the check says the kept scans hold it
(``AmbiguityCheck.holds``; the new place's particles are moved onto it); the belief's reading of the estimate is
reviewed (``AmbiguityCheck.review``), and a rival that decisively leads takes the estimate's mode; the status is
confirmed over ``confirm_updates`` updates; the filter resamples and injects. Without a check (``rivals.enabled``
off) the step is the filter's own, with the belief's status.
"""

from __future__ import annotations

import time

import numpy as np

from pimm_agents.particles.belief import BeliefReading, Confirmation
from pimm_agents.pimm.ambiguity import AmbiguityCheck
from pimm_agents.pimm.feature_filter import FeatureFilter


class MeasurementStep:
    """The filter and, beside it, the check (None: the filter alone); ``reading`` is the last step's status,
    covariance and hypotheses, ``check_ms`` the check's share of the last step (ms)."""

    def __init__(self, filt: FeatureFilter, check: AmbiguityCheck | None, confirm_updates: int) -> None:
        self.filter = filt
        self.check = check
        self.confirmation = Confirmation(confirm_updates)
        self.reading = BeliefReading("lost", np.eye(3), ())
        self.check_ms = 0.0

    def reset(self) -> None:
        """Forget the statuses and the check's state (after the filter's own reset)."""
        self.confirmation.reset()
        if self.check is not None:
            self.check.reset()
        self.reading = BeliefReading("lost", self.filter.covariance(self.filter.best_mean()), ())

    def __call__(
        self,
        features: np.ndarray,
        walls: np.ndarray | None,
        suggestions: np.ndarray,
        previous: np.ndarray | None,
        odom: np.ndarray,
    ) -> np.ndarray | None:
        """Weigh with ``features`` and ``walls`` (robot frame now), review, apply, resample and inject around
        ``suggestions``; ``previous`` is the last estimate carried to now, ``odom`` the odometry now. Returns the
        new estimate, or None (the caller carries its last one by odometry)."""
        filt, check = self.filter, self.check
        checking = 0.0  # s spent in the check
        filt.weigh(features, walls)
        estimate = filt.estimate(previous)
        if estimate is not None and previous is not None and check is not None and filt.jumps(previous, estimate):
            start = time.perf_counter()
            holds = check.holds(previous, estimate, odom, walls)
            checking += time.perf_counter() - start
            if holds:
                filt.move_mode(estimate, previous)  # a held place the kept scans favour: its rival's particles
                estimate = None  # are moved onto it
        pose = estimate if estimate is not None else previous
        reading = filt.read(pose)
        own, earned = reading.status, 0  # the belief's own status, before the check
        radius = max(filt.config.switch_radius_m, 0.5)
        jumped = previous is None or (pose is not None and np.hypot(*(pose[:2] - previous[:2])) > radius)
        if check is not None:
            left = previous if jumped else None
            start = time.perf_counter()
            decision = check.review(filt.view(), odom, pose, reading, self.reading.status, walls, left, suggestions)
            checking += time.perf_counter() - start
            if decision.move_to is not None and pose is not None:  # the check moves only a place it reviewed
                filt.move_mode(pose, decision.move_to)
                reading, estimate, jumped = filt.read(decision.move_to), decision.move_to, True
                earned = decision.led
            reading = BeliefReading(
                decision.status, reading.covariance, reading.hypotheses + decision.rivals, reading.chosen
            )
        confirmed = self.confirmation(own, jumped, earned)  # a rival standing vetoes; it does not restart the count
        status = confirmed if reading.status == "localized" else reading.status
        self.reading = BeliefReading(status, reading.covariance, reading.hypotheses)
        if check is not None:
            check.after(status, jumped)
            self.check_ms = 1000 * checking
        filt.resample_and_inject(suggestions)
        return estimate
