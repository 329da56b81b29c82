import json

import pytest
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
