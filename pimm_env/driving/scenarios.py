"""Named evaluation scenarios: a start pose, a waypoint path and a speed (thesis chapter 4)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pimm_env.errors import MissingFileError, WorldError
from pimm_env.world.files import resolve_world_path, world_dir
from pimm_env.world.model import World


@dataclass(frozen=True)
class Scenario:
    name: str
    start: np.ndarray
    waypoints: np.ndarray
    speed: float
    description: str = ""
    thesis_length_m: float | None = None
    thesis_duration_s: float | None = None
    kidnap_to: np.ndarray | None = None  # set for kidnap scenarios: run the path, teleport here, run again

    @property
    def length(self) -> float:
        """Length of the waypoint path (m), once; kidnap scenarios drive it twice."""
        return float(np.linalg.norm(np.diff(self.waypoints, axis=0), axis=1).sum())


def scenarios_path(world: str | World) -> Path:
    """``scenarios.yaml`` beside the world file of ``world`` (a name, a world file or a loaded world)."""
    folder = world_dir(world) if isinstance(world, World) else resolve_world_path(world).parent
    return folder / "scenarios.yaml"


def load_scenarios(world: str | World = "iilab", path: Path | None = None) -> dict[str, Scenario]:
    import yaml

    path = Path(path or scenarios_path(world))
    if not path.is_file():
        name = world.name if isinstance(world, World) else world
        raise MissingFileError(f"world {name!r} has no scenarios file {path}")
    raw = yaml.safe_load(path.read_text()).get("scenarios") or {}
    out: dict[str, Scenario] = {}
    for name, spec in raw.items():
        base = raw.get(spec["base"], {}) if "base" in spec else spec
        if "base" in spec and spec["base"] not in raw:
            raise WorldError(f"{path}: scenarios.{name}.base: unknown scenario {spec['base']!r}")
        out[name] = Scenario(
            name=name,
            start=np.asarray(base["start"], dtype=float),
            waypoints=np.asarray(base["waypoints"], dtype=float),
            speed=float(base["speed"]),
            description=str(spec.get("description", "")).strip(),
            thesis_length_m=base.get("thesis_length_m"),
            thesis_duration_s=base.get("thesis_duration_s"),
            kidnap_to=np.asarray(spec["kidnap_to"], dtype=float) if "kidnap_to" in spec else None,
        )
    return out


def get_scenario(name: str, world: str | World = "iilab") -> Scenario:
    scenarios = load_scenarios(world)
    if name not in scenarios:
        raise WorldError(f"unknown scenario {name!r}; valid: {', '.join(scenarios)}")
    return scenarios[name]
