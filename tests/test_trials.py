import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import yaml
from typer.testing import CliRunner

import evaluate
from pimm_agents.experiments.runner import group_by_simulation, run_shared, run_trials
from pimm_agents.experiments.trial_store import load_stored, load_trial, save_trial, trial_key
from pimm_agents.scoring.trial import TrialSpec
from tests.rooms import AMCL, DEAD, READER, ROUTES


@pytest.fixture
def room_with_routes(room_file: Path) -> str:
    from pimm_env.mapping.derived_maps import ensure_derived_maps
    from pimm_env.world.files import load_world

    (room_file.parent / "scenarios.yaml").write_text(ROUTES)
    ensure_derived_maps(load_world(room_file))
    return str(room_file)


def _spec(world: str, localizer: str, scenario: str = "there", seed: int = 4, params=None) -> TrialSpec:
    return TrialSpec(scenario, localizer, 0, seed, world, params if params is not None else {})


def _same_log(a, b) -> bool:
    return a.kidnap_index == b.kidnap_index and all(
        np.array_equal(getattr(a, k), getattr(b, k)) for k in ("time", "estimate_time", "true", "estimate", "cov")
    )


@pytest.mark.parametrize("scenario", ["there", "there_kidnap"])
def test_one_simulation_feeds_every_localizer_as_separate_runs_would(room_with_routes, scenario):
    amcl, reader = _spec(room_with_routes, "amcl", scenario, params=AMCL), _spec(room_with_routes, READER, scenario)
    alone = run_shared([amcl])[0]  # no localizer reads the cloud: the simulation casts none
    shared = run_shared([amcl, reader])  # the reader needs the cloud: the same simulation now casts it
    assert shared[0].spec == amcl and shared[1].spec == reader
    assert _same_log(alone.log, shared[0].log) and alone.metrics == shared[0].metrics
    assert len(alone.log) > 50 and (scenario != "there_kidnap" or alone.log.kidnap_index is not None)
    assert shared[1].log.kidnap_index == alone.log.kidnap_index


def test_specs_are_grouped_by_the_simulation_they_share(room_with_routes):
    specs = [_spec(room_with_routes, name, seed=seed) for seed in (1, 2) for name in ("amcl", DEAD)]
    assert group_by_simulation(specs) == [[0, 1], [2, 3]]
    with pytest.raises(ValueError, match="simulate different trials"):
        run_shared(specs)
    seen = []
    results = run_trials(specs, workers=1, on_done=lambda r: seen.append(r.spec))
    assert [r.spec for r in results] == specs and sorted(seen, key=specs.index) == specs


def test_a_saved_trial_loads_back_whole(room_with_routes, tmp_path):
    result = run_shared([_spec(room_with_routes, "amcl", "there_kidnap", params=AMCL)])[0]
    result.log.corners = np.array([[3.0, 1.5, 2.5], [40.0, 0.1, 0.2]])  # as PIMM's would be: row, x, y
    path = save_trial(tmp_path, result)
    assert path.name == f"{trial_key(result.spec)}.npz" and path.stem.startswith("room__there_kidnap__amcl__")
    back = load_trial(path)
    assert back.spec == result.spec and back.metrics == result.metrics and _same_log(back.log, result.log)
    assert back.log.timings == result.log.timings and back.completed == result.completed
    assert np.array_equal(back.log.corners, result.log.corners)
    other = _spec(room_with_routes, "amcl", "there_kidnap", params={**AMCL, "max_particles": 301})
    assert trial_key(other) != trial_key(result.spec)  # a changed setting is a different trial
    assert list(load_stored(tmp_path, [other, result.spec])) == [1]
    (tmp_path / "trials" / "broken.npz").write_text("no")
    with pytest.raises(ValueError, match="broken.npz"):
        load_trial(tmp_path / "trials" / "broken.npz")


def test_resume_runs_only_the_missing_trials_and_gives_the_full_runs_metrics(room_with_routes, tmp_path):
    def run(out: Path, trials: int, *extra: str) -> dict:
        args = ["run", "--world", room_with_routes, "--scenarios", "there", "--localizers", DEAD, "amcl"]
        args += ["--set", "amcl.max_particles=300", "--set", "amcl.min_particles=100", "--workers", "1"]
        args += ["--trials", str(trials), "--out", str(out), "--json", *extra]
        result = CliRunner().invoke(evaluate.app, evaluate.expand_list_options(args))
        assert result.exit_code == 0, result.output
        return json.loads(result.output.strip().splitlines()[-1])

    first = run(tmp_path / "a", 1)
    extended = run(tmp_path / "a", 2, "--resume")
    assert extended["folder"] == first["folder"]  # continued in place
    record = yaml.safe_load((Path(extended["folder"]) / "run.yaml").read_text())["made"]
    assert (record["trials_run"], record["trials_reused"]) == (2, 2)  # 2 localizers x 1 new trial
    assert len(list((Path(extended["folder"]) / "trials").glob("*.npz"))) == 4
    whole = run(tmp_path / "b", 2)

    def no_timings(summary: dict) -> dict:  # what the machine's speed changes: timings and wall times
        rows = {
            name: {k: v for k, v in row.items() if k != "timings_ms"}
            for name, row in summary["scenarios"]["there"].items()
        }
        for row in rows.values():
            row["per_trial"] = [{k: v for k, v in t.items() if k != "wall_s"} for t in row["per_trial"]]
        return rows

    assert no_timings(extended) == no_timings(whole)
    assert run(tmp_path / "a", 2, "--resume")["folder"] == first["folder"]
    assert yaml.safe_load((Path(first["folder"]) / "run.yaml").read_text())["made"]["trials_run"] == 0


def test_a_known_start_gives_every_localizer_the_true_pose(room_with_routes):
    known = [TrialSpec("there", name, 0, 3, room_with_routes, AMCL if name == "amcl" else {}, start="known")
             for name in ("amcl", DEAD)]  # fmt: skip
    amcl, dead = run_shared(known)
    start = np.array([1.0, 1.0, 0.0])
    assert np.allclose(dead.log.estimate[0], start, atol=1e-6)  # dead reckoning from the true start
    assert np.hypot(*(amcl.log.estimate[0, :2] - start[:2])) < 1.0 and amcl.metrics.convergence_time_s == 0.0
    assert trial_key(known[0]).endswith("__start-known") and trial_key(known[0]) != trial_key(
        replace(known[0], start="global")
    )
    with pytest.raises(ValueError, match="start must be one of"):
        run_shared([replace(known[0], start="somewhere")])


def test_an_unknown_backend_is_refused(room_with_routes):
    with pytest.raises(ValueError, match="expected local or ray"):
        run_trials([_spec(room_with_routes, "amcl", params=AMCL)], backend="dask")


def test_a_trial_whose_robot_hits_the_post_is_counted_as_a_collision(room_file, tmp_path):
    from pimm_agents.experiments.trial_store import load_trial, save_trial
    from pimm_agents.results.tables import format_collisions
    from pimm_agents.scoring.summaries import summary_of

    (room_file.parent / "scenarios.yaml").write_text(
        ROUTES + "  through_post:\n    start: [4.5, 0.8, 1.5708]\n    waypoints: [[4.5, 0.8], [4.5, 3.2]]\n"
        "    speed: 0.5\n"
    )
    from pimm_env.mapping.derived_maps import ensure_derived_maps
    from pimm_env.world.files import load_world

    ensure_derived_maps(load_world(room_file))
    world = str(room_file)
    hit = run_shared([_spec(world, DEAD, "through_post")])[0]
    clear = run_shared([_spec(world, DEAD, "there")])[0]
    assert hit.collided and not clear.collided
    summary = summary_of([hit, clear])
    assert summary["scenarios"]["through_post"][DEAD]["collisions"] == 1
    assert summary["scenarios"]["there"][DEAD]["collisions"] == 0
    assert summary["scenarios"]["through_post"][DEAD]["per_trial"][0]["collided"] is True
    assert "through_post: 1 of 1 trial(s)" in format_collisions(summary) and "there:" not in format_collisions(summary)
    saved = save_trial(tmp_path, hit)
    assert load_trial(saved).collided


@pytest.mark.parametrize("scenario", ["there", "there_kidnap"])
def test_a_policy_drives_the_scenario_for_as_long_as_its_route_would(room_with_routes, scenario):
    spec = replace(_spec(room_with_routes, "amcl", scenario, params=AMCL), driver="policy:greedy")
    first, again = run_shared([spec])[0], run_shared([spec])[0]
    assert _same_log(first.log, again.log)  # the same seed drives the same way
    laps = 2 if scenario == "there_kidnap" else 1
    assert first.log.time[-1] == pytest.approx(laps * 4.5 / 0.5, abs=1.1)  # 4.5 m at 0.5 m/s, a primitive's slack
    assert (first.log.kidnap_index is not None) == (scenario == "there_kidnap") and not first.collided
    moved = np.hypot(*(first.log.true[-1, :2] - first.log.true[0, :2]))
    assert moved > 0.3 or scenario == "there_kidnap"
    route = run_shared([replace(spec, driver="route")])[0]
    assert not np.array_equal(route.log.true[-1], first.log.true[-1])  # not the waypoints' path


def test_a_kidnap_leg_starts_the_policy_afresh_as_its_guide_and_explorer(room_with_routes, monkeypatch):
    from pimm_agents.active import policies

    resets: list[int | None] = []

    class Watched(policies.Greedy):
        def reset(self, seed: int | None = None) -> None:
            resets.append(seed)
            super().reset(seed)

    monkeypatch.setattr(policies, "make_policy", lambda name, max_range=20.0: Watched(max_range))
    spec = replace(_spec(room_with_routes, "amcl", "there_kidnap", params=AMCL), driver="policy:greedy")
    run_shared([spec])
    assert resets[-2:] == [4, 5]  # seed 4: once at the start (after the constructor's own reset), once after


def test_policy_driven_specs_simulate_alone_and_are_stored_apart(room_with_routes, tmp_path):
    specs = [replace(_spec(room_with_routes, name), driver="policy:random") for name in ("amcl", DEAD)]
    assert group_by_simulation(specs) == [[0], [1]]  # each drives on its own localizer's belief
    assert trial_key(specs[0]) != trial_key(replace(specs[0], driver="route"))
    args = ["run", "--world", room_with_routes, "--localizers", DEAD, "--scenarios", "there", "--trials", "1"]
    result = CliRunner().invoke(evaluate.app, [*args, "--driver", "policy:random", "--json", "--out", str(tmp_path)])
    assert result.exit_code == 0, result.output
    folder = Path(json.loads(result.output)["folder"])
    assert yaml.safe_load((folder / "run.yaml").read_text())["driver"] == "policy:random"
    assert any("driver-policy-random" in p.name for p in (folder / "trials").iterdir())


def test_a_bad_driver_is_refused_by_name(room_with_routes):
    from pimm_agents.experiments.run_plan import RunPlan

    plan = RunPlan(room_with_routes, {"amcl": {}}, trials=1)
    with pytest.raises(ValueError, match="expected 'route' or 'policy:NAME'"):
        replace(plan, driver="wander").checked()
    with pytest.raises(ValueError, match="nope.zip does not exist"):
        replace(plan, driver="policy:nope.zip").checked()
    assert replace(plan, driver="policy:greedy").checked().driver == "policy:greedy"
