"""PIMM's settings (``pimm`` in a params file) and its two presets.

Each default says where it comes from in one line: the thesis (its table 3.5 and chapter 3), nav2, or a
measurement (docs/design.md, the section named). What is not a setting is a named constant in the module that
uses it, with its source. Two presets ship: ``default`` (``pimm``) and ``thesis`` (``pimm-thesis``: the filter as
the thesis published it, corners and fingerprint suggestions only, no wall field and no ambiguity check).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from pimm_agents.corners.detector import CornerDetectorConfig
from pimm_agents.observation_guard import GuardConfig
from pimm_agents.particles.belief import BeliefConfig
from pimm_agents.particles.likelihood_field import LikelihoodFieldParams
from pimm_agents.pimm.feature_filter import FeatureFilterConfig
from pimm_agents.pimm.rivals import RivalConfig
from pimm_env.errors import LocalizerError

#: nav2's likelihood field: z_hit, z_rand, laser_likelihood_max_dist (m); range_max is the thesis's 3D LiDAR (m)
Z_HIT, Z_RAND, MAX_DISTANCE_M, RANGE_MAX_M = 0.5, 0.5, 2.0, 10.0
#: the height band (m, relative to the sensor) of the wall points used: the walls the occupancy map cuts (0.1-1.5 m
#: above the floor with the sensor at 0.5 m), below lintels over doorways (measured: docs/design.md#the-wall-field)
WALL_BAND_M = (-0.4, 1.0)


@dataclass(frozen=True)
class WallFieldConfig:
    """The wall points of each scan, as the network labels them, scored against the occupancy map with a
    likelihood field (ours, not in the thesis; docs/design.md#the-wall-field): corners are rare in corridors
    and small rooms, the walls are always there. ``enabled: false`` is the thesis's filter."""

    enabled: bool = True  # measured: docs/design.md#the-wall-field
    points: int = 60  # nav2 max_beams, spread evenly over the points' bearings
    temperature: float = 0.2  # measured: the points' log-likelihoods are summed times this
    sigma_hit: float = 0.2  # nav2 (m)

    def __post_init__(self) -> None:
        if self.points < 1:
            raise LocalizerError(f"wall_field.points must be at least 1, got {self.points}")
        if not self.temperature > 0 or not self.sigma_hit > 0:
            raise LocalizerError(
                f"wall_field.temperature and sigma_hit must be positive, got {self.temperature} and {self.sigma_hit}"
            )

    def field_params(self) -> LikelihoodFieldParams:
        """The likelihood field's parameters (distances to the faces free space sees: likelihood_field.py)."""
        return LikelihoodFieldParams(Z_HIT, Z_RAND, self.sigma_hit, MAX_DISTANCE_M, RANGE_MAX_M, surfaces_only=True)


@dataclass(frozen=True)
class PimmConfig:
    filter: FeatureFilterConfig = field(default_factory=FeatureFilterConfig)  # the thesis's particle filter
    corners: CornerDetectorConfig = field(default_factory=CornerDetectorConfig)  # RANSAC planes into corners
    wall_field: WallFieldConfig = field(default_factory=WallFieldConfig)
    belief: BeliefConfig = field(default_factory=BeliefConfig)  # modes and status (particles/belief.py)
    rivals: RivalConfig = field(default_factory=RivalConfig)  # the ambiguity check beside the filter
    guard: GuardConfig = field(default_factory=GuardConfig)  # glitches set aside (observation_guard.py)

    def __post_init__(self) -> None:
        if self.rivals.enabled and not self.wall_field.enabled:
            raise LocalizerError(
                "pimm.rivals.enabled needs pimm.wall_field.enabled: the ambiguity check scores the kept scans'"
                " wall points; turn both off (the thesis preset, pimm-thesis) or leave the wall field on"
            )


#: The presets: PIMM as measured (``pimm``) and the thesis's filter as published (``pimm-thesis``).
PRESETS: dict[str, PimmConfig] = {
    "pimm": PimmConfig(),
    "pimm-thesis": PimmConfig(
        filter=FeatureFilterConfig(thesis=True),
        wall_field=WallFieldConfig(enabled=False),
        rivals=RivalConfig(enabled=False),
    ),
}
