"""The thesis's segmentation network (section 3.2.2), kept as the yardstick ``bench`` times ours against.

The original PointNet's segmentation form on all 10 000 points of a scan: an input transform (a T-Net
predicting a 3 x 3 matrix), a shared MLP (64, 64), a feature transform (a T-Net predicting 64 x 64), a shared
MLP (64, 128, 1024) and a max pool to the 1024-dimensional global feature; each point's 64 local features
joined with it (1 088) go through the head 512, 256, 128, 4, with batch normalization and ReLU between. About
3.5 M parameters, as the thesis gives. Only its cost is used here (random weights, inference); the shipped
network is ``pointnet.py``.
"""

from __future__ import annotations

import itertools

import torch
from torch import nn


def shared_mlp(widths: tuple[int, ...]) -> nn.Sequential:
    """1 x 1 convolutions over the points with batch normalization and ReLU after each."""
    layers: list[nn.Module] = []
    for a, b in itertools.pairwise(widths):
        layers += [nn.Conv1d(a, b, 1), nn.BatchNorm1d(b), nn.ReLU()]
    return nn.Sequential(*layers)


class TNet(nn.Module):
    """PointNet's transform network: a k x k matrix from the points (identity added)."""

    def __init__(self, k: int) -> None:
        super().__init__()
        self.k = k
        self.features = shared_mlp((k, 64, 128, 1024))
        self.regress = nn.Sequential(
            nn.Linear(1024, 512), nn.BatchNorm1d(512), nn.ReLU(),
            nn.Linear(512, 256), nn.BatchNorm1d(256), nn.ReLU(),
            nn.Linear(256, k * k),
        )  # fmt: skip

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        pooled = self.features(x).amax(dim=2)
        return self.regress(pooled).view(-1, self.k, self.k) + torch.eye(self.k, device=x.device)


class ThesisPointNet(nn.Module):
    """(B, 3, N) points -> (B, 4, N) class scores, the thesis's architecture."""

    def __init__(self, num_classes: int = 4) -> None:
        super().__init__()
        self.input_transform = TNet(3)
        self.local = shared_mlp((3, 64, 64))
        self.feature_transform = TNet(64)
        self.encoder = shared_mlp((64, 64, 128, 1024))
        self.head = nn.Sequential(shared_mlp((1088, 512, 256, 128)), nn.Conv1d(128, num_classes, 1))

    def forward(self, points: torch.Tensor) -> torch.Tensor:
        x = torch.bmm(self.input_transform(points).transpose(1, 2), points)
        local = self.local(x)
        local = torch.bmm(self.feature_transform(local).transpose(1, 2), local)
        pooled = self.encoder(local).amax(dim=2, keepdim=True)
        joined = torch.cat([local, pooled.expand(-1, -1, local.shape[2])], dim=1)
        return self.head(joined)


def parameter_count(model: nn.Module) -> int:
    return sum(p.numel() for p in model.parameters())
