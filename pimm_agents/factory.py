"""Build a localizer by name for a world: the one place that knows which localizers exist."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import fields, replace
from typing import Any

from pimm_agents.localizer import Localizer
from pimm_env.sim.lidar import Lidar2DConfig
from pimm_env.world.files import World, load_world


def _amcl(world: World, overrides: dict[str, Any], name: str, preset: dict[str, Any]) -> Localizer:
    from pimm_agents.amcl.localizer import Amcl, AmclConfig
    from pimm_env.mapping.derived_maps import load_derived_maps

    config = _configured(AmclConfig(), {**preset, **overrides}, name)
    lidar = overrides.get("lidar2d") or Lidar2DConfig()
    return Amcl(load_derived_maps(world).occupancy, config, lidar, name=name)


def _configured(config: Any, overrides: dict[str, Any], name: str) -> Any:
    known = {f.name for f in fields(config)}
    unknown = sorted(set(overrides) - known - {"lidar2d"})
    if unknown:
        raise ValueError(f"localizer {name!r} has no setting(s) {unknown}; valid: {', '.join(sorted(known))}")
    return replace(config, **{k: v for k, v in overrides.items() if k in known})


def _pimm(world: World, overrides: dict[str, Any]) -> Localizer:
    """Settings may name a field of PimmConfig or of its FeatureFilterConfig (``num_particles=2000``)."""
    from pimm_agents.perception.files import load_perception
    from pimm_agents.pimm.feature_filter import FeatureFilterConfig
    from pimm_agents.pimm.localizer import PimmConfig, PimmLocalizer
    from pimm_env.mapping.derived_maps import load_derived_maps

    filter_keys = {f.name for f in fields(FeatureFilterConfig)}
    top_keys = {f.name for f in fields(PimmConfig)} - {"filter", "corners"}
    unknown = sorted(set(overrides) - filter_keys - top_keys)
    if unknown:
        valid = ", ".join(sorted(filter_keys | top_keys))
        raise ValueError(f"localizer 'pimm' has no setting(s) {unknown}; valid: {valid}")
    filter_config = replace(FeatureFilterConfig(), **{k: v for k, v in overrides.items() if k in filter_keys})
    config = replace(PimmConfig(filter=filter_config), **{k: v for k, v in overrides.items() if k in top_keys})
    maps = load_derived_maps(world)
    segmenter, fingerprints = load_perception(world)
    return PimmLocalizer(maps.occupancy, maps.corners, segmenter, fingerprints, config)


def _amcl_preset(name: str) -> dict[str, Any]:
    from pimm_agents.amcl.localizer import AMCL_RECOVERY, AMCL_RECOVERY_NAV2

    return {"amcl": {}, "amcl-recovery": AMCL_RECOVERY, "amcl-recovery-nav2": AMCL_RECOVERY_NAV2}[name]


def _amcl_variant(name: str) -> Callable[[World, dict[str, Any]], Localizer]:
    return lambda world, overrides: _amcl(world, overrides, name, _amcl_preset(name))


LOCALIZERS: dict[str, Callable[[World, dict[str, Any]], Localizer]] = {
    "pimm": _pimm,
    **{name: _amcl_variant(name) for name in ("amcl", "amcl-recovery", "amcl-recovery-nav2")},
}


def available_localizers() -> list[str]:
    return list(LOCALIZERS)


def make_localizer(name: str, world: str | World = "iilab", **overrides: Any) -> Localizer:
    """The localizer ``name`` for ``world`` (a name, a world file or a loaded world).

    Keyword arguments override fields of the localizer's config object, e.g. ``max_particles=500``.
    """
    if name not in LOCALIZERS:
        raise ValueError(f"unknown localizer {name!r}; valid: {', '.join(LOCALIZERS)}")
    loaded = world if isinstance(world, World) else load_world(world)
    return LOCALIZERS[name](loaded, overrides)
