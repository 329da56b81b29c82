"""Build a localizer by name for a world: the one place that knows which localizers exist.

Three kinds of names:
- the built-in localizers (``pimm``, ``amcl`` and its variants), each a config dataclass plus a builder;
- ``package.module:factory``, a user's factory called as ``factory(world=World, **params)``;
- installed packages' factories, registered in the ``pimm.localizers`` entry-point group (same call).
"""

from __future__ import annotations

import importlib
import warnings
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from importlib.metadata import entry_points
from pathlib import Path
from typing import Any

from pimm_agents.localizer import Localizer
from pimm_agents.params import Params, apply_params, config_to_params, merge_params
from pimm_env.errors import LocalizerError, ParamsError
from pimm_env.world.files import load_world
from pimm_env.world.model import World

ENTRY_POINT_GROUP = "pimm.localizers"
PluginFactory = Callable[..., Localizer]


@dataclass(frozen=True)
class BuiltIn:
    """A built-in localizer: its default config (the thesis's or nav2's values) and how to build it."""

    default_config: Callable[[], Any]
    build: Callable[[World, Any, str, str | None], Localizer]  # world, config, name, sensor presets
    in_default_runs: bool = True  # run when no localizer is named (a preset for reproducing a paper is not)


#: The AMCL presets: nav2's default, the two recoveries, and nav2's other two laser models.
AMCL_PRESETS = ("amcl", "amcl-recovery", "amcl-recovery-nav2", "amcl-beam", "amcl-lfp")


def _amcl_config(preset: str) -> Callable[[], Any]:
    def make() -> Any:
        from pimm_agents.amcl.localizer import AMCL_BEAM, AMCL_LFP, AMCL_RECOVERY, AMCL_RECOVERY_NAV2, AmclConfig

        extra: dict[str, Mapping[str, Any]] = {
            "amcl": {},
            "amcl-recovery": AMCL_RECOVERY,
            "amcl-recovery-nav2": AMCL_RECOVERY_NAV2,
            "amcl-beam": AMCL_BEAM,
            "amcl-lfp": AMCL_LFP,
        }
        return apply_params(AmclConfig(), extra[preset], preset)

    return make


def _build_amcl(world: World, config: Any, name: str, sensors: str | None) -> Localizer:
    from pimm_agents.amcl.localizer import Amcl
    from pimm_env.mapping.derived_maps import load_derived_maps
    from pimm_env.sim.sensors import sensor_layouts

    return Amcl(load_derived_maps(world).occupancy, config, lidar=sensor_layouts(sensors)[1], name=name)


def _pimm_config(preset: str) -> Callable[[], Any]:
    def make() -> Any:
        from pimm_agents.pimm.config import PRESETS

        return PRESETS[preset]

    return make


def _build_pimm(world: World, config: Any, name: str, sensors: str | None) -> Localizer:
    from pimm_agents.perception.files import load_perception
    from pimm_agents.pimm.localizer import PimmLocalizer
    from pimm_env.mapping.derived_maps import load_derived_maps
    from pimm_env.mapping.twins import world_twins
    from pimm_env.sim.sensors import sensor_layouts

    maps = load_derived_maps(world)
    segmenter, fingerprints = load_perception(world)
    lidar3d = sensor_layouts(sensors)[0]
    twins, stale = world_twins(world, maps.occupancy)
    if stale is not None:
        import warnings

        warnings.warn(
            f"{stale} was made from another map or other twin settings and is not taken: each map cell's twins are"
            f" worked out when the robot first reaches it (tens of ms an update); `python evaluate.py world prepare"
            f" {world.name}` writes the table again",
            stacklevel=2,
        )
    return PimmLocalizer(
        maps.occupancy, maps.corners, segmenter, fingerprints, config, name=name, lidar3d=lidar3d, twins=twins
    )


def _registration_config() -> Any:
    from pimm_agents.registration.localizer import RegistrationConfig

    return RegistrationConfig()


def _build_registration(world: World, config: Any, name: str, sensors: str | None) -> Localizer:
    from pimm_agents.registration.localizer import RegistrationLocalizer
    from pimm_agents.registration.map_cloud import build_map_cloud
    from pimm_env.mapping.derived_maps import load_derived_maps
    from pimm_env.sim.sensors import sensor_layouts

    key = (str(world.source), world.source.stat().st_mtime if world.source else 0.0, config.voxel_m)
    cloud = _MAP_CLOUDS.get(key)
    if cloud is None:  # sampled and described once per process and world (~15 s for the iilab here)
        cloud = _MAP_CLOUDS[key] = build_map_cloud(world, load_derived_maps(world).occupancy, config.voxel_m)
    return RegistrationLocalizer(cloud, config, lidar3d=sensor_layouts(sensors)[0], name=name)


#: Map clouds already built in this process, by world file, its modification time and the voxel size.
_MAP_CLOUDS: dict[tuple[str, float, float], Any] = {}


BUILT_IN: dict[str, BuiltIn] = {
    "pimm": BuiltIn(_pimm_config("pimm"), _build_pimm),
    "pimm-thesis": BuiltIn(_pimm_config("pimm-thesis"), _build_pimm, in_default_runs=False),
    **{name: BuiltIn(_amcl_config(name), _build_amcl) for name in AMCL_PRESETS},
    "registration": BuiltIn(_registration_config, _build_registration),
}


def _installed() -> dict[str, Any]:
    return {ep.name: ep for ep in entry_points(group=ENTRY_POINT_GROUP) if ep.name not in BUILT_IN}


def default_localizers() -> list[str]:
    """The localizers a run uses when none is named: the built-ins (less the reproduction presets) and plugins."""
    return [*(name for name, b in BUILT_IN.items() if b.in_default_runs), *sorted(_installed())]


def available_localizers() -> list[str]:
    """Every registered name: the built-in localizers, then those of installed packages."""
    return [*BUILT_IN, *sorted(_installed())]


def is_plugin_spec(name: str) -> bool:
    return ":" in name


def plugin_factory(name: str) -> PluginFactory:
    """The factory behind ``module:attribute`` or an installed package's registered name."""
    installed = _installed()
    if name in installed:
        return installed[name].load()
    if not is_plugin_spec(name):
        raise LocalizerError(
            f"unknown localizer {name!r}; valid: {', '.join(available_localizers())} or module:factory"
        )
    module_name, _, attribute = name.partition(":")
    try:
        module = importlib.import_module(module_name)
    except ImportError as error:
        raise LocalizerError(f"localizer {name!r}: cannot import module {module_name!r}: {error}") from None
    factory = getattr(module, attribute, None)
    if not callable(factory):
        raise LocalizerError(f"localizer {name!r}: module {module_name!r} has no callable {attribute!r}")
    return factory


def check_name(name: str) -> None:
    """Raise ``ValueError`` naming the valid localizers if ``name`` is none of them (imports a plugin's module)."""
    if name not in BUILT_IN:
        plugin_factory(name)


def resolve_config(name: str, params: Mapping[str, Any] | None = None) -> Any:
    """The config a built-in localizer would run with: its defaults with ``params`` applied."""
    if name not in BUILT_IN:
        raise LocalizerError(f"{name!r} is not a built-in localizer; built-in: {', '.join(BUILT_IN)}")
    return apply_params(BUILT_IN[name].default_config(), dict(params or {}), name)


def resolved_params(name: str, params: Mapping[str, Any] | None = None) -> Params:
    """What a run's ``config.yaml`` records for ``name``: every field for a built-in, the given params otherwise."""
    if name in BUILT_IN:
        return config_to_params(resolve_config(name, params))
    return dict(params or {})


#: The built-in localizers that need nothing but an occupancy map.
MAP_ONLY = AMCL_PRESETS


def make_localizer(
    name: str,
    world: str | World = "iilab",
    params: Mapping[str, Any] | None = None,
    map: str | Path | None = None,
    sensors: str | None = None,
    **overrides: Any,
) -> Localizer:
    """The localizer ``name`` for ``world`` (a name, a world file or a loaded world), or, with ``map`` (a
    map_server ``.yaml``, PGM or PNG), from that map alone: the AMCLs run from a map; PIMM needs a prepared
    world (corner and fingerprint maps) and says so; a plugin's factory gets ``world=None, map=PATH``.
    ``sensors`` names the LiDAR presets the data comes from (``pimm_env.sim.sensors``; None: the thesis's).

    ``params`` is its params-file section; keyword arguments override fields on top of it, nested as the
    config is (``max_particles=500``; ``corners={"planes": {"method": "open3d"}}`` for PIMM).
    """
    settings = merge_params(params or {}, overrides)
    if map is not None:
        return _from_map(name, Path(map), settings, sensors)
    loaded = world if isinstance(world, World) else load_world(world)
    if name in BUILT_IN:
        return BUILT_IN[name].build(loaded, resolve_config(name, settings), name, sensors)
    localizer = plugin_factory(name)(world=loaded, **settings)
    for attribute in ("update", "reset"):
        if not callable(getattr(localizer, attribute, None)):
            raise LocalizerError(f"localizer {name!r}: its factory returned {localizer!r}, which has no {attribute}()")
    return localizer


__all__ = ["ParamsError", "available_localizers", "make_localizer", "resolve_config", "resolved_params"]


def _from_map(name: str, map_path: Path, settings: Params, sensors: str | None) -> Localizer:
    from pimm_agents.amcl.localizer import Amcl
    from pimm_env.mapping.map_server import load_map_server
    from pimm_env.sim.sensors import sensor_layouts

    if name in MAP_ONLY:
        if sensors is None:  # a bare scan array does not say its angles: say what is assumed
            warnings.warn(
                f"make_localizer({name!r}, map=...) without sensors= reads each scan as the thesis's 2D LiDAR"
                " (360 beams over 360 deg from -180 deg); a scan of as many beams over another field of view would"
                " be read at the wrong angles: pass sensors= a preset (e.g. 'sick-lms200') or a sensors .yaml",
                stacklevel=3,
            )
        lidar = sensor_layouts(sensors)[1]
        return Amcl(load_map_server(map_path), resolve_config(name, settings), lidar=lidar, name=name)
    if name in BUILT_IN:
        raise LocalizerError(
            f"localizer {name!r} needs a prepared world (corner map, fingerprint map), not a map alone: "
            f"python evaluate.py world import {map_path} --name NAME, then --world NAME"
        )
    localizer = plugin_factory(name)(world=None, map=map_path, **settings)
    for attribute in ("update", "reset"):
        if not callable(getattr(localizer, attribute, None)):
            raise LocalizerError(f"localizer {name!r}: its factory returned {localizer!r}, which has no {attribute}()")
    return localizer
