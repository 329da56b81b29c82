"""An experiment: trials run into one timestamped results folder, resumable, on worker processes or Ray.

    from pimm_agents.experiments.experiment import Execution, Experiment
    from pimm_agents.experiments.run_plan import RunPlan, resolve_localizers

    plan = RunPlan(world="iilab", localizers=resolve_localizers(["pimm", "amcl"]), scenarios=("area_a",), trials=3)
    outcome = Experiment.of_plan(plan).run(out=Path("results"))
    outcome.summary["scenarios"]["area_a"]["pimm"]["convergence_rate"]

Every trial is saved as it finishes (``trial_store.py``), so ``run(resume=True)`` continues the newest folder of
the same kind under ``out`` and runs only the trials it lacks. The folder gets ``summary.json``, ``run.yaml``
(the plan, which repeats the run), ``config.yaml`` (the params file of the localizers), logs, TUM pairs and
figures (``results/folder.py``).
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path
from typing import Any

from pimm_agents.experiments.engines import check_backend
from pimm_agents.experiments.run_plan import RunPlan
from pimm_agents.experiments.runner import run_trials
from pimm_agents.experiments.sweep import Sweep, sweep_specs
from pimm_agents.experiments.trial_store import load_stored, save_trial
from pimm_agents.results.folder import write_results
from pimm_agents.scoring.trial import TrialResult, TrialSpec
from pimm_env.errors import ExperimentError


@dataclass(frozen=True)
class Execution:
    """Where and how trials run; none of it changes a trial's result."""

    workers: int = 0  # worker processes or Ray CPUs; 0: one per core
    backend: str = "local"  # or "ray": a local Ray, or the cluster at ``address``
    address: str | None = None
    progress: bool = True  # a progress bar on stderr

    def worker_count(self, jobs: int) -> int:
        return max(1, min(self.workers or os.cpu_count() or 1, jobs))


@dataclass
class Outcome:
    """What a finished experiment gives back: its folder, every trial's result and the summary written there."""

    folder: Path
    results: list[TrialResult]
    summary: dict[str, Any]
    trials_run: int
    trials_reused: int
    wall_s: float
    record: dict[str, Any] = field(default_factory=dict)
    maps: Any = None  # the world's DerivedMaps when the experiment ran in one world, for figures and videos


def new_folder(out: Path, kind: str) -> Path:
    """``out/YYYY-MM-DD_HH-MM-SS_KIND``, made now; a second one in the same second gets ``_2`` after it."""
    stamp = f"{datetime.now():%Y-%m-%d_%H-%M-%S}"
    Path(out).mkdir(parents=True, exist_ok=True)
    for n in range(1, 1000):
        folder = Path(out) / (f"{stamp}_{kind}" if n == 1 else f"{stamp}_{kind}_{n}")
        try:
            folder.mkdir(exist_ok=False)
            return folder
        except FileExistsError:
            continue
    raise ExperimentError(f"{out}: a thousand {kind} folders made in one second; give another --out")


def latest_folder(out: Path, kind: str) -> Path | None:
    """The newest ``*_KIND`` (or ``*_KIND_N``) folder under ``out`` (timestamped names sort by time), if any."""
    import re

    pattern = re.compile(rf"^(\d{{4}}-\d{{2}}-\d{{2}}_\d{{2}}-\d{{2}}-\d{{2}})_{re.escape(kind)}(?:_(\d+))?$")
    matched = ((pattern.match(p.name), p) for p in Path(out).glob(f"*_{kind}*") if p.is_dir())
    runs = sorted((m.group(1), int(m.group(2) or 1), p) for m, p in matched if m)
    return runs[-1][2] if runs else None


class Experiment:
    """Trials (``TrialSpec``) to run into a results folder of one kind (``run``, ``sweep``)."""

    def __init__(
        self,
        specs: Sequence[TrialSpec],
        kind: str,
        record: dict[str, Any],
        write_record: Callable[[Path, dict[str, Any]], None],
        execution: Execution | None = None,
    ) -> None:
        self.specs = list(specs)
        self.worlds = list(dict.fromkeys(spec.world for spec in self.specs))
        self.kind = kind
        self.record = record
        self.write_record = write_record
        self.execution = execution or Execution()
        check_backend(self.execution.backend, self.execution.address)

    @classmethod
    def of_plan(cls, plan: RunPlan, execution: Execution | None = None) -> Experiment:
        """The run a plan describes (its scenarios filled in and every field checked)."""
        plan = plan.checked()

        def write(folder: Path, made: dict[str, Any]) -> None:
            from pimm_agents.params import write_params_file

            plan.write(folder / "run.yaml", made)
            write_params_file(folder / "config.yaml", plan.localizers)

        return cls(plan.specs(), "run", plan.as_dict(), write, execution)

    @classmethod
    def of_sweep(cls, sweep: Sweep, source: Path, execution: Execution | None = None) -> Experiment:
        """A sweep file's grid; the folder keeps a copy of the file, which repeats the sweep."""
        text = Path(source).read_text()

        def write(folder: Path, made: dict[str, Any]) -> None:
            import yaml

            (folder / "sweep.yaml").write_text(text)
            (folder / "run.yaml").write_text(yaml.safe_dump({"sweep": "sweep.yaml", "made": made}, sort_keys=False))

        return cls(sweep_specs(sweep), "sweep", {"worlds": sweep.worlds}, write, execution)

    def run(self, out: Path = Path("results"), resume: bool = False, command: str = "") -> Outcome:
        """Run the trials the folder lacks, save each as it ends, and write the results folder (its figures on
        the world's map when all trials share one world). With ``resume``, the newest folder of this kind under
        ``out`` is continued (a new one is made if there is none). ``command``, the command line that asked for
        the run, is kept in the record."""
        from tqdm import tqdm

        from pimm_env.mapping.derived_maps import ensure_derived_maps
        from pimm_env.world.files import load_world

        maps = ensure_derived_maps(load_world(self.worlds[0])) if len(self.worlds) == 1 else None

        earlier = latest_folder(out, self.kind) if resume else None
        folder = earlier or new_folder(out, self.kind)
        stored = load_stored(folder, self.specs) if earlier else {}
        todo = [spec for i, spec in enumerate(self.specs) if i not in stored]
        began = time.perf_counter()
        ex = self.execution
        with tqdm(total=len(todo), desc=self.kind, unit="trial", disable=not ex.progress) as bar:

            def done(result: TrialResult) -> None:
                save_trial(folder, result)
                bar.update()

            fresh = iter(run_trials(todo, ex.worker_count(len(todo)), done, ex.backend, ex.address))
        results = [stored[i] if i in stored else next(fresh) for i in range(len(self.specs))]
        wall_s = round(time.perf_counter() - began, 1)
        repeat = f"python evaluate.py {'run --from' if self.kind == 'run' else 'sweep'} {folder}/"
        repeat += "run.yaml" if self.kind == "run" else "sweep.yaml"
        made: dict[str, Any] = {
            "command": command or repeat,
            "wall_s": wall_s,
            "trials_run": len(todo),
            "trials_reused": len(stored),
            "workers": ex.worker_count(len(todo)),
            "backend": ex.backend if ex.address is None else f"ray at {ex.address}",
            "repeat": repeat,
        }
        self.write_record(folder, made)
        record = {**self.record, **made}
        occupancy = None if maps is None else maps.occupancy
        corners = None if maps is None else maps.corners.xy
        summary = write_results(folder, results, record, occupancy, corners)
        return Outcome(folder, results, summary, len(todo), len(stored), wall_s, record, maps)
