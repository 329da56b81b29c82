"""A study as one file: worlds x scenarios x localizers x settings x trials, run into one results folder.

```yaml
worlds: [iilab]                      # names or world files
scenarios: [area_b, a_c_b]           # optional: every scenario of each world
localizers:                          # label: {localizer: factory name (default: the label), settings...}
  pimm: {}
  amcl-small: {localizer: amcl, max_particles: 500}
grid:                                # optional: settings to cross, per label (dotted keys for nested ones)
  pimm: {filter.num_particles: [2000, 10000]}
trials: 3                            # seeds seed, seed + 1, ...
kidnaps: 0                           # N > 0: N kidnap trials per route scenario in place of trials (RunPlan)
seed: 0
sensors: thesis
start: global
```

Each combination of a label's grid values is its own row, named ``pimm[filter.num_particles=2000]``.
With several worlds, a scenario's row is named ``WORLD/SCENARIO``.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pimm_agents.scoring.trial import TrialSpec
from pimm_env.errors import ExperimentError

KEYS = ("worlds", "scenarios", "localizers", "grid", "trials", "kidnaps", "seed", "sensors", "start")


@dataclass(frozen=True)
class Sweep:
    worlds: list[str]
    localizers: dict[str, dict[str, Any]]
    scenarios: list[str] | None = None
    grid: dict[str, dict[str, list[Any]]] = field(default_factory=dict)
    trials: int = 3
    seed: int = 0
    sensors: str = "thesis"
    start: str = "global"
    kidnaps: int = 0  # as RunPlan.kidnaps


def read_sweep(path: Path) -> Sweep:
    """The sweep in ``path``; every problem names the file and the field."""
    from pimm_env.yaml_file import read_yaml_mapping

    data = read_yaml_mapping(path, "sweep file", ExperimentError)
    unknown = sorted(set(data) - set(KEYS))
    if unknown:
        raise ExperimentError(f"{path}: unknown key {unknown[0]!r}; valid keys: {', '.join(KEYS)}")
    worlds, localizers = data.get("worlds"), data.get("localizers")
    if not isinstance(worlds, list) or not worlds or not all(isinstance(w, str) for w in worlds):
        raise ExperimentError(f"{path}: worlds: expected a non-empty list of world names or files, got {worlds!r}")
    if not isinstance(localizers, dict) or not localizers:
        raise ExperimentError(f"{path}: localizers: expected a mapping of label -> settings, got {localizers!r}")
    for label, settings in localizers.items():
        if settings is not None and not isinstance(settings, dict):
            raise ExperimentError(f"{path}: localizers.{label}: expected a mapping of settings, got {settings!r}")
    grid = data.get("grid") or {}
    for label, axes in grid.items():
        if label not in localizers:
            raise ExperimentError(f"{path}: grid.{label}: no such label under localizers ({', '.join(localizers)})")
        for key, values in (axes or {}).items():
            if not isinstance(values, list) or not values:
                raise ExperimentError(
                    f"{path}: grid.{label}.{key}: expected a non-empty list of values, got {values!r}"
                )
    trials = data.get("trials", 3)
    if not isinstance(trials, int) or trials < 1:
        raise ExperimentError(f"{path}: trials: expected a positive integer, got {trials!r}")
    kidnaps = data.get("kidnaps", 0)
    if not isinstance(kidnaps, int) or kidnaps < 0:
        raise ExperimentError(f"{path}: kidnaps: expected a whole number >= 0, got {kidnaps!r}")
    scenarios = data.get("scenarios")
    if scenarios is not None and (not isinstance(scenarios, list) or not scenarios):
        raise ExperimentError(f"{path}: scenarios: expected a non-empty list, got {scenarios!r}")
    return Sweep(
        worlds=worlds,
        localizers={label: dict(settings or {}) for label, settings in localizers.items()},
        scenarios=scenarios,
        grid={label: dict(axes or {}) for label, axes in grid.items()},
        trials=trials,
        seed=int(data.get("seed", 0)),
        sensors=str(data.get("sensors", "thesis")),
        start=str(data.get("start", "global")),
        kidnaps=kidnaps,
    )


def _settings(factory: str, flat: dict[str, Any]) -> dict[str, Any]:
    """Flat settings (dotted keys allowed) as a nested params section, checked against the factory's config."""
    from pimm_agents.factory import resolved_params
    from pimm_agents.params import merge_params, parse_settings

    nested = parse_settings([f"{factory}.{key}={value}" for key, value in flat.items()], [factory])
    return resolved_params(factory, merge_params({}, nested).get(factory))


def rows_of(sweep: Sweep) -> list[tuple[str, str, dict[str, Any]]]:
    """(row label, factory name, resolved settings) for every localizer label and grid combination."""
    rows = []
    for label, settings in sweep.localizers.items():
        fixed = dict(settings)
        factory = str(fixed.pop("localizer", label))
        axes = sweep.grid.get(label, {})
        for values in itertools.product(*axes.values()) if axes else [()]:
            chosen = dict(zip(axes, values, strict=True))
            name = label + (f"[{','.join(f'{k}={v}' for k, v in chosen.items())}]" if chosen else "")
            rows.append((name, factory, _settings(factory, {**fixed, **chosen})))
    return rows


def sweep_specs(sweep: Sweep) -> list[TrialSpec]:
    """Every trial of the sweep, trial-major (a stopped sweep has every row's first trials)."""
    from pimm_agents.experiments.trial_store import world_label
    from pimm_env.driving.scenarios import load_scenarios
    from pimm_env.envs.faults import kidnap_trial_fault
    from pimm_env.world.files import load_world

    rows = rows_of(sweep)
    cases = []
    for world in sweep.worlds:
        known = load_scenarios(load_world(world))
        available = [n for n, s in known.items() if not sweep.kidnaps or s.kidnap_to is None]
        chosen = sweep.scenarios or available
        missing = [s for s in chosen if s not in available]
        if missing:
            what = "scenario(s) without a kidnap of their own (kidnaps)" if sweep.kidnaps else "scenario(s)"
            raise ExperimentError(f"world {world!r} has no {what} {missing}; it has {', '.join(available)}")
        for scenario in chosen:
            cases.append((world, scenario, f"{world_label(world)}/{scenario}" if len(sweep.worlds) > 1 else ""))
    seeds = range(sweep.seed, sweep.seed + (sweep.kidnaps or sweep.trials))

    def fault(seed: int) -> str:
        return kidnap_trial_fault(seed) if sweep.kidnaps else ""

    setup = (sweep.sensors, sweep.start)
    return [
        TrialSpec(scenario, factory, seed - sweep.seed, seed, world, params, *setup, name, row, fault(seed))
        for seed in seeds
        for world, scenario, row in cases
        for name, factory, params in rows
    ]
