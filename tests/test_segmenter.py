import numpy as np
import pytest
import torch

from pimm_agents.pointnet import PointNetConfig, PointNetSegmenter, load_checkpoint, save_checkpoint
from pimm_agents.segmenter import Segmenter, nearest_sampled, strided_sample

SMALL = PointNetConfig(points=256, local_widths=(8, 16), global_widths=(16, 32), head_widths=(16, 8), descriptor_dim=6)


@pytest.fixture
def checkpoint(tmp_path):
    torch.manual_seed(0)
    path = tmp_path / "pointnet.pt"
    save_checkpoint(PointNetSegmenter(SMALL).eval(), path, {"command": "test"})
    return path


def scan(rng: np.random.Generator, n: int = 40 * 360) -> tuple[np.ndarray, np.ndarray]:
    cloud = rng.uniform(-5, 5, (n, 3)).astype(np.float32)
    mask = rng.random(n) > 0.2
    return np.where(mask[:, None], cloud, 0).astype(np.float32), mask


def test_strided_sample_spreads_over_the_returns_and_repeats_short_scans():
    picks = strided_sample(np.arange(1000), 100)
    assert len(picks) == 100 and np.all(np.diff(picks) == 10)
    short = strided_sample(np.arange(7), 10)
    assert short.tolist() == [0, 1, 2, 3, 4, 5, 6, 0, 1, 2]
    with pytest.raises(ValueError, match="no returns"):
        strided_sample(np.arange(0), 10)


def test_nearest_sampled_gives_each_return_its_closest_sampled_neighbour():
    sampled = np.array([0, 4, 8])
    assert nearest_sampled(10, sampled).tolist() == [0, 0, 0, 1, 1, 1, 1, 2, 2, 2]
    assert nearest_sampled(3, np.array([0, 1, 2, 0, 1])).tolist() == [0, 1, 2]


def test_segmenter_labels_every_return_and_gives_a_unit_descriptor(checkpoint):
    segmenter = Segmenter(checkpoint)
    cloud, mask = scan(np.random.default_rng(0))
    result = segmenter.segment(cloud, mask)
    assert result.labels.shape == (len(cloud),)
    assert np.all(result.labels[~mask] == -1) and np.all((result.labels[mask] >= 0) & (result.labels[mask] < 4))
    assert result.descriptor.shape == (6,) and np.linalg.norm(result.descriptor) == pytest.approx(1.0, abs=1e-5)
    assert set(result.timings_ms) == {"features", "network", "labels"}


def test_segmenter_rejects_empty_and_all_nan_clouds(checkpoint):
    segmenter = Segmenter(checkpoint)
    n = 40 * 360
    with pytest.raises(ValueError, match="no finite returns"):
        segmenter.segment(np.zeros((n, 3), np.float32), np.zeros(n, bool))
    with pytest.raises(ValueError, match="no finite returns"):
        segmenter.segment(np.full((n, 3), np.nan, np.float32), np.ones(n, bool))
    with pytest.raises(ValueError, match="cloud has 10 points"):
        segmenter.segment(np.zeros((10, 3), np.float32), np.ones(10, bool))


def test_checkpoint_round_trip_and_errors(tmp_path, checkpoint):
    model, record = load_checkpoint(checkpoint)
    assert record == {"command": "test"} and model.config == SMALL and not model.training
    with pytest.raises(FileNotFoundError, match="nothing.pt"):
        load_checkpoint(tmp_path / "nothing.pt")
    corrupt = tmp_path / "corrupt.pt"
    corrupt.write_bytes(checkpoint.read_bytes()[:200])
    with pytest.raises(ValueError, match="corrupt.pt: not a readable"):
        load_checkpoint(corrupt)
    other = tmp_path / "other.pt"
    torch.save({"weights": torch.zeros(3)}, other)
    with pytest.raises(ValueError, match="format None"):
        load_checkpoint(other)
    data = torch.load(checkpoint, weights_only=True)
    data["config"]["descriptor_dim"] = 7
    torch.save(data, tmp_path / "mismatch.pt")
    with pytest.raises(ValueError, match="do not fit"):
        load_checkpoint(tmp_path / "mismatch.pt")


def test_fused_inference_matches_the_trained_module():
    from pimm_agents.pointnet import FusedPointNet

    torch.manual_seed(1)
    model = PointNetSegmenter(SMALL)
    # give the batch norms non-trivial statistics, as training would
    model.train()
    with torch.no_grad():
        model(torch.rand(4, SMALL.input_channels, 256) * 3)
    model.eval()
    x = torch.rand(1, SMALL.input_channels, 256) * 3
    with torch.inference_mode():
        logits, descriptor = model(x)
        fused_logits, fused_descriptor = FusedPointNet(model)(x[0].T.contiguous())
    assert torch.allclose(logits[0].T, fused_logits, atol=1e-4)
    assert torch.allclose(descriptor[0], fused_descriptor, atol=1e-5)
