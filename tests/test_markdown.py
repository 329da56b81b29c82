import json

import pytest
from typer.testing import CliRunner

import evaluate
from pimm_agents.results.markdown import markdown_report
from pimm_env.errors import MissingFileError, ResultsError

ROW = {"trials": 10, "convergence_rate": 0.9, "convergence_time_s": 2.5, "position_error_m": 0.0213,
       "angle_error_deg": 0.12}  # fmt: skip


def write_summary(folder, honest: bool):
    row = {**ROW, "false_localized_s": 1.5, "false_localized_rate": 0.02, "time_to_localized_s": 3.0,
           "max_false_localized_s": 1.2, "false_free_share": 0.8, "within_3sigma": 0.95} if honest else ROW  # fmt: skip
    summary = {"scenarios": {"area_a": {"pimm": row, "amcl": {**ROW, "convergence_time_s": None}}},
               "commit": "abc123", "version": "0.2.0", "machine": {"cpu": "Some CPU", "cores": 2},
               "run": {"command": "python evaluate.py run --trials 10"}}  # fmt: skip
    folder.mkdir(exist_ok=True)
    (folder / "summary.json").write_text(json.dumps(summary))


def test_a_results_folder_becomes_one_table_naming_command_commit_and_machine(tmp_path):
    write_summary(tmp_path / "run", honest=False)
    text = markdown_report(tmp_path / "run")
    assert text.startswith("Made by `python evaluate.py run --trials 10` at commit `abc123` (pimm 0.2.0) on Some CPU")
    assert "| area_a | pimm | 10 | 90 | 2.50 | 0.021 | 0.12 |" in text
    assert "| | *pimm, thesis* | *10* | *100* | *20.88* |" in text and "| amcl | 10 | 90 | - |" in text
    assert "false localized" not in text  # an older summary without the figures gets no such table
    write_summary(tmp_path / "honest", honest=True)
    assert "| area_a | pimm | 3.00 | 1.50 | 2 | 1.20 | 80 | 95 |" in markdown_report(tmp_path / "honest")
    result = CliRunner().invoke(evaluate.app, ["report", str(tmp_path / "honest"), "--markdown"])
    assert result.exit_code == 0 and result.output == markdown_report(tmp_path / "honest")


def test_a_folder_that_is_no_results_folder_is_named(tmp_path):
    with pytest.raises(MissingFileError, match="no summary.json"):
        markdown_report(tmp_path)
    (tmp_path / "summary.json").write_text("{}")
    with pytest.raises(ResultsError, match="no 'scenarios' mapping"):
        markdown_report(tmp_path)
    result = CliRunner().invoke(evaluate.app, ["report", str(tmp_path)])
    assert result.exit_code == 1 and "error:" in result.output and "scenarios" in result.output
