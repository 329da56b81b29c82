"""Segmentation and place descriptor of one 3D scan with the trained PointNet, on the CPU.

Two segmenters, one per kind of weights (``load_segmenter`` picks): :class:`Segmenter` for a network of
``grid`` inputs, trained on one organized layout, and :class:`CloudSegmenter` for one of ``cloud`` inputs,
which reads the returns of any LiDAR. The rest of this docstring is the grid segmenter's.

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
from scipy.spatial import cKDTree

from pimm_agents.perception.cloud_features import CloudFeatureConfig, cloud_features
from pimm_agents.perception.point_features import point_features, valid_returns, with_context
from pimm_agents.perception.pointnet import FusedPointNet, PointNetSegmenter, load_checkpoint
from pimm_agents.perception.threads import ThreadChooser
from pimm_env.errors import ObservationError, PerceptionError
from pimm_env.world.semantics import SemanticClass


def strided_sample(valid_index: np.ndarray, count: int, offset: int = 0) -> np.ndarray:
    """Positions (into ``valid_index``) of ``count`` points spread evenly over the returns, in scan order.

    With fewer returns than ``count`` every return is taken and the list is filled by repeating them, which
    changes neither the max-pooled global feature nor any point's class.
    """
    n = len(valid_index)
    if n == 0:
        raise ObservationError("the scan has no returns to segment")
    if n <= count:
        return np.resize(np.arange(n), count)
    stride = n / count
    return np.minimum((offset % max(1, int(stride)) + stride * np.arange(count)).astype(np.int64), n - 1)


def _bracketing_samples(n_valid: int, sampled: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The sampled positions in scan order, and for each return the slots of the samples before and after it."""
    order = sampled[: min(n_valid, len(sampled))]
    at = np.bincount(order, minlength=n_valid)
    after = np.cumsum(at) - at  # samples before each return: np.searchsorted(order, returns), ten times faster
    return order, np.maximum(after - 1, 0), np.minimum(after, len(order) - 1)


def nearest_sampled(n_valid: int, sampled: np.ndarray) -> np.ndarray:
    """For each of ``n_valid`` returns in scan order, the slot in ``sampled`` of the nearest sampled return.

    ``sampled`` is what :func:`strided_sample` gives: increasing, then (for short scans) repeats of itself.
    """
    return _nearest(*_bracketing_samples(n_valid, sampled))


def disputed_returns(n_valid: int, sampled: np.ndarray, classes: np.ndarray) -> np.ndarray:
    """Positions (in scan order) of the returns that were not sampled and lie between two sampled returns of
    different classes: where a class boundary falls, which the nearest sample's class may get wrong.

    ``classes`` holds the class of each slot of ``sampled``.
    """
    return _disputed(*_bracketing_samples(n_valid, sampled), classes)


def _nearest(order: np.ndarray, left: np.ndarray, right: np.ndarray) -> np.ndarray:
    pos = np.arange(len(left))
    return np.where(np.abs(order[left] - pos) <= np.abs(order[right] - pos), left, right)


def _disputed(order: np.ndarray, left: np.ndarray, right: np.ndarray, classes: np.ndarray) -> np.ndarray:
    unsure = classes[left] != classes[right]
    unsure[order] = False
    return np.flatnonzero(unsure)


@dataclass(frozen=True)
class Segmentation:
    """Per-point classes of the whole scan (-1 where no return) and the scan's place descriptor."""

    labels: np.ndarray
    descriptor: np.ndarray
    timings_ms: dict[str, float]


class _Network:
    """What both segmenters hold: the checked weights of one input kind, fused for inference, and a thread
    count chosen by timing."""

    def __init__(self, checkpoint: Path, inputs: str) -> None:
        self.model: PointNetSegmenter
        self.model, self.training = load_checkpoint(checkpoint)
        if self.model.config.inputs != inputs:
            other = "CloudSegmenter" if self.model.config.inputs == "cloud" else "Segmenter"
            raise PerceptionError(f"{checkpoint}: weights of {self.model.config.inputs!r} inputs; use {other}")
        self.network = FusedPointNet(self.model)
        self.checkpoint = Path(checkpoint)
        #: the network's thread count, kept to what runs faster beside whatever else the machine does
        self.threads = ThreadChooser()

    @property
    def weights_sha256(self) -> str:
        """The checksum of the weights, which a fingerprint map made with them records."""
        return str(self.training["sha256"])

    @property
    def descriptor_dim(self) -> int:
        return self.model.config.descriptor_dim


class Segmenter(_Network):
    """Runs a trained checkpoint on scans from the env: ``segment(cloud, mask) -> Segmentation``."""

    def __init__(self, checkpoint: Path, layers: int = 40, points_per_layer: int = 360) -> None:
        super().__init__(checkpoint, "grid")
        self.layers = layers
        self.points_per_layer = points_per_layer

    def _inputs(
        self, cloud: np.ndarray, mask: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Per-return features, which returns are valid, their indices, the sampled ones (into the indices) and
        the network's input for those."""
        features = point_features(cloud, mask, self.layers, self.points_per_layer)
        valid = valid_returns(np.asarray(cloud), mask)
        valid_index = np.flatnonzero(valid)
        if len(valid_index) == 0:
            raise ObservationError("cannot segment a scan with no finite returns (empty or all-NaN cloud)")
        sampled = strided_sample(valid_index, self.model.config.points)
        offsets = self.model.config.context_offsets
        chosen = with_context(features, valid_index[sampled], self.layers, self.points_per_layer, offsets)
        return features, valid, valid_index, sampled, chosen

    def describe(self, cloud: np.ndarray, mask: np.ndarray) -> np.ndarray:
        """The scan's unit descriptor alone, as ``segment`` gives it (no classes: what a fingerprint map needs;
        the classification head and the boundary pass are most of a third of the network's time)."""
        chosen = self._inputs(cloud, mask)[4]
        self.threads.before()
        start = time.perf_counter()
        with torch.inference_mode():
            net = self.network
            descriptor = net.descriptor_of(net.global_feature(net.local_features(torch.from_numpy(chosen))))
        self.threads.after(time.perf_counter() - start)
        return descriptor.numpy().astype(np.float32)

    def segment(self, cloud: np.ndarray, mask: np.ndarray) -> Segmentation:
        start = time.perf_counter()
        features, valid, valid_index, sampled, chosen = self._inputs(cloud, mask)
        offsets = self.model.config.context_offsets
        net = self.network
        self.threads.before()
        prepared = time.perf_counter()
        with torch.inference_mode():
            local = net.local_features(torch.from_numpy(chosen))
            glob = net.global_feature(local)
            classes = net.logits(local, glob).argmax(dim=1).numpy().astype(np.int8)
            descriptor = net.descriptor_of(glob)
            inferred = time.perf_counter()
            # every return takes its nearest sample's class, except near class boundaries: there the network
            # classifies the return itself, against the same global feature
            brackets = _bracketing_samples(len(valid_index), sampled)
            in_order = classes[_nearest(*brackets)]
            todo = _disputed(*brackets, classes)
            if len(todo):
                extra = with_context(features, valid_index[todo], self.layers, self.points_per_layer, offsets)
                logits = net.logits(net.local_features(torch.from_numpy(extra)), glob)
                in_order[todo] = logits.argmax(dim=1).numpy()
        done = time.perf_counter()
        self.threads.after(done - prepared)
        labels = np.full(len(valid), -1, dtype=np.int8)
        labels[valid_index] = in_order
        return Segmentation(
            labels=labels,
            descriptor=descriptor.numpy().astype(np.float32),
            timings_ms={
                "features": 1000 * (prepared - start),
                "network": 1000 * (inferred - prepared),
                "boundaries": 1000 * (done - inferred),
            },
        )


#: returns closer than this to the sensor are its own body, mount or robot (m)
BODY_RANGE_M = 0.2


class CloudSegmenter(_Network):
    """A network of ``cloud`` inputs (``cloud_features.py``) on the returns of any LiDAR, organized or not:
    ``segment_points(level, height)`` for a levelled point set, ``segment(cloud, mask)`` as :class:`Segmenter`
    for a scan in the robot's level frame at the sensor, ``sensor_height`` m above the floor."""

    def __init__(
        self, checkpoint: Path, sensor_height: float = 0.5, features: CloudFeatureConfig = CloudFeatureConfig()
    ) -> None:
        super().__init__(checkpoint, "cloud")
        self.features = features
        #: the sensor's height above the floor (m) for :meth:`segment`; the localizer sets its LiDAR's
        self.sensor_height = sensor_height

    def segment(self, cloud: np.ndarray, mask: np.ndarray) -> Segmentation:
        """Classes of every point of ``cloud`` (-1 where no return) and the scan's descriptor."""
        start = time.perf_counter()
        valid = valid_returns(np.asarray(cloud), mask)
        if not valid.any():
            raise ObservationError("cannot segment a scan with no finite returns (empty or all-NaN cloud)")
        classes, descriptor = self.segment_points(np.asarray(cloud, dtype=np.float64)[valid], self.sensor_height)
        labels = np.full(len(valid), -1, dtype=np.int8)
        labels[valid] = classes
        return Segmentation(labels, descriptor, {"network": 1000 * (time.perf_counter() - start)})

    def describe(self, cloud: np.ndarray, mask: np.ndarray) -> np.ndarray:
        """The scan's unit descriptor, as ``segment`` gives it."""
        return self.segment(cloud, mask).descriptor

    def segment_points(self, level: np.ndarray, height: float) -> tuple[np.ndarray, np.ndarray]:
        """Classes (int8, one per return) and the unit descriptor of returns ``level`` (N, 3, level sensor frame)
        from a sensor ``height`` m above the floor.

        Returns within ``BODY_RANGE_M`` of the sensor are its own housing, mount or robot (a real scan's
        self-hits: a fifth of one office scan's points lay within 0.13 m): clutter, and kept out of the
        network's input, where a handful of voxels holding them swayed the whole scan's classes."""
        level = np.asarray(level, dtype=np.float64)
        body = np.einsum("ij,ij->i", level, level) < BODY_RANGE_M**2
        if body.all():
            raise ObservationError(f"every return lies within {BODY_RANGE_M} m of the sensor: nothing to segment")
        if body.any():
            classes, descriptor = self.segment_points(level[~body], height)
            labels = np.full(len(level), int(SemanticClass.CLUTTER), dtype=np.int8)
            labels[~body] = classes
            return labels, descriptor
        thinned = cloud_features(level, height, self.model.config.points, self.features)
        self.threads.before()
        start = time.perf_counter()
        with torch.inference_mode():
            net = self.network
            local = net.local_features(torch.from_numpy(thinned.features))
            glob = net.global_feature(local)
            classes = net.logits(local, glob).argmax(dim=1).numpy().astype(np.int8)
            descriptor = net.descriptor_of(glob).numpy().astype(np.float32)
        self.threads.after(time.perf_counter() - start)
        # every voxel takes the class of the nearest voxel the network looked at (in space: in voxel order a
        # floor voxel's neighbour is the ceiling above the column before), every return its voxel's
        seen = thinned.chosen[: min(len(thinned.points), len(thinned.chosen))]
        tree = cKDTree(thinned.points[seen], balanced_tree=False, compact_nodes=False)
        per_voxel = classes[: len(seen)][tree.query(thinned.points)[1]]
        return per_voxel[thinned.voxel_of], descriptor


def load_segmenter(checkpoint: Path, sensor_height: float = 0.5) -> Segmenter | CloudSegmenter:
    """The segmenter that fits the weights: layout-free for ``cloud`` inputs, the grid network otherwise."""
    model, _ = load_checkpoint(checkpoint)
    return CloudSegmenter(checkpoint, sensor_height) if model.config.inputs == "cloud" else Segmenter(checkpoint)
