"""``--json`` prints exactly one JSON document on stdout, whatever C libraries print (run as a user would)."""

import json
import subprocess
import sys
from pathlib import Path

import pytest

from tests.rooms import ROUTES

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture
def room_world(room_file: Path) -> Path:
    (room_file.parent / "scenarios.yaml").write_text(ROUTES)
    return room_file


def _stdout(*args: str) -> str:
    done = subprocess.run([sys.executable, str(ROOT / "evaluate.py"), *args, "--json"], capture_output=True,
                          text=True, cwd=ROOT, timeout=600)  # fmt: skip
    assert done.returncode == 0, done.stderr[-2000:]
    return done.stdout


def _one_document(text: str) -> dict:
    document = json.loads(text)  # fails on a banner before or after the document
    assert isinstance(document, dict) and text.strip().count("\n") == 0
    return document


def test_run_score_and_rollout_print_one_json_document(room_world, tmp_path):
    run = _one_document(_stdout("run", "--world", str(room_world), "--localizers", "tests.plugins.dead_reckoning:make",
                                "--trials", "1", "--workers", "1", "--out", str(tmp_path)))  # fmt: skip
    assert set(run["scenarios"]) == {"there", "there_kidnap"}
    scored = _one_document(_stdout("score", str(Path(run["folder"]) / "logs")))
    assert len(scored["trials"]) == 2
    rolled = _one_document(_stdout("rollout", "--world", str(room_world), "--out", str(tmp_path)))
    assert rolled["rollouts"]["there"]["completed"] is True


@pytest.mark.expensive
def test_perception_and_bench_print_one_json_document(room_world):
    perception = _one_document(_stdout("perception", "--world", str(room_world), "--scans", "2"))
    assert "retrieval" not in perception  # the room has no fingerprint map yet: left out, not an error
    iou = perception["segmentation"]["iou"]
    assert perception["segmentation"]["miou"] == pytest.approx(sum(iou.values()) / len(iou))
    bench = _one_document(_stdout("bench", "--repeats", "3"))
    assert bench["pimm_pipeline_ms"] > 0
    assert {"pimm_stage_segmentation_ms", "pimm_stage_corners_ms", "pimm_per_scan_ms"} <= set(
        bench
    )  # where the time goes
    assert bench["pf_converged_particles"] < 10_000  # KLD shrank the converged set the bench times
    # the scan's perception is a part of each update, and the thesis's network is compared with it too
    assert 0 < bench["pimm_perception_ms"] < bench["pimm_pipeline_ms"]
    ratio = bench["thesis_pointnet_ms"] / bench["pimm_perception_ms"]
    assert bench["thesis_pointnet_over_perception"] == pytest.approx(ratio)
    # PIMM as a ROS 2 node beside sim-robot: a cloud's arrival to its pose's publication
    assert 0 < bench["node_latency_ms"] <= bench["node_latency_p99_ms"] <= bench["node_latency_max_ms"]


def test_a_missing_world_is_one_line_naming_it(tmp_path):
    done = subprocess.run([sys.executable, str(ROOT / "evaluate.py"), "run", "--world", str(tmp_path / "nowhere")],
                          capture_output=True, text=True, cwd=ROOT, timeout=120)  # fmt: skip
    assert done.returncode == 1 and done.stdout == ""
    assert done.stderr.startswith("error: unknown world") and "nowhere" in done.stderr
    assert "Traceback" not in done.stderr and len(done.stderr.strip().splitlines()) == 1
