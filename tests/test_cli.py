import json
from pathlib import Path

import numpy as np
import pytest
import yaml
from typer.testing import CliRunner

import evaluate


def test_unknown_scenario_lists_the_valid_ones(tmp_path):
    result = CliRunner().invoke(evaluate.app, ["rollout", "--scenarios", "nowhere", "--out", str(tmp_path)])
    assert result.exit_code != 0
    assert "area_a" in result.output and "nowhere" in result.output


@pytest.mark.expensive
def test_rollout_command_writes_results(tmp_path):
    result = CliRunner().invoke(evaluate.app, ["rollout", "--scenarios", "area_b", "--out", str(tmp_path), "--json"])
    assert result.exit_code == 0, result.output
    data = json.loads(result.output.strip().splitlines()[-1])
    row = data["rollouts"]["area_b"]
    assert row["completed"] and not row["collided"] and row["length_m"] > 20
    folder = next(tmp_path.iterdir())
    assert (folder / "rollouts.json").is_file() and (folder / "rollouts.png").stat().st_size > 10_000


def test_list_options_take_several_values_after_one_flag():
    argv = ["run", "--scenarios", "area_a", "area_b", "--localizers", "amcl", "--trials", "2"]
    assert evaluate.expand_list_options(argv) == [
        "run", "--scenarios", "area_a", "--scenarios", "area_b", "--localizers", "amcl", "--trials", "2",
    ]  # fmt: skip


def test_run_rejects_unknown_names_and_settings(tmp_path):
    runner = CliRunner()
    result = runner.invoke(evaluate.app, ["run", "--localizers", "magic", "--out", str(tmp_path)])
    assert result.exit_code != 0 and "amcl-recovery" in result.output and "magic" in result.output
    result = runner.invoke(evaluate.app, ["run", "--scenarios", "moon", "--out", str(tmp_path)])
    assert result.exit_code != 0 and "a_c_b_kidnap" in result.output
    result = runner.invoke(
        evaluate.app, ["run", "--localizers", "amcl", "--set", "amcl.particles=5", "--out", str(tmp_path)]
    )
    assert result.exit_code != 0 and "max_particles" in result.output
    result = runner.invoke(evaluate.app, ["run", "--localizers", "amcl", "--set", "pimm.x=5", "--out", str(tmp_path)])
    assert result.exit_code != 0 and "localizers: amcl" in result.output
    assert not list(tmp_path.iterdir())  # nothing written for a rejected run


@pytest.mark.expensive
def test_run_one_trial_end_to_end_then_score_its_log(tmp_path):
    args = ["run", "--scenarios", "area_b", "--localizers", "amcl", "--trials", "1", "--workers", "1"]
    args += ["--set", "amcl.max_particles=500", "--set", "amcl.min_particles=100", "--out", str(tmp_path), "--json"]
    result = CliRunner().invoke(evaluate.app, args)
    assert result.exit_code == 0, result.output
    data = json.loads(result.output.strip().splitlines()[-1])
    row = data["scenarios"]["area_b"]["amcl"]
    assert set(row) == {
        "trials", "convergence_rate", "convergence_time_s", "position_error_m", "angle_error_deg", "timings_ms",
        "per_trial", "spread", "ape_m", "rpe_m", "time_to_localized_s", "false_localized_s", "false_localized_rate",
        "max_false_localized_s", "false_free_share", "within_3sigma", "nees", "kidnap_noticed_s", "time_to_fix_s",
        "localized_share", "fixed_share", "collisions", "overconfident_share", "published_overconfident_share",
    }  # fmt: skip
    assert [r["seed"] for r in row["per_trial"]] == [0] and row["ape_m"]["rmse"] >= row["ape_m"]["min"] >= 0
    assert set(data) >= {"version", "commit", "machine"} and len(data["commit"].split("+")[0]) == 40
    assert data["machine"]["cores"] >= 1 and data["machine"]["numpy"] == np.__version__
    assert row["trials"] == 1 and row["convergence_rate"] == float(row["per_trial"][0]["converged"])
    assert set(row["timings_ms"]) >= {"sensor", "total"} and row["timings_ms"]["sensor"]["max"] > 0
    folder = Path(data["folder"])
    assert json.loads((folder / "summary.json").read_text())["scenarios"]["area_b"]["amcl"] == row
    config = yaml.safe_load((folder / "config.yaml").read_text())
    assert config["amcl"]["max_particles"] == 500 and config["amcl"]["min_particles"] == 100
    assert yaml.safe_load((folder / "run.yaml").read_text())["seed"] == 0
    logs = sorted((folder / "logs").glob("*.csv"))
    assert [p.name for p in logs] == ["area_b_amcl_trial00.csv"]
    assert json.loads((folder / "logs" / "area_b_amcl_trial00.json").read_text())["kidnap_row"] is None
    assert {p.name for p in (folder / "tum" / "area_b_amcl_trial00").iterdir()} == {"gt.tum", "est.tum"}
    assert len(list((folder / "figures").glob("*.png"))) >= 1
    scored = CliRunner().invoke(evaluate.app, ["score", str(logs[0]), "--json"])
    assert scored.exit_code == 0, scored.output
    summary = json.loads(scored.output)["groups"]["area_b / amcl"]
    assert summary["convergence_rate"] == row["convergence_rate"]
    if row["convergence_time_s"] is not None:
        assert summary["convergence_time_s"] == pytest.approx(row["convergence_time_s"], abs=1e-3)


def test_score_names_the_bad_line(tmp_path):
    bad = tmp_path / "bad.csv"
    bad.write_text(
        "timestamp_real,timestamp_est,real_x,real_y,real_theta,est_x,est_y,est_theta,cov_x,cov_y,cov_theta\n"
        "0,0,0,0,0,0,0,0,0,0,0\n0,0,0,0,0,x,0,0,0,0,0\n"
    )
    result = CliRunner().invoke(evaluate.app, ["score", str(bad)])
    assert result.exit_code != 0 and "line 3" in result.output and "est_x" in result.output


@pytest.mark.expensive
def test_perception_reports_segmentation_retrieval_and_corners(tmp_path):
    figure = tmp_path / "perception.png"
    result = CliRunner().invoke(evaluate.app, ["perception", "--scans", "3", "--json", "--figure", str(figure)])
    assert result.exit_code == 0, result.output
    assert figure.stat().st_size > 10_000
    report = json.loads(result.output.strip().splitlines()[-1])
    corner_keys = {"precision", "recall", "median_position_error_m", "median_orientation_error_deg"}
    for which in ("true_labels", "predicted_labels"):
        stats = report["corners"][which]
        assert set(stats) == corner_keys
    assert report["corners"]["true_labels"]["recall"] > 0  # the iiLab's corners are found from true labels
    iou = report["segmentation"]["iou"]
    assert set(iou) == {"floor", "ceiling", "wall", "clutter"}
    assert report["segmentation"]["miou"] == pytest.approx(np.mean(list(iou.values())))
    retrieval = report["retrieval"]
    assert {"recall_at_3_2m", "mean_error_m", "mean_min_error_m", "mean_max_error_m"} <= set(retrieval)
    assert retrieval["mean_min_error_m"] <= retrieval["mean_error_m"] <= retrieval["mean_max_error_m"]


@pytest.mark.expensive
def test_a_runs_config_yaml_repeats_it_exactly(tmp_path):
    def run(*extra: str) -> dict:
        args = ["run", "--scenarios", "area_b", "--trials", "1", "--workers", "1", "--seed", "3", "--json"]
        result = CliRunner().invoke(evaluate.app, [*args, *extra])
        assert result.exit_code == 0, result.output
        return json.loads(result.output.strip().splitlines()[-1])

    first = run("--localizers", "amcl", "--set", "amcl.max_particles=400", "--set", "amcl.min_particles=100",
                "--out", str(tmp_path / "a"))  # fmt: skip
    config = Path(first["folder"]) / "config.yaml"
    assert yaml.safe_load(config.read_text())["amcl"]["max_particles"] == 400
    again = run("--params", str(config), "--out", str(tmp_path / "b"))

    def without_clock(summary: dict) -> dict:  # what the machine's speed changes: timings and wall time
        row = {k: v for k, v in summary["scenarios"]["area_b"]["amcl"].items() if k != "timings_ms"}
        row["per_trial"] = [{k: v for k, v in t.items() if k != "wall_s"} for t in row["per_trial"]]
        return row

    assert without_clock(first) == without_clock(again)
    assert (Path(again["folder"]) / "config.yaml").read_text() == config.read_text()


def test_both_command_lines_take_several_values_after_one_flag():
    from pimm_agents.command_line import expand_list_options

    argv = ["train", "--world", "iilab", "gen.yaml", "--epochs", "2", "--localizers", "pimm", "amcl"]
    assert expand_list_options(argv, ("--world", "--localizers")) == [
        "train", "--world", "iilab", "--world", "gen.yaml", "--epochs", "2", "--localizers", "pimm",
        "--localizers", "amcl",
    ]  # fmt: skip
    assert expand_list_options(argv, ()) == argv
