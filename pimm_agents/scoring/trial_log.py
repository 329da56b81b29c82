"""A trial's record: true pose and estimate at every fresh scan, in the thesis's CSV log format."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from pimm_agents.localizer import STATUSES


@dataclass
class TrialLog:
    """Row i: sim time ``time[i]``, true pose ``true[i]``, estimate ``estimate[i]`` made at ``estimate_time[i]``
    with covariance diagonal ``cov[i]`` and x-y covariance ``cov_xy[i]``, and the localizer's ``status[i]`` (an
    index into ``localizer.STATUSES``; a log without them reads as uncorrelated and always localized).
    ``kidnap_index`` is the first row after the last kidnap, if there was one (the metrics count from it);
    ``kidnap_rows`` the first row after each kidnap (a fault run may have several)."""

    time: np.ndarray
    estimate_time: np.ndarray
    true: np.ndarray
    estimate: np.ndarray
    cov: np.ndarray
    kidnap_index: int | None = None
    timings: list[dict[str, float]] = field(default_factory=list, repr=False)
    #: (K, 3): row, x, y of the corners the localizer detected in the update of that row, placed at its estimate
    #: (for figures; empty for localizers that detect none)
    corners: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)), repr=False)
    kidnap_rows: tuple[int, ...] = ()
    status: np.ndarray | None = None
    cov_xy: np.ndarray | None = None
    #: observations the localizer's guard set aside as glitches, by kind, and lasting jumps it took as a new
    #: odometry base (observation_guard.py): nothing it drops goes uncounted
    set_aside: dict[str, int] = field(default_factory=dict)
    rebased: int = 0
    #: (N, 4): the covariance a consumer without the status was shown (``localizer.published_covariance``): x, y
    #: and theta variances and the x-y covariance; None for logs made elsewhere
    published: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.kidnap_index is not None and not self.kidnap_rows:
            self.kidnap_rows = (self.kidnap_index,)
        if self.status is None:
            self.status = np.full(len(self.time), STATUSES.index("localized"), dtype=np.int8)
        if self.cov_xy is None:
            self.cov_xy = np.zeros(len(self.time))

    @property
    def localized(self) -> np.ndarray:
        """Per row: did the localizer say it was localized?"""
        return np.asarray(self.status) == STATUSES.index("localized")

    def __len__(self) -> int:
        return len(self.time)

    def after_kidnap(self) -> TrialLog:
        """The rows from the kidnap on (the whole log if there was none)."""
        start = self.kidnap_index or 0
        corners = self.corners[self.corners[:, 0] >= start] - [start, 0.0, 0.0]
        return TrialLog(
            self.time[start:],
            self.estimate_time[start:],
            self.true[start:],
            self.estimate[start:],
            self.cov[start:],
            None,
            self.timings[start:],
            corners,
            (),
            None if self.status is None else self.status[start:],
            None if self.cov_xy is None else self.cov_xy[start:],
            published=None if self.published is None else self.published[start:],
        )

    def until(self, seconds: float) -> TrialLog:
        """The rows of the first ``seconds`` of the log (from its first row's time)."""
        end = int(np.searchsorted(self.time - self.time[0], seconds, side="right")) if len(self.time) else 0
        return TrialLog(
            self.time[:end],
            self.estimate_time[:end],
            self.true[:end],
            self.estimate[:end],
            self.cov[:end],
            self.kidnap_index if self.kidnap_index is not None and self.kidnap_index < end else None,
            self.timings[:end],
            self.corners[self.corners[:, 0] < end],
            (),
            None if self.status is None else self.status[:end],
            None if self.cov_xy is None else self.cov_xy[:end],
            published=None if self.published is None else self.published[:end],
        )
