"""Segmentation and place descriptor of one 3D scan with the trained PointNet, on the CPU.

The network looks at a fixed number of the scan's points, every k-th return in scan order (the thesis's
"partial segmentation" future work); every other return takes the class of the nearest of those in scan order,
which is almost always its neighbour in the same layer.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from pimm_agents.point_features import point_features, with_context
from pimm_agents.pointnet import FusedPointNet, PointNetSegmenter, load_checkpoint


def strided_sample(valid_index: np.ndarray, count: int, offset: int = 0) -> np.ndarray:
    """Positions (into ``valid_index``) of ``count`` points spread evenly over the returns, in scan order.

    With fewer returns than ``count`` every return is taken and the list is filled by repeating them, which
    changes neither the max-pooled global feature nor any point's class.
    """
    n = len(valid_index)
    if n == 0:
        raise ValueError("the scan has no returns to segment")
    if n <= count:
        return np.resize(np.arange(n), count)
    stride = n / count
    return np.minimum((offset % max(1, int(stride)) + stride * np.arange(count)).astype(np.int64), n - 1)


def nearest_sampled(n_valid: int, sampled: np.ndarray) -> np.ndarray:
    """For each of ``n_valid`` returns in scan order, the slot in ``sampled`` of the nearest sampled return.

    ``sampled`` is what :func:`strided_sample` gives: increasing, then (for short scans) repeats of itself.
    """
    order = sampled[: min(n_valid, len(sampled))]
    pos = np.arange(n_valid)
    right = np.clip(np.searchsorted(order, pos), 0, len(order) - 1)
    left = np.clip(right - 1, 0, len(order) - 1)
    return np.where(np.abs(order[left] - pos) <= np.abs(order[right] - pos), left, right)


@dataclass(frozen=True)
class Segmentation:
    """Per-point classes of the whole scan (-1 where no return) and the scan's place descriptor."""

    labels: np.ndarray
    descriptor: np.ndarray
    timings_ms: dict[str, float]


class Segmenter:
    """Runs a trained checkpoint on scans from the env: ``segment(cloud, mask) -> Segmentation``."""

    def __init__(self, checkpoint: Path, layers: int = 40, points_per_layer: int = 360) -> None:
        self.model: PointNetSegmenter
        self.model, self.training = load_checkpoint(checkpoint)
        self.network = FusedPointNet(self.model)
        self.checkpoint = Path(checkpoint)
        self.layers = layers
        self.points_per_layer = points_per_layer

    @property
    def descriptor_dim(self) -> int:
        return self.model.config.descriptor_dim

    def segment(self, cloud: np.ndarray, mask: np.ndarray) -> Segmentation:
        start = time.perf_counter()
        features = point_features(cloud, mask, self.layers, self.points_per_layer)
        valid = np.asarray(mask, dtype=bool).reshape(-1) & np.isfinite(np.asarray(cloud)).all(axis=1)
        valid_index = np.flatnonzero(valid)
        if len(valid_index) == 0:
            raise ValueError("cannot segment a scan with no finite returns (empty or all-NaN cloud)")
        sampled = strided_sample(valid_index, self.model.config.points)
        offsets = self.model.config.context_offsets
        chosen = with_context(features, valid_index[sampled], self.layers, self.points_per_layer, offsets)
        inputs = torch.from_numpy(chosen)
        prepared = time.perf_counter()
        with torch.inference_mode():
            logits, descriptor = self.network(inputs)
        inferred = time.perf_counter()
        classes = logits.argmax(dim=1).numpy().astype(np.int8)
        labels = np.full(len(valid), -1, dtype=np.int8)
        labels[valid_index] = classes[nearest_sampled(len(valid_index), sampled)]
        done = time.perf_counter()
        return Segmentation(
            labels=labels,
            descriptor=descriptor.numpy().astype(np.float32),
            timings_ms={
                "features": 1000 * (prepared - start),
                "network": 1000 * (inferred - prepared),
                "labels": 1000 * (done - inferred),
            },
        )
