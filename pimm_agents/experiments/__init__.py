"""Running experiments: the recording wrapper, trials on worker processes or Ray, the trial store that makes a
run resumable, sweeps, bag replays, the run plan that repeats a run, and ``Experiment``, which ties them up."""

from pimm_agents.experiments.experiment import Execution, Experiment, Outcome
from pimm_agents.experiments.frames import write_videos
from pimm_agents.experiments.run_plan import RunPlan, read_plan, resolve_localizers
from pimm_agents.experiments.sweep import read_sweep

__all__ = [
    "Execution",
    "Experiment",
    "Outcome",
    "RunPlan",
    "read_plan",
    "read_sweep",
    "resolve_localizers",
    "write_videos",
]
