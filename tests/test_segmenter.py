import numpy as np
import pytest
import torch

from pimm_agents.perception.pointnet import PointNetConfig, PointNetSegmenter, load_checkpoint, save_checkpoint
from pimm_agents.perception.segmenter import Segmenter, disputed_returns, nearest_sampled, strided_sample

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


def test_disputed_returns_lie_between_samples_of_different_classes():
    sampled = np.array([1, 4, 8])
    assert disputed_returns(11, sampled, np.array([0, 0, 2])).tolist() == [5, 6, 7]
    assert disputed_returns(11, sampled, np.array([3, 0, 0])).tolist() == [2, 3]
    assert disputed_returns(11, sampled, np.array([1, 1, 1])).tolist() == []
    assert disputed_returns(3, np.array([0, 1, 2, 0, 1]), np.array([0, 1, 2, 0, 1])).tolist() == []


def test_segmenter_labels_every_return_and_gives_a_unit_descriptor(checkpoint):
    segmenter = Segmenter(checkpoint)
    cloud, mask = scan(np.random.default_rng(0))
    result = segmenter.segment(cloud, mask)
    assert result.labels.shape == (len(cloud),)
    assert np.all(result.labels[~mask] == -1) and np.all((result.labels[mask] >= 0) & (result.labels[mask] < 4))
    assert result.descriptor.shape == (6,) and np.linalg.norm(result.descriptor) == pytest.approx(1.0, abs=1e-5)
    assert set(result.timings_ms) == {"features", "network", "boundaries"}
    # the descriptor alone (what a fingerprint map needs) is the same to the bit
    assert np.array_equal(segmenter.describe(cloud, mask), result.descriptor)


@pytest.fixture
def varied_checkpoint(tmp_path):
    """An untrained network whose classes still vary over a scan: batch norms calibrated on random input and
    no class bias (a fresh network gives every point the same class)."""
    torch.manual_seed(1)
    model = PointNetSegmenter(SMALL)
    with torch.no_grad():
        model.train()
        model(torch.rand(4, SMALL.input_channels, 256) * 3)
        model.head[-1].bias.zero_()
    path = tmp_path / "varied.pt"
    save_checkpoint(model.eval(), path, {"command": "test"})
    return path


def test_segmenter_classifies_returns_at_class_boundaries_itself(varied_checkpoint):
    """Off the sampled points a return takes its nearest sample's class unless it lies between two samples of
    different classes; there it gets the class the network gives it, against the sampled global feature."""
    from pimm_agents.perception.point_features import point_features, with_context

    segmenter = Segmenter(varied_checkpoint)
    cloud, mask = scan(np.random.default_rng(1))
    labels = segmenter.segment(cloud, mask).labels
    valid_index = np.flatnonzero(mask)
    sampled = strided_sample(valid_index, SMALL.points)
    net = segmenter.network
    inputs = with_context(point_features(cloud, mask, 40, 360), valid_index, 40, 360, SMALL.context_offsets)
    with torch.inference_mode():
        local = net.local_features(torch.from_numpy(inputs))
        glob = net.global_feature(local[sampled])
        own = net.logits(local, glob).argmax(dim=1).numpy()
    todo = disputed_returns(len(valid_index), sampled, own[sampled])
    nearest = own[sampled][nearest_sampled(len(valid_index), sampled)]
    assert len(todo) > 0 and np.any(nearest[todo] != own[todo])
    expected = nearest.copy()
    expected[todo] = own[todo]
    assert np.array_equal(labels[valid_index], expected)


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
    from pimm_agents.perception.records import WEIGHTS, write_record

    model, record = load_checkpoint(checkpoint)
    assert record["command"] == "test" and len(record["sha256"]) == 64
    assert model.config == SMALL and not model.training
    with pytest.raises(FileNotFoundError, match="nothing.pt"):
        load_checkpoint(tmp_path / "nothing.pt")
    corrupt = tmp_path / "corrupt.pt"
    corrupt.write_bytes(checkpoint.read_bytes()[:200])
    write_record(corrupt, WEIGHTS, "pimm-pointnet/1")  # recorded as it is: the reading itself must fail
    with pytest.raises(ValueError, match="corrupt.pt: not a readable"):
        load_checkpoint(corrupt)
    other = tmp_path / "other.pt"
    torch.save({"weights": torch.zeros(3)}, other)
    write_record(other, WEIGHTS, "pimm-pointnet/1")
    with pytest.raises(ValueError, match="format None"):
        load_checkpoint(other)
    data = torch.load(checkpoint, weights_only=True)
    data["config"]["descriptor_dim"] = 7
    torch.save(data, tmp_path / "mismatch.pt")
    write_record(tmp_path / "mismatch.pt", WEIGHTS, "pimm-pointnet/1")
    with pytest.raises(ValueError, match="do not fit"):
        load_checkpoint(tmp_path / "mismatch.pt")


def test_weights_without_a_matching_record_are_refused(tmp_path, checkpoint):
    import json

    from pimm_agents.perception.records import WEIGHTS, write_record

    record = json.loads(checkpoint.with_suffix(".json").read_text())
    assert record["kind"] == "pointnet-weights" and record["dtype"] == "float32"
    assert record["parameters"] == sum(p.numel() for p in PointNetSegmenter(SMALL).parameters())
    bare = tmp_path / "bare.pt"
    bare.write_bytes(checkpoint.read_bytes())
    with pytest.raises(ValueError, match=r"bare.pt: no record bare.json beside it"):
        load_checkpoint(bare)
    bare.with_suffix(".json").write_text("{not json")
    with pytest.raises(ValueError, match=r"bare.json: not a JSON record"):
        load_checkpoint(bare)
    data = torch.load(checkpoint, weights_only=True)
    data["state_dict"] = {k: v.double() for k, v in data["state_dict"].items()}
    wide = tmp_path / "wide.pt"
    torch.save(data, wide)
    write_record(wide, WEIGHTS, "pimm-pointnet/1", dtype="float32", parameters=record["parameters"])
    with pytest.raises(ValueError, match=r"wide.pt: tensor .* is torch.float64, the record says float32"):
        load_checkpoint(wide)
    fewer = tmp_path / "fewer.pt"
    fewer.write_bytes(checkpoint.read_bytes())
    write_record(fewer, WEIGHTS, "pimm-pointnet/1", parameters=record["parameters"] + 1)
    with pytest.raises(ValueError, match=r"fewer.pt: \d+ parameters, the record fewer.json says"):
        load_checkpoint(fewer)
    other_kind = tmp_path / "kind.pt"
    other_kind.write_bytes(checkpoint.read_bytes())
    write_record(other_kind, "fingerprint-map", "pimm-pointnet/1")
    with pytest.raises(ValueError, match=r"kind.json: kind is 'fingerprint-map', expected 'pointnet-weights'"):
        load_checkpoint(other_kind)


def test_fused_inference_matches_the_trained_module():
    from pimm_agents.perception.pointnet import FusedPointNet

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


def test_a_damaged_checkpoint_is_caught_by_its_checksum(tmp_path):
    import json
    import shutil

    from pimm_agents.perception.files import SHIPPED_WEIGHTS
    from pimm_agents.perception.records import file_sha256

    record = json.loads(SHIPPED_WEIGHTS.with_suffix(".json").read_text())
    assert record["sha256"] == file_sha256(SHIPPED_WEIGHTS)  # the shipped record holds the weights' checksum
    copy = tmp_path / "pointnet.pt"
    shutil.copy(SHIPPED_WEIGHTS, copy)
    shutil.copy(SHIPPED_WEIGHTS.with_suffix(".json"), copy.with_suffix(".json"))
    load_checkpoint(copy)
    data = bytearray(copy.read_bytes())
    start = len(data) // 2
    data[start : start + 4096] = bytes(b ^ 0xFF for b in data[start : start + 4096])  # 4 KB of flipped bytes
    copy.write_bytes(bytes(data))
    with pytest.raises(ValueError, match=r"pointnet.pt: SHA-256 .* differs from .*pointnet.json"):
        load_checkpoint(copy)
    copy.with_suffix(".json").unlink()  # the same damage with no record beside it: refused too
    with pytest.raises(ValueError, match=r"pointnet.pt: no record pointnet.json beside it"):
        load_checkpoint(copy)


def test_the_thesis_network_the_bench_times_has_its_size_and_shapes():
    import torch

    from pimm_agents.perception.thesis_pointnet import ThesisPointNet, parameter_count

    model = ThesisPointNet().eval()
    assert 3.4e6 < parameter_count(model) < 3.6e6  # the thesis: 3.5 M parameters
    with torch.inference_mode():
        scores = model(torch.zeros(2, 3, 300))
    assert scores.shape == (2, 4, 300)  # four classes per point
