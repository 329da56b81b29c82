"""The shipped iiLab perception: weights and fingerprint map in maps/iilab/, measured on fresh scans."""

import numpy as np
import pytest

from pimm_agents.measurement.perception_quality import iou_per_class
from pimm_agents.perception.files import checkpoint_path, fingerprint_path, load_perception
from pimm_agents.perception.fingerprint_map import FingerprintMap
from pimm_env.envs.iilab_env import IILabEnv


@pytest.fixture(scope="module")
def perception():
    return load_perception("iilab")


def test_shipped_weights_are_small_and_record_how_they_were_made():
    path = checkpoint_path("iilab")
    assert path.stat().st_size <= 5_000_000
    from pimm_agents.perception.pointnet import load_checkpoint

    _, record = load_checkpoint(path)
    assert record["command"].startswith("python -m training train")
    assert len(record["history"]) >= 1


def test_shipped_weights_segment_fresh_scans(perception):
    segmenter, _ = perception
    env = IILabEnv()
    predicted, truth = [], []
    for seed in (11, 12, 13, 14):
        obs, info = env.reset(seed=seed)
        labels = segmenter.segment(obs["cloud"], obs["cloud_mask"]).labels
        mask = obs["cloud_mask"].astype(bool)
        predicted.append(labels[mask])
        truth.append(info["labels"][mask])
    env.close()
    iou = iou_per_class(np.concatenate(predicted), np.concatenate(truth))
    assert np.nanmean(iou) >= 0.8, f"per-class IoU {np.round(iou, 3)}"


def test_fingerprint_map_finds_its_own_positions(perception):
    segmenter, fmap = perception
    env = IILabEnv()
    rng = np.random.default_rng(0)
    hits = 0
    picks = rng.choice(len(fmap), 6, replace=False)
    for i in picks:
        pose = [*fmap.positions[i], fmap.headings[i]]
        obs, _ = env.reset(seed=int(i), options={"pose": pose})  # same place, new noise
        retrieval = fmap.query(segmenter.segment(obs["cloud"], obs["cloud_mask"]).descriptor)
        hits += bool(np.any(np.all(np.isclose(retrieval.positions, fmap.positions[i]), axis=1)))
    env.close()
    assert hits >= 5, f"{hits} of {len(picks)} scans retrieved their own map position"


def test_descriptor_size_mismatch_is_named(tmp_path, monkeypatch, perception):
    segmenter, fmap = perception
    cut = fmap.descriptors[:, :4] / np.linalg.norm(fmap.descriptors[:, :4], axis=1, keepdims=True)
    small = FingerprintMap(cut, fmap.positions, fmap.headings)
    with pytest.raises(ValueError, match="query descriptor has"):
        small.query(segmenter.segment(*_one_scan()).descriptor)
    import pimm_agents.perception.files as pm

    small.save(tmp_path / "fingerprints.npz", segmenter.weights_sha256)
    monkeypatch.setattr(pm, "fingerprint_path", lambda world: tmp_path / "fingerprints.npz")
    with pytest.raises(ValueError, match="4 dimensions"):
        pm.load_perception("iilab")
    assert fingerprint_path("iilab").name == "fingerprints.npz"


def _one_scan():
    env = IILabEnv()
    obs, _ = env.reset(seed=0)
    env.close()
    return obs["cloud"], obs["cloud_mask"]
