import json
import shutil
from pathlib import Path

import pytest
from typer.testing import CliRunner

import evaluate
from pimm_agents.experiments.runner import run_shared
from pimm_agents.experiments.sweep import read_sweep, rows_of, sweep_specs
from pimm_agents.scoring.trial import TrialSpec
from pimm_env.envs.faults import kidnap_trial_fault
from pimm_env.mapping.derived_maps import ensure_derived_maps
from pimm_env.world.files import load_world
from tests.rooms import DEAD, ROUTES


@pytest.fixture
def two_rooms(room_file: Path, tmp_path: Path) -> list[str]:
    worlds = []
    for name in ("room_a", "room_b"):
        folder = tmp_path / name
        shutil.copytree(room_file.parent, folder)
        (folder / "scenarios.yaml").write_text(ROUTES)
        ensure_derived_maps(load_world(folder / "world.yaml"))
        worlds.append(str(folder / "world.yaml"))
    return worlds


def test_a_sweep_crosses_worlds_localizers_and_settings_into_one_table(two_rooms, tmp_path):
    spec = tmp_path / "sweep.yaml"
    spec.write_text(json.dumps({
        "worlds": two_rooms, "scenarios": ["there"], "trials": 1, "seed": 2,
        "localizers": {"dr": {"localizer": DEAD}, "amcl": {"min_particles": 100}},
        "grid": {"amcl": {"max_particles": [200, 300]}},
    }))  # fmt: skip
    assert [name for name, _, _ in rows_of(read_sweep(spec))] == [
        "dr", "amcl[max_particles=200]", "amcl[max_particles=300]",
    ]  # fmt: skip
    args = ["sweep", str(spec), "--workers", "1", "--out", str(tmp_path / "out"), "--json"]
    result = CliRunner().invoke(evaluate.app, args)
    assert result.exit_code == 0, result.output
    summary = json.loads(result.output.strip().splitlines()[-1])
    assert set(summary["scenarios"]) == {"room_a/there", "room_b/there"}
    row = summary["scenarios"]["room_b/there"]["amcl[max_particles=300]"]
    alone = run_shared([TrialSpec("there", "amcl", 0, 2, two_rooms[1], {"max_particles": 300, "min_particles": 100})])
    assert row["convergence_rate"] == float(alone[0].metrics.converged)
    assert row["per_trial"][0]["position_error_m"] == alone[0].metrics.position_error_m
    assert (Path(summary["folder"]) / "sweep.yaml").is_file()


def test_a_sweep_of_kidnaps_runs_that_many_kidnap_trials_of_each_route(tmp_path):
    spec = tmp_path / "sweep.yaml"
    spec.write_text("worlds: [iilab]\nscenarios: [area_b]\nlocalizers: {amcl: {}}\ntrials: 7\nkidnaps: 3\nseed: 4\n")
    specs = sweep_specs(read_sweep(spec))
    assert [(s.trial, s.seed, s.faults) for s in specs] == [(k, 4 + k, kidnap_trial_fault(4 + k)) for k in range(3)]


def test_a_bad_sweep_file_names_the_field(tmp_path):
    spec = tmp_path / "sweep.yaml"
    for text, message in (
        ("worlds: [iilab]\nlocalizers: {amcl: {}}\nruns: 3\n", "unknown key 'runs'"),
        ("worlds: []\nlocalizers: {amcl: {}}\n", "worlds: expected a non-empty list"),
        ("worlds: [iilab]\nlocalizers: {amcl: {}}\ngrid: {pimm: {x: [1]}}\n", "grid.pimm: no such label"),
        ("worlds: [iilab]\nlocalizers: {amcl: {}}\ngrid: {amcl: {max_particles: 5}}\n", "grid.amcl.max_particles"),
        ("worlds: [iilab]\nlocalizers: {amcl: {}}\nkidnaps: -1\n", "kidnaps: expected a whole number"),
    ):
        spec.write_text(text)
        with pytest.raises(ValueError, match=message):
            read_sweep(spec)
    spec.write_text("worlds: [iilab]\nlocalizers: {amcl: {particles: 5}}\n")
    result = CliRunner().invoke(evaluate.app, ["sweep", str(spec), "--out", str(tmp_path)])
    assert result.exit_code == 1 and "max_particles" in result.output  # the valid keys are listed


@pytest.mark.expensive  # Ray takes 10 s to start and its workers 20 s to import torch on this 2-core machine
def test_a_sweep_on_a_local_ray_gives_the_local_backends_metrics(two_rooms, tmp_path):
    pytest.importorskip("ray")
    spec = tmp_path / "sweep.yaml"
    spec.write_text(json.dumps({
        "worlds": two_rooms[:1], "trials": 2, "seed": 1,
        "localizers": {"dr": {"localizer": DEAD}, "amcl": {"max_particles": 300, "min_particles": 100}},
    }))  # fmt: skip

    def metrics(*backend: str) -> dict:
        args = [
            "sweep",
            str(spec),
            "--workers",
            "2",
            "--out",
            str(tmp_path / "_".join(backend or ("local",))),
            "--json",
        ]
        result = CliRunner().invoke(evaluate.app, [*args, *backend])
        assert result.exit_code == 0, result.output
        rows = json.loads(result.output.strip().splitlines()[-1])["scenarios"]
        return {(case, name): [{k: v for k, v in t.items() if k != "wall_s"} for t in row["per_trial"]]
                for case, by in rows.items() for name, row in by.items()}  # fmt: skip

    local, on_ray = metrics(), metrics("--backend", "ray")
    assert set(local) == {(s, n) for s in ("there", "there_kidnap") for n in ("dr", "amcl")}
    assert on_ray == local
