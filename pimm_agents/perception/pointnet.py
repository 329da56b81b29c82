"""The segmentation network: a PointNet with a per-point 4-class head and a global place descriptor.

Thesis 3.2.2 in a CPU-sized form. A shared per-point MLP gives local features; a second shared MLP and a max
pool give the global feature; each point's class comes from its local feature concatenated with the global
one. The descriptor is a linear projection of the global feature, L2-normalized, trained with a metric loss
so that scans taken close together have close descriptors. The thesis's input transform and feature transform
are left out: the input features are already invariant to the robot's heading (``point_features.py``).
"""

from __future__ import annotations

import itertools
from dataclasses import asdict, dataclass, fields
from pathlib import Path
from typing import Any

import torch
from torch import nn

from pimm_agents.perception.cloud_features import CLOUD_FEATURE_SCALE, CLOUD_FEATURES, CLOUD_NUM_FEATURES
from pimm_agents.perception.point_features import CONTEXT_OFFSETS, FEATURES, NUM_FEATURES
from pimm_agents.perception.records import WEIGHTS, read_record, record_path, write_record
from pimm_env.errors import MissingFileError, PerceptionError
from pimm_env.world.semantics import CLASS_NAMES

CHECKPOINT_FORMAT = "pimm-pointnet/1"
INPUT_KINDS = ("grid", "cloud")
WEIGHTS_DTYPE = "float32"
#: Rough scale of each input feature, so that the first layer sees numbers near 1.
FEATURE_SCALE = {
    "height": 4.0,
    "horizontal_range": 10.0,
    "normal_z": 1.0,
    "normal_radial": 1.0,
    "column_depth": 1.0,
    "scan_height": 1.0,
    "roughness": 0.05,
    "below_column_top": 4.0,
    "before_column_end": 5.0,
}


@dataclass(frozen=True)
class PointNetConfig:
    """Widths of the network and the number of points it looks at per scan."""

    points: int = 2048
    local_widths: tuple[int, ...] = (64, 64)
    global_widths: tuple[int, ...] = (128, 256)
    head_widths: tuple[int, ...] = (128, 64)
    descriptor_dim: int = 128
    num_classes: int = len(CLASS_NAMES)
    context_offsets: tuple[tuple[int, int], ...] = CONTEXT_OFFSETS
    #: "grid": the organized scan's features and grid context (``point_features.py``); "cloud": the
    #: layout-free features of any point set (``cloud_features.py``; context_offsets unused)
    inputs: str = "grid"

    def __post_init__(self) -> None:
        if self.inputs not in INPUT_KINDS:
            raise PerceptionError(f"PointNetConfig.inputs {self.inputs!r}: valid kinds are {INPUT_KINDS}")

    @property
    def input_channels(self) -> int:
        if self.inputs == "cloud":
            return CLOUD_NUM_FEATURES
        return NUM_FEATURES * (1 + len(self.context_offsets))

    @property
    def feature_names(self) -> tuple[str, ...]:
        return CLOUD_FEATURES if self.inputs == "cloud" else FEATURES

    def feature_scales(self) -> list[float]:
        if self.inputs == "cloud":
            return list(CLOUD_FEATURE_SCALE)
        return [FEATURE_SCALE[name] for name in FEATURES] * (1 + len(self.context_offsets))

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> PointNetConfig:
        known = {f.name for f in fields(cls)}
        unknown = set(data) - known
        if unknown:
            raise PerceptionError(f"unknown PointNetConfig field(s) {sorted(unknown)}; valid: {sorted(known)}")
        values = {k: tuple(v) if isinstance(v, list) else v for k, v in data.items()}
        if "context_offsets" in values:
            values["context_offsets"] = tuple(tuple(o) for o in values["context_offsets"])
        return cls(**values)  # type: ignore[arg-type]  # field types were checked by name above


def _mlp(widths: list[int]) -> nn.Sequential:
    layers: list[nn.Module] = []
    for a, b in itertools.pairwise(widths):
        layers += [nn.Conv1d(a, b, 1, bias=False), nn.BatchNorm1d(b), nn.ReLU(inplace=True)]
    return nn.Sequential(*layers)


class PointNetSegmenter(nn.Module):
    """Input (B, input_channels, N): each point's features and its grid neighbours'.

    Output: per-point logits (B, classes, N) and unit descriptors (B, descriptor_dim).
    """

    feature_scale: torch.Tensor  # a buffer: (1, channels, 1)

    def __init__(self, config: PointNetConfig = PointNetConfig()) -> None:
        super().__init__()
        self.config = config
        scale = torch.tensor([1.0 / v for v in config.feature_scales()])
        self.register_buffer("feature_scale", scale.view(1, -1, 1))
        self.local = _mlp([config.input_channels, *config.local_widths])
        self.globe = _mlp([config.local_widths[-1], *config.global_widths])
        # the head's first layer on [local, global] is split in two: the global half is computed once per scan
        first = config.head_widths[0]
        self.head_local = nn.Conv1d(config.local_widths[-1], first, 1, bias=False)
        self.head_global = nn.Linear(config.global_widths[-1], first, bias=False)
        self.head = nn.Sequential(
            nn.BatchNorm1d(first),
            nn.ReLU(inplace=True),
            _mlp(list(config.head_widths)),
            nn.Conv1d(config.head_widths[-1], config.num_classes, 1),
        )
        self.descriptor = nn.Linear(config.global_widths[-1], config.descriptor_dim)

    def forward(self, features: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        local = self.local(features * self.feature_scale)
        glob = self.globe(local).amax(dim=2)
        per_point = self.head_local(local) + self.head_global(glob).unsqueeze(2)
        descriptor = nn.functional.normalize(self.descriptor(glob), dim=1)
        return self.head(per_point), descriptor


def _fold(conv_weight: torch.Tensor, bn: nn.BatchNorm1d) -> tuple[torch.Tensor, torch.Tensor]:
    """A bias-free layer followed by eval-mode batch norm, as one affine map (W, b)."""
    if bn.running_var is None or bn.running_mean is None:
        raise PerceptionError("batch norm without running statistics cannot be folded")
    scale = bn.weight / torch.sqrt(bn.running_var + bn.eps)
    return conv_weight * scale[:, None], bn.bias - bn.running_mean * scale


def _folded_mlp(mlp: nn.Sequential) -> list[tuple[torch.Tensor, torch.Tensor]]:
    convs = [m for m in mlp if isinstance(m, nn.Conv1d)]
    norms = [m for m in mlp if isinstance(m, nn.BatchNorm1d)]
    return [_fold(c.weight[:, :, 0], n) for c, n in zip(convs, norms, strict=True)]


class FusedPointNet:
    """The trained network for inference on one scan: batch norms and the input scaling folded into the
    layers, points as rows so that every layer is one matrix product. Same outputs as the module."""

    def __init__(self, model: PointNetSegmenter) -> None:
        model = model.eval()
        with torch.no_grad():
            self.local = _folded_mlp(model.local)
            w0, b0 = self.local[0]
            self.local[0] = (w0 * model.feature_scale.view(1, -1), b0)
            self.globe = _folded_mlp(model.globe)
            head_norm, _, head_mlp, classify = model.head
            assert isinstance(head_norm, nn.BatchNorm1d) and isinstance(head_mlp, nn.Sequential)
            assert isinstance(classify, nn.Conv1d) and classify.bias is not None
            head_local, self.head_bias = _fold(model.head_local.weight[:, :, 0], head_norm)
            self.head_local = head_local
            self.head_global, _ = _fold(model.head_global.weight, head_norm)
            self.head = _folded_mlp(head_mlp)
            self.classify = (classify.weight[:, :, 0], classify.bias)
            self.descriptor = (model.descriptor.weight, model.descriptor.bias)
            for name in ("local", "globe", "head"):
                setattr(self, name, [(w.T.contiguous(), b) for w, b in getattr(self, name)])

    @staticmethod
    def _run(layers: list[tuple[torch.Tensor, torch.Tensor]], x: torch.Tensor) -> torch.Tensor:
        for w, b in layers:
            x = torch.relu_(torch.addmm(b, x, w))
        return x

    def local_features(self, points: torch.Tensor) -> torch.Tensor:
        """``points`` (N, input_channels) -> each point's local feature (N, local width)."""
        return self._run(self.local, points)

    def global_feature(self, local: torch.Tensor) -> torch.Tensor:
        """The scan's global feature: the max over points of the global MLP of their local features."""
        return self._run(self.globe, local).amax(dim=0)

    def logits(self, local: torch.Tensor, glob: torch.Tensor) -> torch.Tensor:
        """Class logits (N, classes) of points with local features ``local`` in a scan with feature ``glob``;
        the points need not be those the global feature was pooled from."""
        h = torch.relu_(torch.addmm(self.head_global @ glob + self.head_bias, local, self.head_local.T))
        return torch.addmm(self.classify[1], self._run(self.head, h), self.classify[0].T)

    def descriptor_of(self, glob: torch.Tensor) -> torch.Tensor:
        return nn.functional.normalize(self.descriptor[0] @ glob + self.descriptor[1], dim=0)

    def __call__(self, points: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """``points`` (N, input_channels) -> logits (N, classes), unit descriptor (descriptor_dim,)."""
        local = self.local_features(points)
        glob = self.global_feature(local)
        return self.logits(local, glob), self.descriptor_of(glob)


def parameter_count(model: nn.Module) -> int:
    return sum(p.numel() for p in model.parameters())


def save_checkpoint(model: PointNetSegmenter, path: Path, training: dict[str, Any]) -> dict[str, Any]:
    """Weights, the network's config and how they were made (command, data, per-epoch metrics), and the
    file's record beside it (``records.py``: checksum, format, dtype and parameter count); returns the record."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    torch.save(
        {
            "format": CHECKPOINT_FORMAT,
            "config": asdict(model.config),
            "features": list(model.config.feature_names),
            "classes": list(CLASS_NAMES),
            "state_dict": model.state_dict(),
            "training": training,
        },
        path,
    )
    shape = {"dtype": WEIGHTS_DTYPE, "parameters": parameter_count(model)}
    return write_record(path, WEIGHTS, CHECKPOINT_FORMAT, **{**training, **shape})


def _check_dtype(path: Path, state: dict[str, Any], record: dict[str, Any], remake: str) -> None:
    """Every weight of the dtype the record names (batch norms' integer step counters aside)."""
    dtype = record.get("dtype", WEIGHTS_DTYPE)
    for name, value in state.items():
        counter = name.endswith("num_batches_tracked")
        if not isinstance(value, torch.Tensor) or (not counter and str(value.dtype) != f"torch.{dtype}"):
            found = value.dtype if isinstance(value, torch.Tensor) else type(value).__name__
            raise PerceptionError(f"{path}: tensor {name!r} is {found}, the record says {dtype}; {remake}")


def load_checkpoint(path: Path) -> tuple[PointNetSegmenter, dict[str, Any]]:
    """The model (in eval mode) and its training record; a missing, corrupt or mismatched file is named."""
    path = Path(path)
    if not path.is_file():
        raise MissingFileError(
            f"{path}: no PointNet checkpoint; train one with `python -m training rebuild --world <world>`"
        )
    remake = "restore the file with its record, or retrain (`python -m training train`)"
    record = read_record(path, WEIGHTS, CHECKPOINT_FORMAT, remake)
    try:
        data = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as err:  # torch raises many types for a damaged file
        raise PerceptionError(f"{path}: not a readable PointNet checkpoint ({type(err).__name__}: {err})") from None
    if not isinstance(data, dict) or data.get("format") != CHECKPOINT_FORMAT:
        found = data.get("format") if isinstance(data, dict) else type(data).__name__
        raise PerceptionError(f"{path}: checkpoint format {found!r}, expected {CHECKPOINT_FORMAT!r}")
    config = PointNetConfig.from_dict(data["config"])
    if list(data.get("features", [])) != list(config.feature_names):
        raise PerceptionError(
            f"{path}: checkpoint was trained on features {data.get('features')}, this code makes "
            f"{config.feature_names} for {config.inputs!r} inputs"
        )
    if list(data.get("classes", [])) != list(CLASS_NAMES):
        raise PerceptionError(f"{path}: checkpoint classes {data.get('classes')} differ from {CLASS_NAMES}")
    _check_dtype(path, data.get("state_dict", {}), record, remake)
    model = PointNetSegmenter(config)
    try:
        model.load_state_dict(data["state_dict"])
    except RuntimeError as err:
        raise PerceptionError(f"{path}: weights do not fit the network described by its config ({err})") from None
    if "parameters" in record and record["parameters"] != parameter_count(model):
        raise PerceptionError(
            f"{path}: {parameter_count(model)} parameters, the record {record_path(path).name} says "
            f"{record['parameters']}; {remake}"
        )
    model.eval()
    return model, {**data.get("training", {}), "sha256": record["sha256"]}
