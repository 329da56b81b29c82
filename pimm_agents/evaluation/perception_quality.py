"""How good perception is on fresh scans: segmentation IoU (thesis table 3.2), retrieval errors (table 3.4)
and the corner detector on true and on predicted labels. ``evaluate.py perception`` prints this."""

from __future__ import annotations

from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np

from pimm_agents.evaluation.corner_quality import FreshScan, corner_stats
from pimm_agents.perception.fingerprint_map import FingerprintMap, Retrieval
from pimm_agents.perception.segmenter import Segmenter
from pimm_env.mapping.corner_map import CornerMap
from pimm_env.mapping.occupancy import OccupancyGrid
from pimm_env.world.semantics import CLASS_NAMES

#: Thesis table 3.2 (segmentation) and table 3.4 (retrieval, on its own training scans, k = 5).
THESIS_IOU = {"floor": 0.930, "ceiling": 0.648, "wall": 0.619, "clutter": 0.483, "mean": 0.69}
THESIS_RETRIEVAL = {
    "A": (1.69, 0.28, 3.54),
    "B": (1.06, 0.10, 2.49),
    "C": (2.88, 0.42, 6.14),
    "total": (1.87, 0.27, 4.01),
}
CORNER_KEYS = ("precision", "recall", "median_position_error_m", "median_orientation_error_deg")


def confusion_matrix(predicted: np.ndarray, truth: np.ndarray, num_classes: int = len(CLASS_NAMES)) -> np.ndarray:
    """Counts (true class, predicted class) over the points with a true label."""
    keep = truth >= 0
    p, t = predicted[keep].astype(np.int64), truth[keep].astype(np.int64)
    if np.any((p < 0) | (p >= num_classes)):
        raise ValueError(f"predicted labels outside 0..{num_classes - 1} on points that have a true label")
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


def format_segmentation(scores: dict[str, Any], what: str) -> list[str]:
    """The IoU table of :func:`segmentation_scores`, with thesis table 3.2 beside it."""
    lines = [f"{'segmentation IoU, ' + what:<40}ours   thesis (table 3.2)"]
    for name in ("floor", "ceiling", "wall", "clutter"):
        lines.append(f"  {name:<38}{_num(scores['iou'][name])}   {THESIS_IOU[name]:.3f}")
    lines.append(f"  {'mean':<38}{_num(scores['miou'])}   {THESIS_IOU['mean']:.3f}")
    return lines


def retrieval_errors(retrievals: list[Retrieval], truths: np.ndarray) -> dict[str, float]:
    """Table 3.4's metrics: mean, mean-min and mean-max distance (m) from the true position to the k retrieved
    ones; recall@k within 2 m (share of queries with a retrieved position within 2 m); the share of queries
    whose suggestions pass the spread check."""
    if len(retrievals) == 0:
        raise ValueError("no retrievals to score")
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
    segmenter: Segmenter | None = None,
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


def plot_perception(
    occupancy: OccupancyGrid, confusion: np.ndarray, retrievals: list[Retrieval], truths: np.ndarray, path: Path
) -> Path:
    """Left: each query's true position joined to its nearest retrieved one (green within 2 m, red beyond).
    Right: the confusion matrix, each row normalized to the true class's returns."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from pimm_env.envs.render import show_map

    fig, (ax_map, ax_conf) = plt.subplots(1, 2, figsize=(15, 5.5), gridspec_kw={"width_ratios": [1.6, 1]})
    show_map(ax_map, occupancy)
    for retrieval, truth in zip(retrievals, truths, strict=True):
        errors = np.linalg.norm(retrieval.positions - truth[:2], axis=1)
        best = retrieval.positions[int(np.argmin(errors))]
        color = "tab:green" if errors.min() <= 2.0 else "tab:red"
        ax_map.plot([truth[0], best[0]], [truth[1], best[1]], "-", color=color, lw=1.2)
        ax_map.plot(*truth[:2], "o", color=color, ms=3)
    from matplotlib.lines import Line2D

    ax_map.legend(
        handles=[
            Line2D([], [], color="tab:green", marker="o", ms=3, label="nearest suggestion within 2 m"),
            Line2D([], [], color="tab:red", marker="o", ms=3, label="all suggestions over 2 m away"),
        ],
        loc="upper right",
        fontsize=8,
        title="scan position -> nearest of k",
        title_fontsize=8,
    )
    ax_map.set_title(f"fingerprint retrieval: {len(retrievals)} fresh scans")
    ax_map.set_xlabel("x (m)")
    ax_map.set_ylabel("y (m)")
    shares = confusion / np.maximum(confusion.sum(axis=1, keepdims=True), 1)
    ax_conf.imshow(shares, cmap="Blues", vmin=0, vmax=1)
    for (i, j), v in np.ndenumerate(shares):
        ax_conf.text(j, i, f"{v:.2f}", ha="center", va="center", color="white" if v > 0.5 else "black")
    ax_conf.set_xticks(range(len(CLASS_NAMES)), CLASS_NAMES)
    ax_conf.set_yticks(range(len(CLASS_NAMES)), CLASS_NAMES)
    ax_conf.set_xlabel("predicted")
    ax_conf.set_ylabel("true")
    ax_conf.set_title("segmentation: share of each true class's returns")
    fig.tight_layout()
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return Path(path)


def _num(value: float | None, fmt: str = ".3f") -> str:
    return "-" if value is None else format(value, fmt)


def format_perception(report: dict[str, Any]) -> str:
    """Readable tables of a :func:`perception_report`, with the thesis's figures beside ours."""
    lines = []
    if "segmentation" in report:
        seg = report["segmentation"]
        lines += [*format_segmentation(seg, f"{seg['scans']} fresh scans"), ""]
    if "retrieval" in report:
        ret = report["retrieval"]
        lines.append(
            "retrieval (k = 3)      queries  recall@3<2m  mean  mean-min  mean-max   thesis (k = 5, seen scans)"
        )
        rows = [*ret["per_area"].items(), ("total", ret)]
        for area, r in rows:
            thesis = THESIS_RETRIEVAL.get(area)
            ref = " / ".join(f"{v:.2f}" for v in thesis) if thesis else "-"
            lines.append(
                f"  {area:<20}{r['queries']:>7}  {r['recall_at_3_2m']:>11.3f}  {r['mean_error_m']:>4.2f}  "
                f"{r['mean_min_error_m']:>8.2f}  {r['mean_max_error_m']:>8.2f}   {ref}"
            )
        lines += [f"  suggestions passing the 10 m spread check: {ret['consistent_share']:.3f}", ""]
    headers = ("precision", "recall", "median pos. err m", "median orient. err deg")
    lines.append("corners                    " + "  ".join(f"{h:>{max(12, len(h))}}" for h in headers))
    for which, stats in report["corners"].items():
        lines.append(
            f"  {which:<24} "
            + "  ".join(f"{_num(stats[k]):>{max(12, len(h))}}" for k, h in zip(CORNER_KEYS, headers, strict=True))
        )
    return "\n".join(lines)
