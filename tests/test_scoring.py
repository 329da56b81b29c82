import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

import evaluate
from pimm_agents.results.log_files import write_csv
from pimm_agents.results.scored_logs import find_logs, group_summaries, score_log
from pimm_agents.scoring.log_faults import cleaned, faults_of
from pimm_agents.scoring.trial_log import TrialLog
from tests.conftest import SHARED


def _thesis_logs() -> Path:
    folder = SHARED / "thesis" / "trials"
    if not folder.is_dir():
        pytest.skip(f"the thesis's logs {folder} are not present")
    return folder


def test_the_thesis_logs_faults_are_counted_and_can_be_dropped():
    scored = [score_log(p) for p in find_logs([_thesis_logs()])]
    assert len(scored) == 19
    assert sum(s.faults.repeated_stamps for s in scored) == 425
    assert max(s.faults.longest_gap_s for s in scored) > 13_000  # a recording paused for almost four hours
    assert sum(s.faults.uninitialised_leading for s in scored) > 0
    assert list(group_summaries(scored)) == ["Nave_A_AMCL", "Nave_A_MM"]
    for item in scored:
        clean = cleaned(item.log, drop_repeated=True, drop_uninitialised=True)
        assert faults_of(clean).repeated_stamps == 0 and faults_of(clean).uninitialised_leading == 0
        most = item.faults.repeated_stamps + item.faults.uninitialised_leading  # a row can be both
        assert (
            len(item.log) - most
            <= len(clean)
            <= len(item.log) - max(item.faults.repeated_stamps, item.faults.uninitialised_leading)
        )


def test_a_kidnap_marked_in_the_sidecar_is_scored_from_the_kidnap(tmp_path):
    t = np.arange(0.0, 30.0, 0.5)
    true = np.column_stack([t * 0.1, np.zeros_like(t), np.zeros_like(t)])
    estimate = true.copy()
    estimate[30:40, 0] += 10.0  # lost for 5 s right after the kidnap at row 30, then found again
    log = TrialLog(t, t, true, estimate, np.zeros_like(true))
    path = tmp_path / "route_1_kidnap_pimm_trial00.csv"
    write_csv(log, path)
    assert score_log(path).metrics.convergence_time_s == pytest.approx(20.0)  # counted from the start
    path.with_suffix(".json").write_text(json.dumps({"scenario": "route_1_kidnap", "localizer": "pimm",
                                                     "kidnap_row": 30}))  # fmt: skip
    scored = score_log(path)
    assert scored.group == "route_1_kidnap / pimm" and scored.metrics.convergence_time_s == pytest.approx(5.0)
    path.with_suffix(".json").write_text(json.dumps({"kidnap_row": 99}))
    with pytest.raises(ValueError, match="kidnap_row 99 is past"):
        score_log(path)


def test_score_takes_folders_and_names_what_is_missing(tmp_path):
    empty = tmp_path / "empty"
    empty.mkdir()
    result = CliRunner().invoke(evaluate.app, ["score", str(empty)])
    assert result.exit_code != 0 and "holds no .csv" in result.output
    result = CliRunner().invoke(evaluate.app, ["score", str(tmp_path / "nothing.csv")])
    assert result.exit_code != 0 and "no such log file or folder" in result.output


@pytest.mark.expensive
def test_score_reproduces_runs_metrics_on_every_scenario(tmp_path):
    args = ["run", "--localizers", "amcl-recovery", "--trials", "1", "--workers", "1", "--seed", "3", "--json"]
    args += ["--out", str(tmp_path)]
    result = CliRunner().invoke(evaluate.app, args)
    assert result.exit_code == 0, result.output
    run = json.loads(result.output.strip().splitlines()[-1])
    scored = CliRunner().invoke(evaluate.app, ["score", str(Path(run["folder"]) / "logs"), "--json"])
    assert scored.exit_code == 0, scored.output
    groups = json.loads(scored.output)["groups"]
    scenarios = ("area_a", "area_b", "a_c_b", "a_c_b_kidnap")  # the iilab's, which run runs by default
    assert set(groups) == {f"{s} / amcl-recovery" for s in scenarios}
    for scenario in scenarios:
        ran, again = run["scenarios"][scenario]["amcl-recovery"], groups[f"{scenario} / amcl-recovery"]
        for key in ("trials", "convergence_rate", "convergence_time_s", "position_error_m", "angle_error_deg"):
            assert again[key] == pytest.approx(ran[key], abs=1e-5), (scenario, key)
    assert run["scenarios"]["a_c_b_kidnap"]["amcl-recovery"]["convergence_rate"] == 1.0  # a real kidnap recovery


def test_a_binary_file_or_rows_out_of_time_order_are_named(tmp_path):
    binary = tmp_path / "weights.csv"
    binary.write_bytes(bytes(range(256)) * 4)
    with pytest.raises(ValueError, match="weights.csv: not a text CSV file"):
        score_log(binary)
    t = np.array([0.0, 1.0, 0.5, 2.0])
    log = TrialLog(t, t, np.zeros((4, 3)), np.zeros((4, 3)), np.zeros((4, 3)))
    path = tmp_path / "reversed.csv"
    write_csv(log, path)
    with pytest.raises(ValueError, match=r"reversed.csv: line 4: timestamp_real goes back \(0.5 after 1.0\)"):
        score_log(path)
