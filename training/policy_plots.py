"""The training curve of an active-localization policy, drawn beside its logs."""

from __future__ import annotations

from pathlib import Path


def plot_progress(progress_csv: Path) -> Path | None:
    """The training's mean episode return and length against its steps, beside ``progress.csv`` as
    ``progress.png`` (None when no episode has ended yet)."""
    import csv

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    with open(progress_csv, newline="") as handle:
        rows = [r for r in csv.DictReader(handle) if r.get("rollout/ep_rew_mean")]
    if not rows:
        return None
    steps = [int(float(r["time/total_timesteps"])) for r in rows]
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(6, 4.5), sharex=True)
    top.plot(steps, [float(r["rollout/ep_rew_mean"]) for r in rows])
    top.set_ylabel("mean episode return")
    bottom.plot(steps, [float(r["rollout/ep_len_mean"]) for r in rows])
    bottom.set_ylabel("mean episode length\n(primitives)")
    bottom.set_xlabel("environment steps (primitives)")
    fig.tight_layout()
    target = progress_csv.with_suffix(".png")
    fig.savefig(target, dpi=100)
    plt.close(fig)
    return target
