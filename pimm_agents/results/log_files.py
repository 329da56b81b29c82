"""Trial logs on disk: the thesis's 11-column CSV, and the JSON sidecar that says what the trial was."""

from __future__ import annotations

import csv
import json
from pathlib import Path
from typing import Any

import numpy as np

from pimm_agents.localizer import STATUSES
from pimm_agents.scoring.trial import TrialResult
from pimm_agents.scoring.trial_log import TrialLog
from pimm_env.errors import MissingFileError, ResultsError

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
#: Beside them, where the log has it: the covariance a consumer without the status was shown (amcl_pose's).
PUBLISHED_COLUMNS = ("pub_cov_x", "pub_cov_y", "pub_cov_theta")


def read_csv(path: Path) -> TrialLog:
    """Read a log in the thesis's format; errors name the file, the line and the bad field."""
    path = Path(path)
    if not path.is_file():
        raise MissingFileError(f"{path}: no such log file")
    try:
        return _read_rows(path)
    except UnicodeDecodeError:
        raise ResultsError(f"{path}: not a text CSV file (it does not decode as UTF-8)") from None


def _read_rows(path: Path) -> TrialLog:
    with path.open(newline="") as handle:
        reader = csv.reader(handle)
        header = [h.strip() for h in next(reader, [])]
        missing = [c for c in CSV_COLUMNS if c not in header]
        if missing:
            raise ResultsError(f"{path}: line 1: header lacks column(s) {missing}; expected {', '.join(CSV_COLUMNS)}")
        columns = CSV_COLUMNS + (PUBLISHED_COLUMNS if all(c in header for c in PUBLISHED_COLUMNS) else ())
        index = [header.index(c) for c in columns]
        rows = []
        for line_no, row in enumerate(reader, start=2):
            if not row or all(not cell.strip() for cell in row):
                continue
            if len(row) != len(header):
                raise ResultsError(f"{path}: line {line_no}: {len(row)} fields, the header has {len(header)}")
            values = []
            for column, i in zip(columns, index, strict=True):
                try:
                    value = float(row[i])
                except ValueError:
                    raise ResultsError(f"{path}: line {line_no}: {column} is not a number: {row[i]!r}") from None
                if not np.isfinite(value):
                    raise ResultsError(f"{path}: line {line_no}: {column} is not finite: {row[i]!r}")
                values.append(value)
            rows.append(values)
    if not rows:
        raise ResultsError(f"{path}: the log has no rows")
    table = np.array(rows)
    back = np.nonzero(np.diff(table[:, 0]) < 0)[0]
    if len(back):
        line = int(back[0]) + 3  # the header is line 1, the first row line 2
        raise ResultsError(
            f"{path}: line {line}: timestamp_real goes back ({table[back[0] + 1, 0]} after {table[back[0], 0]}); "
            f"{len(back)} row(s) out of time order: sort the log by time first"
        )
    published = None
    if table.shape[1] > len(CSV_COLUMNS):  # the published variances, with no x-y term in the file
        published = np.column_stack([table[:, 11:14], np.zeros(len(table))])
    return TrialLog(table[:, 0], table[:, 1], table[:, 2:5], table[:, 5:8], table[:, 8:11], published=published)


def read_sidecar(csv_path: Path) -> dict[str, Any]:
    path = Path(csv_path).with_suffix(".json")
    if not path.is_file():
        return {}
    try:
        record = json.loads(path.read_text())
    except json.JSONDecodeError as error:
        raise ResultsError(f"{path}: not JSON ({error})") from None
    kidnap = record.get("kidnap_row")
    if kidnap is not None and (not isinstance(kidnap, int) or kidnap < 0):
        raise ResultsError(f"{path}: kidnap_row must be a row index or null, got {kidnap!r}")
    return record


def write_sidecar(path: Path, result: TrialResult) -> Path:
    """What a trial's CSV holds, beside it: scenario, localizer, trial, seed, world, the first row after the
    kidnap, the localizer's status as ``[first row, status]`` wherever it changed, and the observations its
    guard set aside and the odometry re-bases it took (the thesis's 11 columns
    stay as they are, so the thesis's tools still read the CSV)."""
    s = result.spec
    record = {
        "scenario": s.case,
        "localizer": s.name,
        "factory": s.localizer,
        "trial": s.trial,
        "seed": s.seed,
        "world": s.world,
        "kidnap_row": result.log.kidnap_index,
        "kidnap_rows": list(result.log.kidnap_rows),
        "rows": len(result.log),
        "status": status_changes(np.asarray(result.log.status)),
        "set_aside": result.log.set_aside,
        "rebased": result.log.rebased,
    }
    Path(path).write_text(json.dumps(record, indent=1))
    return Path(path)


def write_csv(log: TrialLog, path: Path) -> Path:
    """Write ``log`` in the thesis's 11-column format (six decimals), and beside them the published variances
    where the log has them (a reader of the thesis's columns finds them where they were)."""
    table = np.column_stack([log.time, log.estimate_time, log.true, log.estimate, log.cov])
    header: tuple[str, ...] = CSV_COLUMNS
    if log.published is not None and len(log.published) == len(table):
        table, header = np.column_stack([table, np.asarray(log.published)[:, :3]]), CSV_COLUMNS + PUBLISHED_COLUMNS
    with Path(path).open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(header)
        writer.writerows([[f"{v:.6f}" for v in row] for row in table])
    return Path(path)


def status_changes(status: np.ndarray) -> list[list[int | str]]:
    """``[row, status name]`` at the first row and wherever the status changes."""
    changed = np.concatenate([[True], status[1:] != status[:-1]]) if len(status) else np.zeros(0, dtype=bool)
    return [[int(row), STATUSES[int(status[row])]] for row in np.flatnonzero(changed)]


def status_rows(changes: list[Any], rows: int, where: Path) -> np.ndarray:
    """Per-row status codes from a sidecar's ``status`` changes; errors name the sidecar."""
    status = np.full(rows, STATUSES.index("localized"), dtype=np.int8)
    for k, change in enumerate(changes):
        if not (isinstance(change, list) and len(change) == 2 and change[1] in STATUSES and 0 <= change[0] < rows):
            raise ResultsError(f"{where}: status[{k}]: expected [row < {rows}, one of {STATUSES}], got {change!r}")
        status[int(change[0]) :] = STATUSES.index(change[1])
    return status
