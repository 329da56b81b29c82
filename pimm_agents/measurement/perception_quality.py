"""How good perception is on fresh scans: segmentation IoU (thesis table 3.2), retrieval errors (table 3.4)
and the corner detector on true and on predicted labels. ``evaluate.py perception`` prints this."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np

from pimm_agents.measurement.corner_quality import FreshScan, corner_stats
from pimm_agents.perception.fingerprint_map import FingerprintMap, Retrieval
from pimm_agents.perception.segmenter import CloudSegmenter, Segmenter
from pimm_agents.results.figures import plot_perception
from pimm_env.errors import ResultsError
from pimm_env.mapping.corner_map import CornerMap
from pimm_env.mapping.occupancy import OccupancyGrid
from pimm_env.world.semantics import CLASS_NAMES

CORNER_KEYS = ("precision", "recall", "median_position_error_m", "median_orientation_error_deg")


def confusion_matrix(predicted: np.ndarray, truth: np.ndarray, num_classes: int = len(CLASS_NAMES)) -> np.ndarray:
    """Counts (true class, predicted class) over the points with a true label."""
    keep = truth >= 0
    p, t = predicted[keep].astype(np.int64), truth[keep].astype(np.int64)
    if np.any((p < 0) | (p >= num_classes)):
        raise ResultsError(f"predicted labels outside 0..{num_classes - 1} on points that have a true label")
    return np.bincount(t * num_classes + p, minlength=num_classes**2).reshape(num_classes, num_classes)


def iou_from_confusion(confusion: np.ndarray) -> np.ndarray:
    """Intersection over union of each class (NaN for a class neither present nor predicted)."""
    inter = np.diag(confusion).astype(float)
    union = confusion.sum(0) + confusion.sum(1) - inter
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(union > 0, inter / union, np.nan)


def iou_per_class(predicted: np.ndarray, truth: np.ndarray, num_classes: int = len(CLASS_NAMES)) -> np.ndarray:
    """Intersection over union of each class over the points with a true label (NaN for a class never seen)."""
    return iou_from_confusion(confusion_matrix(predicted, truth, num_classes))


def segmentation_scores(confusion: np.ndarray, scans: int) -> dict[str, Any]:
    """Per-class IoU (None for a class neither present nor predicted), their mean and the scan count."""
    iou = iou_from_confusion(confusion)
    return {
        "miou": float(np.nanmean(iou)),
        "iou": {name: None if np.isnan(v) else float(v) for name, v in zip(CLASS_NAMES, iou, strict=True)},
        "scans": scans,
    }


def retrieval_errors(retrievals: list[Retrieval], truths: np.ndarray) -> dict[str, float]:
    """Table 3.4's metrics: mean, mean-min and mean-max distance (m) from the true position to the k retrieved
    ones; recall@k within 2 m (share of queries with a retrieved position within 2 m); the share of queries
    whose suggestions pass the spread check."""
    if len(retrievals) == 0:
        raise ResultsError("no retrievals to score")
    dists = np.array([np.linalg.norm(r.positions - t[:2], axis=1) for r, t in zip(retrievals, truths, strict=True)])
    return {
        "recall_at_3_2m": float(np.mean(dists.min(axis=1) <= 2.0)),
        "mean_error_m": float(dists.mean()),
        "mean_min_error_m": float(dists.min(axis=1).mean()),
        "mean_max_error_m": float(dists.max(axis=1).mean()),
        "consistent_share": float(np.mean([r.consistent for r in retrievals])),
        "queries": len(retrievals),
    }


def _corner_dict(stats) -> dict[str, float | None]:
    return {k: asdict(stats)[k] for k in CORNER_KEYS}


def perception_report(
    scans: list[FreshScan],
    corners: CornerMap,
    segmenter: Segmenter | CloudSegmenter | None = None,
    fingerprints: FingerprintMap | None = None,
    figure: Path | None = None,
    occupancy: OccupancyGrid | None = None,
) -> dict[str, Any]:
    """The ``evaluate.py perception`` JSON; parts whose component is missing are left out. With ``figure``,
    also a picture of the retrievals on ``occupancy`` and of the segmentation's confusion matrix."""
    report: dict[str, Any] = {
        "corners": {"true_labels": _corner_dict(corner_stats([s.corner_input() for s in scans], corners))}
    }
    if segmenter is None:
        return report
    segmented = [segmenter.segment(s.cloud, s.mask) for s in scans]
    confusion = confusion_matrix(
        np.concatenate([g.labels[s.mask] for g, s in zip(segmented, scans, strict=True)]),
        np.concatenate([s.labels[s.mask] for s in scans]),
    )
    report["segmentation"] = segmentation_scores(confusion, len(scans))
    predicted = [s.corner_input(g.labels) for g, s in zip(segmented, scans, strict=True)]
    report["corners"]["predicted_labels"] = _corner_dict(corner_stats(predicted, corners))
    retrievals: list[Retrieval] = []
    truths = np.array([s.pose for s in scans])
    if fingerprints is not None:
        retrievals = [fingerprints.query(g.descriptor) for g in segmented]
        areas = np.array([s.area for s in scans])
        report["retrieval"] = retrieval_errors(retrievals, truths)
        report["retrieval"]["per_area"] = {
            area: retrieval_errors(
                [r for r, a in zip(retrievals, areas, strict=True) if a == area], truths[areas == area]
            )
            for area in sorted(set(areas) - {""})
        }
    if figure is not None and occupancy is not None:
        plot_perception(occupancy, confusion, retrievals, truths, figure)
    return report


def measure_world(
    world: str, scans: int, seed: int, figure: Path | None = None, warn: Callable[[str], None] = print
) -> dict[str, Any]:
    """``evaluate.py perception``: perception of ``world`` on ``scans`` fresh scans drawn with ``seed``, with the
    world's own network and fingerprint map; ``warn`` hears which parts are left out because a file is missing."""
    from pimm_agents.measurement.corner_quality import collect_scans
    from pimm_agents.perception.files import checkpoint_path, fingerprint_path, load_perception
    from pimm_agents.perception.segmenter import load_segmenter
    from pimm_env.mapping.derived_maps import ensure_derived_maps
    from pimm_env.world.files import load_world

    loaded = load_world(world)
    maps = ensure_derived_maps(loaded)
    segmenter = fingerprints = None
    if not checkpoint_path(loaded).exists():
        warn(f"{checkpoint_path(loaded)} is missing: only the corner detector on true labels is measured")
    elif not fingerprint_path(loaded).exists():
        warn(f"{fingerprint_path(loaded)} is missing (python evaluate.py world prepare {world}): no retrieval")
        segmenter = load_segmenter(checkpoint_path(loaded))
    else:
        segmenter, fingerprints = load_perception(loaded)
    collected = collect_scans(world, scans, seed)
    return perception_report(collected, maps.corners, segmenter, fingerprints, figure, maps.occupancy)
