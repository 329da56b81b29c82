"""What a run is, as data: world, scenarios, localizers with their resolved settings, trials and seeds, sensors,
start, movers and faults. A results folder keeps it as ``run.yaml``; ``evaluate.py run --from run.yaml`` reads
it back and repeats the run trial for trial.

```yaml
world: iilab
scenarios: [area_a, a_c_b_kidnap]
localizers:                 # name (or module:factory) -> its params section, resolved (every key written)
  amcl: {max_particles: 2000, ...}
trials: 3
seed: 0                     # trial i uses seed + i
sensors: thesis
start: global
faults: dropout@30:5        # pimm_env/envs/faults.py
kidnaps: 0                  # N > 0: N kidnap trials per route scenario in place of `trials` (below)
walkers: 2
unmapped: 0
driver: route               # or policy:NAME (random, greedy, a policy's .zip): pimm_agents/active/driver.py
```

A ``made:`` section, if present, says how and where the run was made; it is not part of what is repeated.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

from pimm_agents.scoring.trial import TrialSpec
from pimm_env.errors import ExperimentError

STARTS = ("global", "known")


@dataclass(frozen=True)
class RunPlan:
    """A run, complete enough to repeat. ``scenarios`` empty means every scenario of the world."""

    world: str = "iilab"
    localizers: dict[str, dict[str, Any]] = field(default_factory=dict)
    scenarios: tuple[str, ...] = ()
    trials: int = 10  # thesis: 10 per scenario
    seed: int = 0
    sensors: str = "thesis"
    start: str = "global"
    faults: str = ""
    walkers: int = 0
    unmapped: int = 0
    driver: str = "route"
    #: N > 0: each scenario without a kidnap of its own runs N kidnap trials in place of ``trials``: trial k is
    #: kidnapped once, at a time and to a place drawn from its seed (``faults.kidnap_trial_fault``: anywhere in
    #: the free space, half the time into a twin of the place left)
    kidnaps: int = 0
    maps: str = ""  # the world whose maps the localizers take ("": the simulated world's; TrialSpec.maps)

    def checked(self) -> RunPlan:
        """This plan with its scenarios filled in from the world, after checking every field; a bad one raises a
        ``PimmError`` that names it."""
        from pimm_env.driving.scenarios import load_scenarios
        from pimm_env.envs.faults import parse_faults
        from pimm_env.sim.sensors import sensor_layouts
        from pimm_env.world.files import load_world

        if not self.localizers:
            raise ExperimentError("localizers: a run needs at least one")
        if self.trials < 1 or self.walkers < 0 or self.unmapped < 0 or self.kidnaps < 0:
            raise ExperimentError(
                f"trials must be >= 1 and walkers, unmapped, kidnaps >= 0, got {self.trials}, {self.walkers}, "
                f"{self.unmapped}, {self.kidnaps}"
            )
        if self.start not in STARTS:
            raise ExperimentError(f"start: expected {' or '.join(STARTS)}, got {self.start!r}")
        sensor_layouts(self.sensors)
        parse_faults(self.faults)
        check_driver(self.driver)
        known = load_scenarios(load_world(self.world))
        if self.maps:
            try:
                load_world(self.maps)
            except OSError as error:
                raise ExperimentError(f"maps: no world {self.maps!r} to take maps from ({error.strerror})") from None
        available = [n for n, s in known.items() if not self.kidnaps or s.kidnap_to is None]
        unknown = [s for s in self.scenarios if s not in available]
        if unknown:
            valid = ", ".join(available)
            what = "scenario(s) without a kidnap of their own (kidnaps)" if self.kidnaps else "scenario(s)"
            raise ExperimentError(f"unknown {what} {unknown} in world {self.world!r}; valid: {valid}")
        return RunPlan(**{**self.as_dict(), "scenarios": tuple(self.scenarios or available)})

    def specs(self) -> list[TrialSpec]:
        """Every trial, trial-major (a stopped run holds every scenario's first trials)."""
        from pimm_env.envs.faults import kidnap_trial_fault

        def faults(seed: int) -> str:
            return ",".join(filter(None, [self.faults, kidnap_trial_fault(seed) if self.kidnaps else ""]))

        return [
            TrialSpec(
                scenario,
                name,
                trial,
                self.seed + trial,
                self.world,
                params,
                self.sensors,
                self.start,
                faults=faults(self.seed + trial),
                walkers=self.walkers,
                unmapped=self.unmapped,
                driver=self.driver,
                maps=self.maps,
            )
            for trial in range(self.kidnaps or self.trials)
            for scenario in self.scenarios
            for name, params in self.localizers.items()
        ]

    def as_dict(self) -> dict[str, Any]:
        return {f.name: getattr(self, f.name) for f in fields(self)}

    def write(self, path: Path, made: Mapping[str, Any] | None = None) -> Path:
        """``path`` as YAML that :func:`read_plan` reads back to an equal plan; ``made`` goes under ``made:``."""
        import yaml

        data = {**self.as_dict(), "scenarios": list(self.scenarios)}
        if made:
            data["made"] = dict(made)
        Path(path).write_text(yaml.safe_dump(data, sort_keys=False, default_flow_style=None, width=120))
        return Path(path)


def check_driver(driver: str) -> None:
    """``route``, or ``policy:`` and a policy ``make_policy`` takes; else an error naming it."""
    from pimm_agents.active.driver import policy_name
    from pimm_agents.active.policies import check_policy

    name = policy_name(driver)
    if name is None:
        return
    try:
        check_policy(name)
    except (ValueError, FileNotFoundError) as error:  # the plan's field, as every other field's error says
        raise ExperimentError(f"driver {driver!r}: {error}") from None


def read_plan(path: Path) -> RunPlan:
    """The plan in a ``run.yaml``; every problem names the file and the field."""
    from pimm_env.yaml_file import read_yaml_mapping

    data = read_yaml_mapping(path, "run record (a results folder's run.yaml)", ExperimentError)
    data.pop("made", None)
    valid = [f.name for f in fields(RunPlan)]
    unknown = sorted(set(data) - set(valid))
    if unknown:
        raise ExperimentError(f"{path}: unknown field {unknown[0]!r}; valid fields: {', '.join(valid)}")
    kinds = {"world": str, "trials": int, "seed": int, "sensors": str, "start": str, "faults": str, "driver": str}
    kinds.update(walkers=int, unmapped=int, kidnaps=int, localizers=dict, scenarios=list)
    for name, kind in kinds.items():
        if name in data and not isinstance(data[name], kind):
            raise ExperimentError(f"{path}: {name}: expected {kind.__name__}, got {data[name]!r}")
    for name, section in data.get("localizers", {}).items():
        if not isinstance(section, dict):
            raise ExperimentError(f"{path}: localizers.{name}: expected a mapping of settings, got {section!r}")
    return RunPlan(**{**data, "scenarios": tuple(data.get("scenarios", ()))})


def resolve_localizers(
    names: Sequence[str] | None, params_file: Path | None = None, settings: Sequence[str] = ()
) -> dict[str, dict[str, Any]]:
    """``{name: resolved params}`` for the localizers to run (default: the params file's sections, else
    ``default_localizers``), from a params file and ``NAME.KEY=VALUE`` settings; a bad name or setting raises here."""
    from pimm_agents.factory import check_name, default_localizers, resolved_params
    from pimm_agents.params import merge_params, parse_settings, read_params_file

    from_file = read_params_file(params_file) if params_file is not None else {}
    chosen = list(names or from_file or default_localizers())
    for name in chosen:
        check_name(name)
    sections = merge_params(from_file, parse_settings(settings, chosen))
    return {name: resolved_params(name, sections.get(name)) for name in chosen}
