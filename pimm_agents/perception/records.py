"""The record beside each weights and fingerprint file: what it is, its checksum, and what made it.

A damaged weights file can still load and then label scans badly without a word (one flipped byte took the
segmentation accuracy from 0.93 to 0.33), and a fingerprint map stored at another scale or dtype loads and
sends the filter to wrong places. So every such file ``X.pt`` or ``X.npz`` has ``X.json`` beside it, written
when the file is made, and a file whose record is missing or does not match is refused:

=======================  ===========================================================================
field                    meaning
=======================  ===========================================================================
``kind``                 ``pointnet-weights`` or ``fingerprint-map``
``format``               the file's format version (``pimm-pointnet/1``, ``pimm-fingerprints/1``)
``sha256``               the file's SHA-256
``descriptor_version``   how descriptors are made (:data:`DESCRIPTOR_VERSION`)
``dtype``, ``shape``     the weights' dtype and parameter count; the map's descriptor dtype and shape
``weights_sha256``       (maps) the SHA-256 of the weights whose descriptors the map holds
=======================  ===========================================================================

Other fields (how the weights were trained, the map's spacing and seed) are kept as written.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any

from pimm_env.errors import PerceptionError

#: Descriptors are the network's L2-normalized place vectors; a map of any other kind cannot be searched
#: against this code's queries.
DESCRIPTOR_VERSION = "pimm-descriptor/1 (unit L2)"

WEIGHTS = "pointnet-weights"
FINGERPRINTS = "fingerprint-map"


def record_path(path: Path) -> Path:
    return Path(path).with_suffix(".json")


def file_sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with Path(path).open("rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def write_record(path: Path, kind: str, file_format: str, **fields: Any) -> dict[str, Any]:
    """Write ``path``'s record (its checksum taken now) beside it, keeping ``fields``; returns the record."""
    record = {
        **fields,
        "kind": kind,
        "format": file_format,
        "descriptor_version": DESCRIPTOR_VERSION,
        "sha256": file_sha256(path),
    }
    record_path(path).write_text(json.dumps(record, indent=1) + "\n")
    return record


def read_record(path: Path, kind: str, file_format: str, remake: str) -> dict[str, Any]:
    """``path``'s record, checked against the file: present, of this kind and format, same checksum.

    ``remake`` says how to make a good file, for the errors.
    """
    path = Path(path)
    record_file = record_path(path)
    if not record_file.is_file():
        raise PerceptionError(
            f"{path}: no record {record_file.name} beside it (its checksum and what made it), so it is refused: "
            f"a damaged or foreign file would load and mislead the localizer; {remake}"
        )
    try:
        record = json.loads(record_file.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as err:
        raise PerceptionError(f"{record_file}: not a JSON record ({err}); {remake}") from None
    if not isinstance(record, dict):
        raise PerceptionError(f"{record_file}: not a JSON record (a {type(record).__name__}); {remake}")
    expected = {"kind": kind, "format": file_format, "descriptor_version": DESCRIPTOR_VERSION}
    for key, want in expected.items():
        if key in record and record[key] != want:
            raise PerceptionError(f"{record_file}: {key} is {record[key]!r}, expected {want!r}; {remake}")
    if "kind" not in record and kind != WEIGHTS:  # weights' records older than this field carry the rest
        raise PerceptionError(f"{record_file}: no 'kind' field: not the record of a {kind}; {remake}")
    checksum = record.get("sha256")
    if not isinstance(checksum, str):
        raise PerceptionError(f"{record_file}: no 'sha256' field; {remake}")
    actual = file_sha256(path)
    if actual != checksum:
        raise PerceptionError(
            f"{path}: SHA-256 {actual[:16]}... differs from {record_file.name}'s {checksum[:16]}...: the file is "
            f"damaged, or was changed or replaced without its record; {remake}"
        )
    return record


def recorded(record: dict[str, Any], key: str, record_file: Path, remake: str) -> Any:
    """A field the record must hold, or an error naming it."""
    if key not in record:
        raise PerceptionError(f"{record_file}: no {key!r} field; {remake}")
    return record[key]
