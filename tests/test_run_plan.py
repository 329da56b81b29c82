import json
from pathlib import Path

import pytest
import yaml
from typer.testing import CliRunner

import evaluate
from pimm_agents.experiments.run_plan import RunPlan, read_plan, resolve_localizers
from pimm_env.errors import ExperimentError, MissingFileError, PimmError


def test_a_plan_written_reads_back_equal_and_ignores_how_it_was_made(tmp_path):
    plan = RunPlan(
        "iilab", resolve_localizers(["amcl"], settings=["amcl.max_particles=500"]), ("area_b",), 2, 7,
        "thesis", "known", "dropout@5:2,kidnap@9", 2, 1,
    )  # fmt: skip
    path = plan.write(tmp_path / "run.yaml", made={"wall_s": 3.0, "trials_run": 4})
    assert read_plan(path) == plan
    assert yaml.safe_load(path.read_text())["made"]["trials_run"] == 4
    specs = plan.specs()
    assert [(s.trial, s.seed) for s in specs] == [(0, 7), (1, 8)]
    assert {(s.faults, s.walkers, s.unmapped, s.start) for s in specs} == {("dropout@5:2,kidnap@9", 2, 1, "known")}
    assert specs[0].params["max_particles"] == 500


def test_a_bad_plan_names_the_file_and_the_field(tmp_path):
    with pytest.raises(MissingFileError, match="no-such.yaml"):
        read_plan(tmp_path / "no-such.yaml")
    path = tmp_path / "run.yaml"
    for text, message in [
        ("world: iilab\nspeed: 3\n", "unknown field 'speed'"),
        ("trials: many\n", "trials: expected int"),
        ("localizers: {amcl: 5}\n", r"localizers.amcl: expected a mapping"),
        ("- a list\n", "holds a mapping, got list"),
    ]:
        path.write_text(text)
        with pytest.raises(ExperimentError, match=message):
            read_plan(path)
    localizers = resolve_localizers(["amcl"])
    for bad, message in [
        (RunPlan(localizers=localizers, scenarios=("moon",)), r"unknown scenario\(s\) \['moon'\].*area_a"),
        (RunPlan(localizers=localizers, start="somewhere"), "start: expected global or known"),
        (RunPlan(localizers=localizers, faults="fog@1"), "fog@1"),
        (RunPlan(localizers=localizers, sensors="no-such-lidar"), "no-such-lidar"),
        (RunPlan(localizers={}), "at least one"),
    ]:
        with pytest.raises(PimmError, match=message):
            bad.checked()


@pytest.mark.expensive
def test_run_from_its_own_record_repeats_a_run_with_walkers_and_a_fault_exactly(tmp_path):
    args = ["run", "--scenarios", "area_b", "--localizers", "amcl", "--trials", "1", "--seed", "3", "--workers", "1"]
    args += ["--set", "amcl.max_particles=500", "--walkers", "1", "--unmapped", "1", "--fault", "dropout@4:2"]
    first = CliRunner().invoke(evaluate.app, [*args, "--out", str(tmp_path / "a"), "--json"])
    assert first.exit_code == 0, first.output
    folder = Path(json.loads(first.output.strip().splitlines()[-1])["folder"])
    record = folder / "run.yaml"
    plan = read_plan(record)
    assert (plan.walkers, plan.unmapped, plan.faults, plan.seed) == (1, 1, "dropout@4:2", 3)
    again = CliRunner().invoke(evaluate.app, ["run", "--from", str(record), "--out", str(tmp_path / "b"), "--json"])
    assert again.exit_code == 0, again.output
    repeat = Path(json.loads(again.output.strip().splitlines()[-1])["folder"])
    log = "logs/area_b_amcl_trial00.csv"
    assert (repeat / log).read_text() == (folder / log).read_text()
    assert read_plan(repeat / "run.yaml") == plan
    plain = CliRunner().invoke(evaluate.app, [*args[:-6], "--out", str(tmp_path / "c"), "--json"])  # no movers, fault
    assert plain.exit_code == 0, plain.output
    other = Path(json.loads(plain.output.strip().splitlines()[-1])["folder"])
    assert (other / log).read_text() != (folder / log).read_text()  # the movers and the fault did change the run


def test_results_folders_made_in_one_second_do_not_collide(tmp_path):
    from pimm_agents.experiments.experiment import latest_folder, new_folder

    first, second = new_folder(tmp_path, "run"), new_folder(tmp_path, "run")
    other = new_folder(tmp_path, "run_plan")
    assert first != second and first.is_dir() and second.is_dir()
    assert second.name.startswith(first.name) or second.name[:19] > first.name[:19]
    assert latest_folder(tmp_path, "run") == second and latest_folder(tmp_path, "run_plan") == other


def test_kidnap_trials_replace_the_trials_of_each_route_and_leave_out_kidnap_scenarios():
    localizers = resolve_localizers(["amcl"])
    plan = RunPlan(localizers=localizers, trials=5, seed=3, faults="dropout@5:2", kidnaps=2).checked()
    assert "a_c_b_kidnap" not in plan.scenarios and "area_b" in plan.scenarios
    specs = plan.specs()
    assert len(specs) == 2 * len(plan.scenarios)
    first = [s for s in specs if s.scenario == "area_b"]
    assert [(s.trial, s.seed) for s in first] == [(0, 3), (1, 4)]
    assert first[0].faults.startswith("dropout@5:2,kidnap@") and first[0].faults.endswith(":anywhere")
    assert first[0].faults != first[1].faults  # each trial's kidnap time is its seed's
    with pytest.raises(ExperimentError, match=r"without a kidnap of their own.*\['a_c_b_kidnap'\]"):
        RunPlan(localizers=localizers, scenarios=("a_c_b_kidnap",), kidnaps=1).checked()


def test_maps_made_another_way_go_to_the_localizers_and_name_the_trials(room_file, tmp_path, monkeypatch):
    import shutil

    import pimm_agents.factory
    from pimm_agents.experiments.runner import run_shared
    from pimm_agents.experiments.trial_store import trial_key
    from pimm_env.mapping.derived_maps import ensure_derived_maps
    from pimm_env.world.files import load_world
    from tests.rooms import ROUTES

    (room_file.parent / "scenarios.yaml").write_text(ROUTES)
    ensure_derived_maps(load_world(room_file))
    other = tmp_path / "scanned" / "world.yaml"
    shutil.copytree(room_file.parent, other.parent)
    with pytest.raises(ExperimentError, match="maps: no world .*nowhere.yaml"):
        RunPlan(str(room_file), resolve_localizers(["amcl"]), maps=str(tmp_path / "nowhere.yaml")).checked()
    plan = RunPlan(str(room_file), resolve_localizers(["amcl"]), ("there",), 1, maps=str(other)).checked()
    spec = plan.specs()[0]
    assert spec.maps == str(other) and trial_key(spec).endswith("__maps-scanned")
    assert "maps" not in trial_key(RunPlan(str(room_file), resolve_localizers(["amcl"]), ("there",), 1).specs()[0])
    given = []

    def remember(name, world, **kwargs):
        given.append(world.source)
        raise ExperimentError("stop here")

    monkeypatch.setattr(pimm_agents.factory, "make_localizer", remember)
    with pytest.raises(ExperimentError, match="stop here"):
        run_shared([spec])
    assert [Path(p) for p in given] == [other]
