"""Reading PIMM's ``.npz`` files (datasets, fingerprint maps) with errors that name the file and the field."""

from __future__ import annotations

import zipfile
from pathlib import Path

import numpy as np

from pimm_env.errors import MissingFileError, WorldError


def write_npz(path: Path, file_format: str, **arrays: np.ndarray | np.generic) -> None:
    """Write ``arrays`` compressed to ``path`` (making its folder), tagged ``format = file_format``."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(path, **{"format": np.str_(file_format), **arrays})  # type: ignore[arg-type]


def read_npz(path: Path, what: str, fields: tuple[str, ...], file_format: str, make_hint: str) -> dict[str, np.ndarray]:
    """The arrays ``fields`` of the ``.npz`` at ``path``, which must carry ``format == file_format``.

    ``what`` names the kind of file in errors; ``make_hint`` says how to make one when it is missing.
    """
    path = Path(path)
    if not path.is_file():
        raise MissingFileError(f"{path}: no {what}; {make_hint}")
    damaged = (OSError, ValueError, zipfile.BadZipFile, EOFError)
    with path.open("rb") as handle:  # ours to close, also when numpy gives up half way
        try:
            data = np.load(handle, allow_pickle=False)
        except damaged as err:
            raise WorldError(f"{path}: not a readable {what}, damaged or truncated ({err}); {make_hint}") from None
        with data:
            missing = [k for k in ("format", *fields) if k not in data.files]
            if missing:
                raise WorldError(f"{path}: {what} lacks field(s) {missing}")
            try:
                if str(data["format"]) != file_format:
                    raise WorldError(f"{path}: format {str(data['format'])!r}, expected {file_format!r}")
                return {k: data[k] for k in fields}
            except damaged as err:  # a member cut short
                if isinstance(err, ValueError) and str(err).startswith(str(path)):
                    raise
                raise WorldError(f"{path}: {what} is damaged or truncated ({err}); {make_hint}") from None
