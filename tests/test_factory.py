import json
from importlib.metadata import EntryPoint

import numpy as np
import pytest
import yaml
from typer.testing import CliRunner

import evaluate
import pimm_agents.factory as factory
from pimm_agents import make_localizer
from pimm_env.errors import ParamsError

PLUGIN = "tests.plugins.dead_reckoning:make"


def test_a_users_module_factory_builds_a_localizer_with_its_params():
    localizer = make_localizer(PLUGIN, spread=2.5)
    assert localizer.spread == 2.5 and localizer.sensors == ("odom",)
    with pytest.raises(ValueError, match="no callable 'nothing'"):
        make_localizer("tests.plugins.dead_reckoning:nothing")
    with pytest.raises(ValueError, match="cannot import module 'no_such_pkg'"):
        make_localizer("no_such_pkg:make")


def test_installed_entry_points_are_registered(monkeypatch):
    point = EntryPoint(name="dead-reckoning", value=PLUGIN, group=factory.ENTRY_POINT_GROUP)
    monkeypatch.setattr(factory, "entry_points", lambda group: [point] if group == factory.ENTRY_POINT_GROUP else [])
    assert factory.available_localizers()[-1] == "dead-reckoning"
    assert make_localizer("dead-reckoning").name == "dead-reckoning"


def test_nested_configs_take_namespaced_settings_and_refuse_unknown_keys():
    config = factory.resolve_config("pimm", {"corners": {"min_inliers": 30}, "rivals": {"settle_scans": 12}})
    assert config.corners.min_inliers == 30 and config.corners.planes.min_inliers == 30
    assert config.rivals.settle_scans == 12
    with pytest.raises(ParamsError, match=r"pimm.corners: unknown key 'inliers'; valid keys: .*min_inliers"):
        factory.resolve_config("pimm", {"corners": {"inliers": 30}})
    with pytest.raises(ParamsError, match="pimm.filter.num_particles: expected a int, got 'many'"):
        factory.resolve_config("pimm", {"filter": {"num_particles": "many"}})
    with pytest.raises(ParamsError, match="corners.min_inliers must be at least 3"):
        factory.resolve_config("pimm", {"corners": {"min_inliers": 1}})


def test_the_two_presets_are_the_default_and_the_thesis_filter_as_published():
    from pimm_agents.pimm.config import PRESETS, PimmConfig

    assert factory.resolve_config("pimm") == PimmConfig() == PRESETS["pimm"]
    thesis = factory.resolve_config("pimm-thesis")
    assert thesis.filter.thesis and not thesis.wall_field.enabled and not thesis.rivals.enabled
    f = thesis.filter  # what the thesis published: a fixed set, nearest corners, the mean of the heaviest
    assert (f.adaptive, f.mode_min_particles, f.mode_evidence, f.estimate_bin_xy, f.orientation_bins) == (
        False, 0, "sum", 0.0, 1,
    )  # fmt: skip
    assert thesis.filter.num_particles == 10_000 and thesis.filter.alpha == 0.8  # table 3.5 in both
    assert "pimm-thesis" in factory.available_localizers() and "pimm-thesis" not in factory.default_localizers()
    # the preset takes the same params as the default
    assert factory.resolve_config("pimm-thesis", {"filter": {"num_particles": 500}}).filter.thesis


def test_resolved_params_read_back_to_the_same_config(tmp_path):
    from pimm_agents.params import read_params_file, write_params_file

    configs = {name: factory.resolved_params(name, {}) for name in factory.BUILT_IN}
    path = write_params_file(tmp_path / "config.yaml", configs)
    again = read_params_file(path)
    for name in factory.BUILT_IN:
        assert factory.resolve_config(name, again[name]) == factory.resolve_config(name)


def test_a_plugin_localizer_runs_from_the_command_line(tmp_path):
    args = ["run", "--localizers", PLUGIN, "--scenarios", "area_b", "--trials", "1", "--workers", "1"]
    args += ["--set", f"{PLUGIN}.spread=0.5", "--out", str(tmp_path), "--json"]
    result = CliRunner().invoke(evaluate.app, args)
    assert result.exit_code == 0, result.output
    data = json.loads(result.output.strip().splitlines()[-1])
    row = data["scenarios"]["area_b"][PLUGIN]
    assert row["trials"] == 1 and row["convergence_rate"] == 0.0  # it starts at the origin: never near the truth
    folder = next(tmp_path.iterdir())
    assert yaml.safe_load((folder / "config.yaml").read_text()) == {PLUGIN: {"spread": 0.5}}
    assert sorted(p.name for p in (folder / "logs").iterdir()) == [
        f"area_b_tests.plugins.dead_reckoning-make_trial00.{ext}" for ext in ("csv", "json")
    ]


def test_a_map_only_localizer_without_sensors_says_which_lidar_it_assumes():
    import warnings

    with warnings.catch_warnings(record=True) as heard:
        warnings.simplefilter("always")
        factory.make_localizer("amcl", map="maps/iilab/occupancy.yaml")
        factory.make_localizer("amcl", map="maps/iilab/occupancy.yaml", sensors="sick-lms200")
    assert len(heard) == 1 and "sensors=" in str(heard[0].message) and "360 beams over 360 deg" in str(heard[0].message)


def test_a_twins_table_made_with_other_settings_is_said_and_not_taken(tmp_path):
    import shutil
    from dataclasses import replace

    from pimm_agents.factory import make_localizer
    from pimm_env.mapping.derived_maps import load_derived_maps
    from pimm_env.mapping.twins import TWINS_FILE, MapTwins, TwinConfig
    from pimm_env.world.files import MAPS_DIR, load_world

    shutil.copytree(MAPS_DIR / "iilab", tmp_path / "iilab")
    world = load_world(tmp_path / "iilab" / "world.yaml")
    stale = MapTwins(load_derived_maps(world).occupancy, replace(TwinConfig(), max_twins=6))
    stale.of(np.array([-10.0, 4.2, 0.0]))
    stale.save(tmp_path / "iilab" / TWINS_FILE)
    with pytest.warns(UserWarning, match="twins.npz was made from another map or other twin settings"):
        make_localizer("pimm", world)
