"""Training of the PointNet segmenter and descriptor on the CPU (thesis 3.2.2, table 3.1).

Kept from the thesis: class weights w_c = (max f / f_c)^(1/3) (eq. 3.6) in the cross-entropy, Adam at 1e-3,
batches of 16 scans, the learning rate times 0.7 five times over the run (every 20 of its 100 epochs), the
80/20 split. Changed, because measured better or needed: the input features are heading-invariant so no
random rotation is needed; each batch holds 8 pairs of scans taken within ``positive_radius`` of each other,
and a supervised contrastive loss on the descriptors is added to the cross-entropy so that the global feature
is a place descriptor by training, not by hope.

A smaller network may learn from a trained one (``teacher``): its class probabilities at a temperature are
matched to the teacher's on the same points (knowledge distillation, Hinton, Vinyals and Dean 2015), besides
the labels' cross-entropy.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import asdict, dataclass

import numpy as np
import torch
from scipy.spatial import cKDTree
from torch import nn

from pimm_agents.measurement.perception_quality import iou_per_class
from pimm_agents.perception.point_features import point_features, with_context
from pimm_agents.perception.pointnet import PointNetConfig, PointNetSegmenter, parameter_count
from pimm_agents.perception.segmenter import strided_sample
from pimm_env.errors import PerceptionError
from pimm_env.sim.lidar import Lidar3DConfig, directions_3d
from pimm_env.world.semantics import CLASS_NAMES
from training.cloud_dataset import CloudSet
from training.dataset import ScanSet


@dataclass(frozen=True)
class TrainConfig:
    epochs: int = 40
    batch_pairs: int = 8
    learning_rate: float = 1e-3
    lr_decay: float = 0.7
    lr_decay_times: int = 5
    descriptor_weight: float = 1.0
    temperature: float = 0.1
    positive_radius: float = 2.0
    seed: int = 0
    #: with a teacher: the share of the loss that matches its class probabilities (the rest is the labels'
    #: cross-entropy) and the temperature they are softened at (Hinton et al. 2015's usual 0.5 and 2)
    distill_weight: float = 0.5
    distill_temperature: float = 2.0


def class_weights(labels: np.ndarray, num_classes: int = len(CLASS_NAMES)) -> np.ndarray:
    """Thesis eq. 3.6: w_c = (max f / f_c)^(1/3) from the class frequencies of the returns in ``labels``."""
    counts = np.bincount(labels[labels >= 0].ravel().astype(np.int64), minlength=num_classes).astype(float)
    if np.any(counts == 0):
        missing = [CLASS_NAMES[c] for c in np.flatnonzero(counts == 0)]
        raise PerceptionError(f"the training scans have no points of class(es) {missing}")
    freq = counts / counts.sum()
    return (freq.max() / freq) ** (1 / 3)


def distillation_loss(student: torch.Tensor, teacher: torch.Tensor, temperature: float) -> torch.Tensor:
    """KL divergence of the student's class probabilities from the teacher's, both at ``temperature``, per
    point and times T^2 (so its gradients keep their scale whatever T); logits are (batch, classes, points)."""
    target = nn.functional.log_softmax(teacher / temperature, dim=1)
    guess = nn.functional.log_softmax(student / temperature, dim=1)
    per_point = (target.exp() * (target - guess)).sum(dim=1)
    return per_point.mean() * temperature**2


def check_teacher(teacher: PointNetSegmenter, network: PointNetConfig) -> None:
    """A teacher must read the student's inputs: the same input kind, features and grid context."""
    mine, its = network, teacher.config
    for name in ("inputs", "feature_names", "context_offsets", "num_classes"):
        if getattr(mine, name) != getattr(its, name):
            raise PerceptionError(
                f"the teacher network's {name} {getattr(its, name)!r} differ from the student's "
                f"{getattr(mine, name)!r}: a teacher must read the same inputs"
            )


def contrastive_loss(descriptors: torch.Tensor, positions: torch.Tensor, radius: float, temperature: float):
    """Supervised contrastive loss: each scan's descriptor should be nearest those taken within ``radius``."""
    sim = descriptors @ descriptors.T / temperature
    eye = torch.eye(len(descriptors), dtype=torch.bool)
    sim = sim.masked_fill(eye, float("-inf"))
    positive = (torch.cdist(positions, positions) < radius) & ~eye
    log_prob = sim - torch.logsumexp(sim, dim=1, keepdim=True)
    has = positive.any(dim=1)
    per_anchor = -(log_prob.masked_fill(~positive, 0).sum(1) / positive.sum(1).clamp(min=1))
    return per_anchor[has].mean()


class ScanSampler:
    """Network inputs for scans of a :class:`ScanSet`: features of ``points`` strided returns, and labels."""

    def __init__(self, scans: ScanSet, network: PointNetConfig, lidar: Lidar3DConfig = Lidar3DConfig()) -> None:
        scans.require_lidar(lidar.layers, lidar.points_per_layer)
        self.scans = scans
        self.network = network
        self.lidar = lidar
        self.directions = directions_3d(lidar).astype(np.float32)
        self._cache: dict[int, tuple[np.ndarray, np.ndarray]] = {}  # float16 features and returns per scan

    def _features(self, i: int) -> tuple[np.ndarray, np.ndarray]:
        if i not in self._cache:
            cloud, mask = self.scans.cloud(i, self.directions)
            features = point_features(cloud, mask, self.lidar.layers, self.lidar.points_per_layer)
            self._cache[i] = features.astype(np.float16), np.flatnonzero(mask)
        return self._cache[i]

    def sample(self, i: int, offset: int) -> tuple[np.ndarray, np.ndarray]:
        features, valid_index = self._features(i)
        chosen = valid_index[strided_sample(valid_index, self.network.points, offset)]
        lidar = self.lidar
        inputs = with_context(features, chosen, lidar.layers, lidar.points_per_layer, self.network.context_offsets)
        return inputs.T.astype(np.float32), self.scans.labels[i].reshape(-1)[chosen]

    def batch(self, indices: np.ndarray, rng: np.random.Generator) -> tuple[torch.Tensor, torch.Tensor]:
        feats, labels = zip(*(self.sample(int(i), int(rng.integers(0, 1 << 16))) for i in indices), strict=True)
        return torch.from_numpy(np.stack(feats)), torch.from_numpy(np.stack(labels).astype(np.int64))


class CloudSampler:
    """Network inputs for scans of a :class:`CloudSet` (layout-free features, ``cloud_features.py``). A sample
    with a non-zero ``offset`` is also jittered as the floor fit errs at run time: the height by up to 3 cm,
    the levelling by up to 0.5 deg."""

    def __init__(self, clouds: CloudSet, network: PointNetConfig) -> None:
        if network.inputs != "cloud":
            raise PerceptionError(f"a cloud dataset trains a network of 'cloud' inputs, not {network.inputs!r}")
        self.scans = clouds
        self.network = network

    def sample(self, i: int, offset: int) -> tuple[np.ndarray, np.ndarray]:
        from pimm_agents.perception.cloud_features import cloud_features
        from pimm_env.geometry import rotation_onto_z

        points, labels = self.scans.scan(i)
        height = float(self.scans.heights[i])
        if offset:
            rng = np.random.default_rng(offset)
            height += rng.uniform(-0.03, 0.03)
            lean = np.radians(0.5) * rng.uniform(-1, 1, 2)
            points = points @ rotation_onto_z(np.array([lean[0], lean[1], 1.0])).T
        thinned = cloud_features(points, height, self.network.points, offset=offset)
        # the stored points are voxels already, but stored as float16 a few cross into a neighbour voxel and
        # merge: each voxel takes its stored points' label (the last), as voxel_of says, never by position
        voxel_labels = np.empty(len(thinned.points), dtype=labels.dtype)
        voxel_labels[thinned.voxel_of] = labels
        return thinned.features.T.astype(np.float32), voxel_labels[thinned.chosen]

    def batch(self, indices: np.ndarray, rng: np.random.Generator) -> tuple[torch.Tensor, torch.Tensor]:
        feats, labels = zip(*(self.sample(int(i), int(rng.integers(1, 1 << 16))) for i in indices), strict=True)
        return torch.from_numpy(np.stack(feats)), torch.from_numpy(np.stack(labels).astype(np.int64))


def make_sampler(scans: ScanSet | CloudSet, network: PointNetConfig) -> ScanSampler | CloudSampler:
    return CloudSampler(scans, network) if isinstance(scans, CloudSet) else ScanSampler(scans, network)


def pair_batches(positions: np.ndarray, pairs: int, radius: float, rng: np.random.Generator) -> list[np.ndarray]:
    """One epoch of batches, each of ``pairs`` anchors and for each a scan within ``radius`` (or itself)."""
    tree = cKDTree(positions)
    anchors = rng.permutation(len(positions))
    batches = []
    for start in range(0, len(anchors) - pairs + 1, 2 * pairs):
        chosen = anchors[start : start + pairs]
        partners = []
        for a in chosen:
            near = [j for j in tree.query_ball_point(positions[a], radius * 0.75) if j != a]
            partners.append(rng.choice(near) if near else a)
        batches.append(np.concatenate([chosen, partners]))
    return batches


def evaluate_segmentation(model: PointNetSegmenter, sampler: ScanSampler | CloudSampler, batch: int = 32) -> np.ndarray:
    """Per-class IoU over the network's sampled points of every scan in ``sampler`` (offset 0)."""
    model.eval()
    predicted, truth = [], []
    with torch.inference_mode():
        for start in range(0, len(sampler.scans), batch):
            idx = np.arange(start, min(start + batch, len(sampler.scans)))
            inputs, labels = zip(*(sampler.sample(int(i), 0) for i in idx), strict=True)
            logits, _ = model(torch.from_numpy(np.stack(inputs)))
            predicted.append(logits.argmax(1).numpy())
            truth.append(np.stack(labels))
    return iou_per_class(np.concatenate(predicted).ravel(), np.concatenate(truth).ravel())


def train(
    train_set: ScanSet | CloudSet,
    validation_set: ScanSet | CloudSet,
    config: TrainConfig = TrainConfig(),
    network: PointNetConfig = PointNetConfig(),
    on_epoch: Callable[[dict], None] | None = None,
    progress: bool = True,
    initial: PointNetSegmenter | None = None,
    teacher: PointNetSegmenter | None = None,
) -> tuple[PointNetSegmenter, list[dict]]:
    """Train from scratch (or go on from ``initial``), learning from ``teacher``'s class probabilities when
    one is given; returns the model (eval mode) and one record of metrics per epoch."""
    from tqdm import tqdm

    torch.manual_seed(config.seed)
    rng = np.random.default_rng(config.seed)
    if teacher is not None:
        check_teacher(teacher, network)
        teacher = teacher.eval()
    model = PointNetSegmenter(network)
    if initial is not None:
        model.load_state_dict(initial.state_dict())
    weights = torch.tensor(class_weights(train_set.labels), dtype=torch.float32)
    criterion = nn.CrossEntropyLoss(weight=weights)
    optimizer = torch.optim.Adam(model.parameters(), lr=config.learning_rate)
    step = max(1, config.epochs // config.lr_decay_times)
    scheduler = torch.optim.lr_scheduler.StepLR(optimizer, step_size=step, gamma=config.lr_decay)
    sampler = make_sampler(train_set, network)
    val_sampler = make_sampler(validation_set, network)
    positions = train_set.poses[:, :2]
    history = []
    for epoch in range(1, config.epochs + 1):
        model.train()
        start = time.perf_counter()
        batches = pair_batches(positions, config.batch_pairs, config.positive_radius, rng)
        totals = {"loss": 0.0, "ce": 0.0, "descriptor": 0.0, "distillation": 0.0, "correct": 0, "points": 0}
        bar = tqdm(batches, desc=f"epoch {epoch}/{config.epochs}", disable=not progress, unit="batch", leave=False)
        for indices in bar:
            feats, labels = sampler.batch(indices, rng)
            logits, descriptors = model(feats)
            ce = criterion(logits, labels)
            pos = torch.from_numpy(positions[indices]).float()
            metric = contrastive_loss(descriptors, pos, config.positive_radius, config.temperature)
            loss = config.descriptor_weight * metric
            if teacher is None:
                loss = loss + ce
            else:  # the labels' share and the teacher's
                with torch.no_grad():
                    taught = teacher(feats)[0]
                distilled = distillation_loss(logits, taught, config.distill_temperature)
                loss = loss + (1 - config.distill_weight) * ce + config.distill_weight * distilled
                totals["distillation"] += distilled.item()
            optimizer.zero_grad()
            loss.backward()
            optimizer.step()
            totals["loss"] += loss.item()
            totals["ce"] += ce.item()
            totals["descriptor"] += metric.item()
            totals["correct"] += int((logits.argmax(1) == labels).sum())
            totals["points"] += labels.numel()
            bar.set_postfix(loss=f"{loss.item():.3f}")
        scheduler.step()
        iou = evaluate_segmentation(model, val_sampler)
        record = {
            "epoch": epoch,
            "seconds": time.perf_counter() - start,
            "lr": optimizer.param_groups[0]["lr"],
            "loss": totals["loss"] / len(batches),
            "cross_entropy": totals["ce"] / len(batches),
            "descriptor_loss": totals["descriptor"] / len(batches),
            "distillation_loss": totals["distillation"] / len(batches),
            "train_accuracy": totals["correct"] / totals["points"],
            "test_iou": dict(zip(CLASS_NAMES, [float(v) for v in iou], strict=True)),
            "test_miou": float(np.nanmean(iou)),
        }
        history.append(record)
        if on_epoch is not None:
            on_epoch(record)
    model.eval()
    return model, history


def describe(config: TrainConfig, network: PointNetConfig, model: PointNetSegmenter) -> dict:
    return {"train": asdict(config), "network": asdict(network), "parameters": parameter_count(model)}
