"""Does a localizer know when it is right? Its reported status and covariance, held against the truth.

The thesis's metrics say when a trial's estimate settled near the truth; they do not say whether the localizer
claimed to be localized while it was wrong, which is what a navigation stack acting on the pose must know. A
pose is *right* within ``RIGHT_POSITION_M`` and ``RIGHT_ANGLE_DEG``; a row's duration is the time to the next
row. A localizer that reports no status counts as localized on every row.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pimm_agents.scoring.metrics import angle_errors_deg, position_errors
from pimm_agents.scoring.trial_log import TrialLog

RIGHT_POSITION_M = 1.0
RIGHT_ANGLE_DEG = 10.0
#: A kidnap must be noticed (the status leave ``localized``) within this time (s); the localized rows until it
#: is noticed are not counted false when it is (no localizer can know of a kidnap before it sees a scan).
KIDNAP_NOTICE_S = 2.0
#: Mahalanobis distance of the 3-sigma ellipse (2-D position: 98.9 % of a consistent estimate's errors).
SIGMAS = 3.0
#: A row is *overconfident* when the position is more than ``RIGHT_POSITION_M`` off while the covariance shows a
#: position sigma (its larger axis) under this (m): a consumer reading only the ellipse is misled.
CONFIDENT_SIGMA_M = 0.5


@dataclass(frozen=True)
class HonestyMetrics:
    #: first time (s from the log's start) the status is localized with the pose right, staying right while localized
    time_to_localized_s: float | None
    localized_s: float  # seconds with status localized
    false_localized_s: float  # seconds with status localized while the pose is wrong
    false_localized_rate: float | None  # false_localized_s over localized_s
    max_false_localized_s: float  # the longest such spell
    within_3sigma: float | None  # share of rows from convergence on whose position error is inside the 3-sigma ellipse
    nees: float | None  # mean normalized estimation error squared of the position there (2 when consistent)
    #: a log that starts at a kidnap: seconds until the status first left localized (inf: it never did)
    kidnap_noticed_s: float | None = None
    rows: int = 0
    #: rows more than ``RIGHT_POSITION_M`` off with a position sigma under ``CONFIDENT_SIGMA_M``: by the chosen
    #: mode's covariance, and by the published one (None: the log has none)
    overconfident_rows: int = 0
    published_overconfident_rows: int | None = None


def row_durations(time: np.ndarray) -> np.ndarray:
    """Each row's duration: the time to the next row (the last row: 0)."""
    return np.diff(time, append=time[-1]) if len(time) else np.zeros(0)


def longest_spell(flags: np.ndarray, durations: np.ndarray) -> float:
    """The longest run of consecutive ``flags`` rows, in seconds."""
    padded = np.concatenate([[False], flags, [False]])
    edges = np.flatnonzero(padded[1:] != padded[:-1])  # run i covers rows edges[2i] .. edges[2i + 1] - 1
    sums = np.concatenate([[0.0], np.cumsum(durations)])
    spells = sums[edges[1::2]] - sums[edges[::2]]
    return float(spells.max()) if len(spells) else 0.0


def position_nees(log: TrialLog) -> np.ndarray:
    """Per row, the squared Mahalanobis distance of the position error under the reported x-y covariance
    (inf where that covariance is singular and the error is not zero)."""
    error = log.estimate[:, :2] - log.true[:, :2]
    cxx, cyy, cxy = log.cov[:, 0], log.cov[:, 1], np.asarray(log.cov_xy, dtype=float)
    det = cxx * cyy - cxy**2
    with np.errstate(divide="ignore", invalid="ignore"):
        d2 = (cyy * error[:, 0] ** 2 - 2 * cxy * error[:, 0] * error[:, 1] + cxx * error[:, 1] ** 2) / det
    exact = np.all(error == 0, axis=1)
    return np.where(det > 0, d2, np.where(exact, 0.0, np.inf))


def overconfident(log: TrialLog, variances: np.ndarray, xy: np.ndarray) -> int:
    """Rows more than ``RIGHT_POSITION_M`` off whose x-y covariance's larger axis is under ``CONFIDENT_SIGMA_M``."""
    cxx, cyy = variances[:, 0], variances[:, 1]
    larger = (cxx + cyy) / 2 + np.sqrt(((cxx - cyy) / 2) ** 2 + xy**2)
    return int(np.count_nonzero((position_errors(log) > RIGHT_POSITION_M) & (larger < CONFIDENT_SIGMA_M**2)))


def honesty_metrics(log: TrialLog, convergence_time_s: float | None, kidnapped: bool = False) -> HonestyMetrics:
    """The metrics of ``log``; covariance consistency over the rows from ``convergence_time_s`` on (None: none).
    ``kidnapped``: the log starts at a kidnap; the rows until the status first leaves localized are not false
    if that is within ``KIDNAP_NOTICE_S``, and the time it took is ``kidnap_noticed_s``."""
    if len(log) == 0:
        return HonestyMetrics(None, 0.0, 0.0, None, 0.0, None, None, None)
    right = (position_errors(log) < RIGHT_POSITION_M) & (angle_errors_deg(log) < RIGHT_ANGLE_DEG)
    localized = log.localized
    durations = row_durations(log.time)
    false = localized & ~right
    noticed = None
    if kidnapped:
        left = np.flatnonzero(~localized)
        noticed = float(log.time[left[0]] - log.time[0]) if len(left) else float("inf")
        if noticed <= KIDNAP_NOTICE_S:
            false[: left[0]] = False
    localized_s, false_s = float(durations[localized].sum()), float(durations[false].sum())
    after_last_false = np.flatnonzero(false)[-1] + 1 if np.any(false) else 0
    found = np.flatnonzero((localized & right)[after_last_false:])
    time_to_localized = float(log.time[after_last_false + found[0]] - log.time[0]) if len(found) else None
    within = nees = None
    if convergence_time_s is not None:
        d2 = position_nees(log)[log.time - log.time[0] >= convergence_time_s - 1e-9]
        if len(d2):
            within = float(np.mean(d2 <= SIGMAS**2))
            finite = d2[np.isfinite(d2)]  # a singular covariance with an error: outside every ellipse
            nees = float(np.mean(finite)) if len(finite) else None
    return HonestyMetrics(
        time_to_localized,
        localized_s,
        false_s,
        false_s / localized_s if localized_s > 0 else None,
        longest_spell(false, durations),
        within,
        nees,
        noticed,
        len(log),
        overconfident(log, log.cov, np.asarray(log.cov_xy, dtype=float)),
        None if log.published is None else overconfident(log, log.published[:, :3], log.published[:, 3]),
    )
