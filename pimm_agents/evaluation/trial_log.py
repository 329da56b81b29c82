"""A trial's record: true pose and estimate at every fresh scan, in the thesis's CSV log format."""

from __future__ import annotations

import csv
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

#: The thesis's log columns, in order.
CSV_COLUMNS = (
    "timestamp_real",
    "timestamp_est",
    "real_x",
    "real_y",
    "real_theta",
    "est_x",
    "est_y",
    "est_theta",
    "cov_x",
    "cov_y",
    "cov_theta",
)


@dataclass
class TrialLog:
    """Row i: sim time ``time[i]``, true pose ``true[i]``, estimate ``estimate[i]`` made at ``estimate_time[i]``
    with covariance diagonal ``cov[i]``. ``kidnap_index`` is the first row after the last kidnap, if there was
    one (the metrics count from it); ``kidnap_rows`` the first row after each kidnap (a fault run may have
    several)."""

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

    def __post_init__(self) -> None:
        if self.kidnap_index is not None and not self.kidnap_rows:
            self.kidnap_rows = (self.kidnap_index,)

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
        )

    def write_csv(self, path: Path) -> None:
        table = np.column_stack([self.time, self.estimate_time, self.true, self.estimate, self.cov])
        with Path(path).open("w", newline="") as handle:
            writer = csv.writer(handle)
            writer.writerow(CSV_COLUMNS)
            writer.writerows([[f"{v:.6f}" for v in row] for row in table])


def read_csv(path: Path) -> TrialLog:
    """Read a log in the thesis's format; errors name the file, the line and the bad field."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such log file")
    try:
        return _read_rows(path)
    except UnicodeDecodeError:
        raise ValueError(f"{path}: not a text CSV file (it does not decode as UTF-8)") from None


def _read_rows(path: Path) -> TrialLog:
    with path.open(newline="") as handle:
        reader = csv.reader(handle)
        header = [h.strip() for h in next(reader, [])]
        missing = [c for c in CSV_COLUMNS if c not in header]
        if missing:
            raise ValueError(f"{path}: line 1: header lacks column(s) {missing}; expected {', '.join(CSV_COLUMNS)}")
        index = [header.index(c) for c in CSV_COLUMNS]
        rows = []
        for line_no, row in enumerate(reader, start=2):
            if not row or all(not cell.strip() for cell in row):
                continue
            if len(row) != len(header):
                raise ValueError(f"{path}: line {line_no}: {len(row)} fields, the header has {len(header)}")
            values = []
            for column, i in zip(CSV_COLUMNS, index, strict=True):
                try:
                    value = float(row[i])
                except ValueError:
                    raise ValueError(f"{path}: line {line_no}: {column} is not a number: {row[i]!r}") from None
                if not np.isfinite(value):
                    raise ValueError(f"{path}: line {line_no}: {column} is not finite: {row[i]!r}")
                values.append(value)
            rows.append(values)
    if not rows:
        raise ValueError(f"{path}: the log has no rows")
    table = np.array(rows)
    back = np.nonzero(np.diff(table[:, 0]) < 0)[0]
    if len(back):
        line = int(back[0]) + 3  # the header is line 1, the first row line 2
        raise ValueError(
            f"{path}: line {line}: timestamp_real goes back ({table[back[0] + 1, 0]} after {table[back[0], 0]}); "
            f"{len(back)} row(s) out of time order: sort the log by time first"
        )
    return TrialLog(table[:, 0], table[:, 1], table[:, 2:5], table[:, 5:8], table[:, 8:11])
