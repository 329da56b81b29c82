"""Segmentation quality of a checkpoint on a stored scan set, with every return labelled the way the
localizer labels it (:class:`~pimm_agents.perception.segmenter.Segmenter`), not only the points the network samples."""

from __future__ import annotations

import numpy as np

from pimm_agents.measurement.perception_quality import confusion_matrix
from pimm_agents.perception.segmenter import Segmenter
from pimm_env.errors import PerceptionError
from pimm_env.sim.lidar import Lidar3DConfig, directions_3d
from training.dataset import ScanSet


def scan_set_confusion(
    segmenter: Segmenter, scans: ScanSet, lidar: Lidar3DConfig = Lidar3DConfig(), progress: bool = True
) -> np.ndarray:
    """Confusion counts (true class, predicted class) over every labelled return of every scan."""
    from tqdm import tqdm

    scans.require_lidar(lidar.layers, lidar.points_per_layer)
    directions = directions_3d(lidar).astype(np.float32)
    total = None
    for i in tqdm(range(len(scans)), desc="validation scans", unit="scan", disable=not progress):
        cloud, mask = scans.cloud(i, directions)
        predicted = segmenter.segment(cloud, mask).labels
        truth = np.where(mask, scans.labels[i].reshape(-1), -1)
        counts = confusion_matrix(predicted, truth)
        total = counts if total is None else total + counts
    if total is None:
        raise PerceptionError("the scan set is empty")
    return total
