import json

import numpy as np
import pytest
import torch

from pimm_agents.measurement.perception_quality import iou_per_class
from pimm_agents.perception.pointnet import PointNetConfig, PointNetSegmenter, save_checkpoint
from pimm_agents.perception.segmenter import Segmenter
from pimm_agents.preparation.fingerprints import _descriptors, build_fingerprint_map
from pimm_env.envs.iilab_env import IILabEnv
from pimm_env.errors import PerceptionError
from training.dataset import generate, load, save, split
from training.train import (
    TrainConfig,
    check_teacher,
    class_weights,
    contrastive_loss,
    distillation_loss,
    make_sampler,
    pair_batches,
    train,
)

TINY = PointNetConfig(points=128, local_widths=(8, 16), global_widths=(16, 32), head_widths=(16, 8), descriptor_dim=8)


def test_class_weights_follow_thesis_eq_3_6():
    labels = np.array([0] * 8 + [1] * 1 + [2] * 8 + [3] * 27 + [-1] * 5)
    weights = class_weights(labels)
    assert weights == pytest.approx([(27 / 8) ** (1 / 3), 3.0, (27 / 8) ** (1 / 3), 1.0])
    with pytest.raises(ValueError, match="clutter"):
        class_weights(np.array([0, 1, 2]))


def test_iou_by_hand():
    truth = np.array([0, 0, 1, 1, 2, 3, -1])
    predicted = np.array([0, 1, 1, 1, 2, 2, 3])
    iou = iou_per_class(predicted, truth)
    assert iou == pytest.approx([1 / 2, 2 / 3, 1 / 2, 0.0])


def test_contrastive_loss_prefers_descriptors_that_agree_with_places():
    positions = torch.tensor([[0.0, 0.0], [0.5, 0.0], [10.0, 0.0], [10.5, 0.0]])
    good = torch.nn.functional.normalize(torch.tensor([[1.0, 0.1], [1.0, 0.0], [0.0, 1.0], [0.1, 1.0]]), dim=1)
    bad = good[[0, 2, 1, 3]]
    assert contrastive_loss(good, positions, 2.0, 0.1) < contrastive_loss(bad, positions, 2.0, 0.1)


def test_distillation_loss_is_zero_only_where_the_student_agrees_with_the_teacher():
    teacher = torch.tensor([[[3.0, -1.0], [0.0, 2.0], [0.0, 0.0], [-2.0, 0.5]]])  # (batch, classes, points)
    assert float(distillation_loss(teacher.clone(), teacher, 2.0)) == pytest.approx(0.0, abs=1e-6)
    shifted = teacher + 5.0  # the same probabilities: softmax ignores a constant per point
    assert float(distillation_loss(shifted, teacher, 2.0)) == pytest.approx(0.0, abs=1e-5)
    swapped = teacher[:, [1, 0, 3, 2], :]
    assert float(distillation_loss(swapped, teacher, 2.0)) > 0.5


@pytest.mark.expensive
def test_a_student_learns_the_teachers_classes():
    """Trained on a teacher's probabilities alone, a smaller student agrees with it on more points than the
    same student left where it started (learning rate 0); a teacher of other inputs is refused by name."""
    scans = generate("iilab", 6, seed=3, progress=False)
    train_set, test_set = split(scans, 0.8, np.random.default_rng(0))
    teacher, _ = train(
        train_set, test_set, TrainConfig(epochs=8, batch_pairs=1, learning_rate=1e-2), TINY, progress=False
    )
    student = PointNetConfig(points=128, local_widths=(6, 8), global_widths=(8, 16), head_widths=(8, 4))
    runs = {
        rate: train(
            train_set,
            test_set,
            TrainConfig(epochs=12, batch_pairs=1, seed=1, distill_weight=1.0, learning_rate=rate),
            student,
            progress=False,
            teacher=teacher,
        )
        for rate in (1e-2, 0.0)
    }
    history = runs[1e-2][1]
    assert history[-1]["distillation_loss"] < history[0]["distillation_loss"]
    inputs = torch.from_numpy(np.stack([make_sampler(scans, TINY).sample(i, 0)[0] for i in range(len(scans))]))
    with torch.inference_mode():
        wanted = teacher(inputs)[0].argmax(1)
        agree = {rate: float((m(inputs)[0].argmax(1) == wanted).float().mean()) for rate, (m, _) in runs.items()}
    assert len(torch.unique(wanted)) > 1 and agree[1e-2] > agree[0.0] + 0.1, agree
    cloud_teacher = PointNetSegmenter(PointNetConfig(points=128, inputs="cloud", context_offsets=()))
    with pytest.raises(PerceptionError, match="teacher network's inputs"):
        check_teacher(cloud_teacher, TINY)


def test_pair_batches_pair_each_anchor_with_a_near_scan():
    rng = np.random.default_rng(0)
    positions = rng.uniform(0, 20, (200, 2))
    for batch in pair_batches(positions, 8, 2.0, rng):
        anchors, partners = batch[:8], batch[8:]
        assert np.all(np.linalg.norm(positions[anchors] - positions[partners], axis=1) < 2.0)


def test_tiny_end_to_end_training_run(tmp_path):
    """A handful of scans, one epoch: dataset -> weights -> segmenter -> fingerprint map, all on disk."""
    scans = generate("iilab", 12, seed=5, progress=False)
    assert scans.ranges.shape == (12, 40, 360) and scans.ranges.dtype == np.float16
    assert set(np.unique(scans.labels)) <= {-1, 0, 1, 2, 3}
    save(scans, tmp_path / "scans.npz")
    again = load(tmp_path / "scans.npz")
    assert np.array_equal(again.labels, scans.labels) and np.allclose(again.poses, scans.poses)
    train_set, test_set = split(again, 0.8, np.random.default_rng(0))
    assert len(train_set) + len(test_set) == 12 and len(test_set) == 2
    config = TrainConfig(epochs=1, batch_pairs=2)
    model, history = train(train_set, test_set, config, TINY, progress=False)
    assert len(history) == 1 and np.isfinite(history[0]["loss"])
    assert set(history[0]["test_iou"]) == {"wall", "ceiling", "floor", "clutter"}
    save_checkpoint(model, tmp_path / "pointnet.pt", {"history": history})
    segmenter = Segmenter(tmp_path / "pointnet.pt")
    fmap = build_fingerprint_map("iilab", segmenter, spacing=4.0, seed=0, progress=False)
    assert len(fmap) > 10 and fmap.dim == 8
    # the map casts the 3D LiDAR alone and takes the descriptor alone: the same as a full env's scan segmented
    poses, seeds = np.column_stack([fmap.positions[:3], [0.3, -2.0, 3.0]]), np.array([5, 6, 7])
    env = IILabEnv()
    full = [env.reset(seed=int(k), options={"pose": list(p)})[0] for p, k in zip(poses, seeds, strict=True)]
    env.close()
    expected = [segmenter.segment(obs["cloud"], obs["cloud_mask"]).descriptor for obs in full]
    np.testing.assert_array_equal(_descriptors(("iilab", segmenter, poses, seeds, False)), np.array(expected))


def test_dataset_errors_name_the_file(tmp_path):
    with pytest.raises(FileNotFoundError, match="absent.npz"):
        load(tmp_path / "absent.npz")
    np.savez(tmp_path / "partial.npz", format="pimm-scans/1", ranges=np.zeros((1, 2, 2)))
    with pytest.raises(ValueError, match=r"partial.npz: dataset lacks field\(s\)"):
        load(tmp_path / "partial.npz")
    scans = generate("iilab", 2, seed=0, progress=False)
    with pytest.raises(ValueError, match="train_fraction"):
        split(scans, 1.0, np.random.default_rng(0))
    with pytest.raises(ValueError, match=r"scans are \(40, 360\), the LiDAR is 16 x 360"):
        scans.require_lidar(16, 360)


def test_rebuild_command_makes_every_perception_file_for_a_world(room_file, tmp_path, monkeypatch):
    """`python -m training rebuild` on a small room: dataset, weights (with their record) and fingerprint map."""
    from typer.testing import CliRunner

    from training.__main__ import app

    monkeypatch.chdir(tmp_path)
    args = ["rebuild", "--world", str(room_file), "--scans", "10", "--validation", "2", "--epochs", "1"]
    result = CliRunner().invoke(app, [*args, "--spacing", "1.0"])
    assert result.exit_code == 0, result.output
    assert (tmp_path / "build/datasets/room/scans.npz").is_file()
    folder = room_file.parent
    assert {"pointnet.pt", "pointnet.json", "fingerprints.npz"} <= {p.name for p in folder.iterdir()}
    record = json.loads((folder / "pointnet.json").read_text())
    validation = record["validation"]  # scored on the 2 validation scans, every return
    assert validation["scans"] == 2 and set(validation["iou"]) == {"wall", "ceiling", "floor", "clutter"}
    assert "mean" in result.output and f"{validation['mean_iou']:.3f}" in result.output
    from pimm_agents.perception.files import load_perception

    segmenter, fmap = load_perception(str(room_file))
    assert len(fmap) >= 3 and fmap.dim == segmenter.descriptor_dim


def test_train_command_builds_the_network_of_the_widths_given(room_file, tmp_path, monkeypatch):
    """`python -m training train --local-widths ...`: the weights are of those widths, and the record says so;
    a width that is not a positive integer, or widths with --init, are refused by option. `--teacher`: a
    smaller network learns from the first, its record names the teacher, also when it goes on from its own weights
    (`--init`); one of other inputs is refused."""
    from typer.testing import CliRunner

    from pimm_agents.perception.pointnet import load_checkpoint
    from training.__main__ import app

    monkeypatch.chdir(tmp_path)
    runner = CliRunner()
    made = runner.invoke(app, ["dataset", "--world", str(room_file), "--scans", "10", "--validation", "2"])
    assert made.exit_code == 0, made.output
    out = tmp_path / "small.pt"
    base = ["train", "--world", str(room_file), "--epochs", "1", "--points", "256", "--out", str(out)]
    widths = ["--local-widths", "16,8", "--global-widths", "12,24", "--head-widths", "10,6"]
    result = runner.invoke(app, [*base, *widths])
    assert result.exit_code == 0, result.output
    model, record = load_checkpoint(out)
    assert (model.config.local_widths, model.config.global_widths, model.config.head_widths) == (
        (16, 8),
        (12, 24),
        (10, 6),
    )
    assert tuple(record["network"]["global_widths"]) == (12, 24) and model.config.points == 256
    bad = runner.invoke(app, [*base, "--head-widths", "64,0"])
    assert bad.exit_code != 0 and "--head-widths" in bad.output and "positive integers" in bad.output
    both = runner.invoke(app, [*base, "--local-widths", "16,8", "--init", str(out)])
    assert both.exit_code != 0 and "--init" in both.output
    taught_path = tmp_path / "taught.pt"
    teach = ["--teacher", str(out), "--out", str(taught_path), "--local-widths", "8,8", "--global-widths", "8,16"]
    taught = runner.invoke(app, [*base[:-2], *teach])
    assert taught.exit_code == 0, taught.output
    assert "teacher" in taught.output  # its loss reported each epoch
    record = load_checkpoint(taught_path)[1]
    assert record["teacher_weights"]["sha256"] == load_checkpoint(out)[1]["sha256"]
    assert record["history"][0]["distillation_loss"] > 0
    on = runner.invoke(
        app, [*base[:-2], "--init", str(taught_path), "--teacher", str(out), "--out", str(tmp_path / "on.pt")]
    )
    assert on.exit_code == 0, on.output  # going on from the student's weights, still taught
    record = load_checkpoint(tmp_path / "on.pt")[1]
    assert record["initial_weights"] == str(taught_path) and record["teacher_weights"]["path"] == str(out)
    cloud_path = tmp_path / "cloud.pt"
    save_checkpoint(PointNetSegmenter(PointNetConfig(points=256, inputs="cloud", context_offsets=())), cloud_path, {})
    refused = runner.invoke(app, [*base[:-2], "--teacher", str(cloud_path), "--out", str(tmp_path / "no.pt")])
    assert refused.exit_code != 0 and "--teacher" in refused.output and "inputs" in refused.output
    alone = runner.invoke(app, [*base, "--distill-weight", "0.3"])
    assert alone.exit_code != 0 and "--distill-weight" in alone.output


def test_scans_and_fingerprints_are_the_same_whichever_engine_takes_them(tmp_path):
    """Split over two local processes, the data equal the serial run's (on Ray: the expensive test below)."""
    serial = generate("iilab", 6, seed=3, progress=False)
    split_up = generate("iilab", 6, seed=3, progress=False, workers=2)
    for field in ("ranges", "labels", "poses", "areas"):
        np.testing.assert_array_equal(getattr(split_up, field), getattr(serial, field))
    model = PointNetSegmenter(TINY)
    save_checkpoint(model, tmp_path / "pointnet.pt", {})
    segmenter = Segmenter(tmp_path / "pointnet.pt")
    one = build_fingerprint_map("iilab", segmenter, spacing=5.0, seed=1, progress=False)
    two = build_fingerprint_map("iilab", segmenter, spacing=5.0, seed=1, progress=False, workers=2)
    np.testing.assert_allclose(two.descriptors, one.descriptors, atol=1e-6)
    np.testing.assert_array_equal(two.positions, one.positions)
    with pytest.raises(ValueError, match="expected local or ray"):
        generate("iilab", 2, seed=0, progress=False, backend="dask")


@pytest.mark.expensive
def test_scans_on_a_local_ray_equal_the_serial_ones():
    pytest.importorskip("ray")
    serial = generate("iilab", 4, seed=7, progress=False)
    on_ray = generate("iilab", 4, seed=7, progress=False, workers=2, backend="ray")
    np.testing.assert_array_equal(on_ray.ranges, serial.ranges)
    np.testing.assert_array_equal(on_ray.poses, serial.poses)


def test_heldout_refuses_a_bad_setting_before_writing_any_building(tmp_path):
    """`python -m training heldout --set`: a setting the localizer does not have is named, and nothing is built."""
    from typer.testing import CliRunner

    from training.__main__ import app

    worlds, out = tmp_path / "worlds", tmp_path / "out"
    args = ["heldout", "--seeds", "920", "--localizers", "pimm", "--worlds", str(worlds), "--out", str(out)]
    result = CliRunner().invoke(app, [*args, "--set", "pimm.rivals.max_rivalz=10"])
    assert result.exit_code != 0
    assert "max_rivalz" in result.output
    assert not worlds.exists() and not out.exists()


def test_the_heldout_table_shows_the_published_covariances_overconfident_rows():
    from training.heldout import format_table, summarize

    row = {"miou": 0.9, "recall_at_3": 0.8, "corner_recall": 0.7, "convergence_rate": 1.0, "convergence_time_s": 4.0,
           "position_error_m": 0.02, "excursions_per_trial": 0.0, "excursions_held_per_trial": 0.0,
           "kidnap_recovery": 1.0, "trials": 5.0, "false_free_trials": 5.0, "false_localized_s": 0.0,
           "localized_s": 100.0, "max_false_localized_s": 0.0, "localized_right_trials": 5.0,
           "time_to_localized_s": 6.0, "within_3sigma": 1.0, "kidnap_noticed_s": 0.3, "rows": 4000.0,
           "published_overconfident_rows": 2.0}  # fmt: skip
    rows = {"gen-1": {"pimm": row}, "gen-2": {"pimm": {**row, "published_overconfident_rows": 6.0}}}
    table = format_table(rows, ["pimm"]).splitlines()
    assert table[0].endswith("| published overconf. % |") and table[2].endswith("| 0.05 % |")
    assert summarize(rows, "pimm")["published_overconfident_rows"] == 8.0
