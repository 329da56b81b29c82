"""The fingerprint map (thesis 3.2.3-3.2.4): place descriptors of scans at known positions, searched with FAISS.

A query returns the positions of the k nearest descriptors (exact L2 search) and passes them on as pose
suggestions only if they agree: all pairwise distances within ``max_spread`` (eq. 3.8-3.9), else none.
Stored as ``maps/<world>/fingerprints.npz`` (descriptors, positions, the headings they were taken at) with its
record ``fingerprints.json`` beside it (``records.py``); the FAISS index is rebuilt on load, which for an exact
index is a copy and keeps the file free of pickles.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pimm_agents.perception.records import FINGERPRINTS, read_record, record_path, recorded, write_record
from pimm_env.errors import PerceptionError

FORMAT = "pimm-fingerprints/1"
DESCRIPTOR_DTYPE = "float32"
#: how far from 1 a stored descriptor's length may be (float32 rounding of a normalized vector is ~1e-7)
UNIT_TOLERANCE = 1e-3


@dataclass(frozen=True)
class FingerprintConfig:
    """Thesis values: k = 3 neighbours, suggestions dropped when they spread over more than 10 m."""

    k: int = 3
    max_spread: float = 10.0


@dataclass(frozen=True)
class Retrieval:
    """The k nearest map positions (nearest first), their descriptor distances and the spread verdict."""

    positions: np.ndarray
    distances: np.ndarray
    spread: float
    consistent: bool

    @property
    def suggestions(self) -> np.ndarray:
        """Positions to seed particles around: all k if they agree, none otherwise."""
        return self.positions if self.consistent else self.positions[:0]


class FingerprintMap:
    def __init__(
        self,
        descriptors: np.ndarray,
        positions: np.ndarray,
        headings: np.ndarray | None = None,
        config: FingerprintConfig = FingerprintConfig(),
        source: str = "fingerprint map",
    ) -> None:
        import faiss

        descriptors = np.ascontiguousarray(descriptors, dtype=np.float32)
        positions = np.asarray(positions, dtype=np.float64)
        if descriptors.ndim != 2 or len(descriptors) == 0:
            raise PerceptionError(
                f"{source}: descriptors must be a non-empty (M, D) array, got shape {descriptors.shape}"
            )
        if positions.shape != (len(descriptors), 2):
            raise PerceptionError(f"{source}: positions {positions.shape} do not match {len(descriptors)} descriptors")
        if not (np.isfinite(descriptors).all() and np.isfinite(positions).all()):
            raise PerceptionError(f"{source}: descriptors or positions contain NaN or infinite values")
        if config.k < 1 or config.k > len(descriptors):
            raise PerceptionError(
                f"{source}: k = {config.k} must be between 1 and the map's {len(descriptors)} entries"
            )
        self.descriptors = descriptors
        self.positions = positions
        self.headings = np.zeros(len(positions)) if headings is None else np.asarray(headings, dtype=np.float64)
        self.config = config
        self.source = source
        self.index = faiss.IndexFlatL2(descriptors.shape[1])
        self.index.add(descriptors)

    @property
    def dim(self) -> int:
        return self.descriptors.shape[1]

    def __len__(self) -> int:
        return len(self.descriptors)

    def query(self, descriptor: np.ndarray) -> Retrieval:
        """The k nearest entries to one descriptor and the thesis's spread check."""
        q = np.asarray(descriptor, dtype=np.float32).reshape(1, -1)
        if q.shape[1] != self.dim:
            raise PerceptionError(
                f"{self.source}: query descriptor has {q.shape[1]} dimensions, the index has {self.dim}"
            )
        if not np.isfinite(q).all():
            raise PerceptionError(f"{self.source}: query descriptor contains NaN or infinite values")
        distances, index = self.index.search(q, self.config.k)
        positions = self.positions[index[0]]
        diff = positions[:, None, :] - positions[None, :, :]
        spread = float(np.sqrt((diff**2).sum(-1)).max())
        return Retrieval(positions, np.sqrt(np.maximum(distances[0], 0)), spread, spread <= self.config.max_spread)

    def save(self, path: Path, weights_sha256: str, provenance: dict[str, str] | None = None) -> None:
        """Write the map and its record (``records.py``): checksum, descriptor dtype and shape, and the
        checksum of the weights that made the descriptors, which a query must come from."""
        from pimm_env.mapping.npz_file import write_npz

        extra = {f"provenance_{k}": np.str_(v) for k, v in (provenance or {}).items()}
        write_npz(path, FORMAT, descriptors=self.descriptors, positions=self.positions, headings=self.headings, **extra)
        write_record(
            path,
            FINGERPRINTS,
            FORMAT,
            dtype=str(self.descriptors.dtype),
            shape=list(self.descriptors.shape),
            weights_sha256=weights_sha256,
            **(provenance or {}),
        )

    @classmethod
    def load(
        cls, path: Path, config: FingerprintConfig = FingerprintConfig(), weights_sha256: str | None = None
    ) -> FingerprintMap:
        """Read a map written by :meth:`save`, refusing one whose record is missing or does not match (checksum,
        dtype, shape, unit-length descriptors; with ``weights_sha256``, the weights that made it)."""
        from pimm_env.mapping.npz_file import read_npz

        hint = "build one with `python -m training fingerprints --world <world>`"
        path = Path(path)
        record = read_record(path, FINGERPRINTS, FORMAT, hint) if path.is_file() else {}
        data = read_npz(path, "fingerprint map", ("descriptors", "positions", "headings"), FORMAT, hint)
        descriptors = data["descriptors"]
        record_file = record_path(path)
        dtype, shape = (recorded(record, key, record_file, hint) for key in ("dtype", "shape"))
        if str(descriptors.dtype) != dtype or dtype != DESCRIPTOR_DTYPE:
            raise PerceptionError(
                f"{path}: descriptors stored as {descriptors.dtype}, the record says {dtype}; a map's descriptors "
                f"are {DESCRIPTOR_DTYPE}; {hint}"
            )
        if list(descriptors.shape) != list(shape):
            raise PerceptionError(f"{path}: descriptors of shape {descriptors.shape}, the record says {shape}; {hint}")
        norms = np.linalg.norm(descriptors.astype(np.float64), axis=1)
        if len(norms) and np.abs(norms - 1).max() > UNIT_TOLERANCE:
            raise PerceptionError(
                f"{path}: descriptor lengths {norms.min():.3g}-{norms.max():.3g}, expected 1 (unit L2): scaled, or not "
                f"made by this code's network; {hint}"
            )
        made_with = recorded(record, "weights_sha256", record_file, hint)
        if weights_sha256 is not None and made_with != weights_sha256:
            raise PerceptionError(
                f"{path}: made with weights {str(made_with)[:16]}..., the segmenter runs {weights_sha256[:16]}...: its "
                f"descriptors cannot be matched against this network's; {hint}"
            )
        return cls(descriptors, data["positions"], data["headings"], config, source=str(path))
