"""A trial as scoring sees it: what was asked (``TrialSpec``) and what came back (``TrialResult``)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from pimm_agents.scoring.metrics import TrialMetrics, trial_metrics
from pimm_agents.scoring.trial_log import TrialLog


@dataclass(frozen=True)
class TrialSpec:
    scenario: str
    localizer: str
    trial: int
    seed: int
    world: str = "iilab"
    params: dict[str, Any] = field(default_factory=dict)  # the localizer's params-file section
    sensors: str = "thesis"  # LiDAR presets (pimm_env.sim.sensors)
    start: str = "global"  # or "known": the true start pose with nav2's covariance (recorder.STARTS)
    label: str = ""  # how reports name the localizer (a sweep's "amcl[max_particles=500]"); default its name
    row: str = ""  # how reports name the scenario (a sweep over worlds: "gen-900/route_1"); default its name
    faults: str = ""  # pimm_env.envs.faults.parse_faults's form, e.g. "dropout@30:5,kidnap@60"
    walkers: int = 0  # people walking about (pimm_env/sim/movers.py)
    unmapped: int = 0  # furniture the maps do not have
    #: who drives: "route" (the scenario's waypoints) or "policy:NAME" (pimm_agents/active/driver.py), which
    #: drives on this spec's localizer's belief, so such a spec has a simulation of its own
    driver: str = "route"
    #: the world whose maps the localizers take ("": the simulated world's): a building's maps made another way
    #: (``world import`` of its point-cloud map), judged in the building itself
    maps: str = ""

    @property
    def name(self) -> str:
        return self.label or self.localizer

    @property
    def case(self) -> str:
        return self.row or self.scenario

    @property
    def simulation(self) -> tuple[str, str, int, int, str, str, int, int, str, str]:
        """What the simulated stream depends on; specs that share it share one simulation."""
        return (
            self.world,
            self.scenario,
            self.trial,
            self.seed,
            self.sensors,
            self.faults,
            self.walkers,
            self.unmapped,
            self.driver,
            "" if self.driver == "route" else self.name,  # a policy drives on one localizer's belief
        )


@dataclass
class TrialResult:
    spec: TrialSpec
    log: TrialLog
    metrics: TrialMetrics  # for kidnap scenarios: measured from the kidnap on
    wall_s: float  # the shared simulation's wall time, with every localizer it fed
    completed: bool
    collided: bool = False  # the robot touched an obstacle on the way (the trial went on, the route may not)


def metrics_of(log: TrialLog) -> TrialMetrics:
    """The thesis's metrics of one trial; a kidnap trial counts from the kidnap on."""
    return trial_metrics(log.after_kidnap())
