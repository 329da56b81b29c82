"""The fingerprint map (thesis 3.2.3-3.2.4): place descriptors of scans at known positions, searched with FAISS.

A query returns the positions of the k nearest descriptors (exact L2 search) and passes them on as pose
suggestions only if they agree: all pairwise distances within ``max_spread`` (eq. 3.8-3.9), else none.
Stored as ``maps/<world>/fingerprints.npz`` (descriptors, positions, the headings they were taken at); the
FAISS index is rebuilt on load, which for an exact index is a copy and keeps the file free of pickles.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pimm_env.errors import PerceptionError

FORMAT = "pimm-fingerprints/1"


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

    def save(self, path: Path, provenance: dict[str, str] | None = None) -> None:
        from pimm_env.mapping.npz_file import write_npz

        extra = {f"provenance_{k}": np.str_(v) for k, v in (provenance or {}).items()}
        write_npz(path, FORMAT, descriptors=self.descriptors, positions=self.positions, headings=self.headings, **extra)

    @classmethod
    def load(cls, path: Path, config: FingerprintConfig = FingerprintConfig()) -> FingerprintMap:
        """Read a map written by :meth:`save`; a missing or damaged file and missing fields are named."""
        from pimm_env.mapping.npz_file import read_npz

        hint = "build one with `python -m training fingerprints --world <world>`"
        data = read_npz(path, "fingerprint map", ("descriptors", "positions", "headings"), FORMAT, hint)
        return cls(data["descriptors"], data["positions"], data["headings"], config, source=str(path))
