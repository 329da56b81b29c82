"""Perception training for a world: ``python -m training rebuild --world iilab`` makes everything.

python -m training dataset --world iilab --scans 2300 --seed 0      # build/datasets/iilab/*.npz
python -m training train --world iilab --epochs 40                  # maps/iilab/pointnet.pt (+ .json), the world's own
python -m training validate --world iilab                           # IoU on the validation set
python -m training fingerprints --world iilab                       # maps/iilab/fingerprints.npz
python -m training rebuild --world iilab                            # all of it, in order
"""

from __future__ import annotations

import json
import shlex
import sys
from pathlib import Path
from typing import Any

import typer

from pimm_agents import command_line
from training import benchmark_commands

app = typer.Typer(add_completion=False, help=__doc__)
DATA_DIR = Path("build/datasets")


def _prepare(world: str) -> None:
    """Build the world's derived maps if missing or stale: the simulator only reads them."""
    from pimm_env.mapping.derived_maps import ensure_derived_maps
    from pimm_env.world.files import load_world

    ensure_derived_maps(load_world(world))


def _dataset_paths(world: str) -> tuple[Path, Path]:
    from pimm_env.world.files import load_world

    folder = DATA_DIR / load_world(world).name
    return folder / "scans.npz", folder / "validation.npz"


@command_line.command(app)
def dataset(
    world: str = typer.Option("iilab", help="world name or world file"),
    scans: int = typer.Option(2300, min=10, help="scans for training + test (the thesis's 2300)"),
    validation: int = typer.Option(400, min=1, help="scans of the separate validation set (another seed)"),
    seed: int = typer.Option(0, help="seed of the poses and noise"),
    workers: int = typer.Option(1, min=1, help="worker processes (or Ray CPUs); the scans are the same for any"),
    backend: str = typer.Option("local", help="local (worker processes) or ray (a local Ray, or --address)"),
    address: str | None = typer.Option(None, help="a Ray cluster to join, e.g. ray://head:10001 or auto"),
) -> None:
    """Labelled scans at random free poses, and a validation set from poses drawn with another seed."""
    from training.dataset import VALIDATION_SEED_OFFSET, generate, save

    _check_backend(backend, address)
    _prepare(world)
    main_path, val_path = _dataset_paths(world)
    save(generate(world, scans, seed, workers=workers, backend=backend, address=address), main_path)
    validation_seed = seed + VALIDATION_SEED_OFFSET
    save(generate(world, validation, validation_seed, workers=workers, backend=backend, address=address), val_path)
    typer.echo(f"wrote {main_path} ({scans} scans) and {val_path} ({validation} scans)")


@command_line.command(app)
def clouds(
    worlds: list[str] = typer.Option(..., "--world", help="world name or file; repeat for several"),
    per_world: int = typer.Option(200, min=1, help="scans of each world"),
    seed: int = typer.Option(0, help="seed of every draw (poses, LiDARs, mounts, noise)"),
    out: Path = typer.Option(..., help="the .npz to write"),
) -> None:
    """Labelled scans of many LiDARs, mounts and conditions for the layout-free network
    (training/cloud_dataset.py)."""
    from training.buildings import NEVER_TRAIN_SEEDS
    from training.cloud_dataset import generate, save

    held = {f"gen-{s}" for s in NEVER_TRAIN_SEEDS}
    for world in worlds:
        if Path(world).parent.name in held or world in held:
            raise typer.BadParameter(f"{world} is a held-out building: never train on it", param_hint="--world")
    for world in worlds:
        _prepare(world)
    made = generate(worlds, per_world, seed)
    save(made, out)
    typer.echo(f"wrote {out}: {len(made)} scans, {len(made.points)} voxel points")


@command_line.command(app)
def train(
    worlds: list[str] = typer.Option(["iilab"], "--world", help="world name or file; repeat to pool several"),
    cloud_sets: list[Path] = typer.Option(
        [], "--clouds", help="train the layout-free network on these cloud datasets (`clouds`) instead"
    ),
    epochs: int = typer.Option(40, min=1),
    points: int = typer.Option(2048, min=64, help="points per scan the network looks at"),
    local_widths: str | None = typer.Option(
        None, help="the local MLP's widths, e.g. 48,48 (default: PointNetConfig's)"
    ),
    global_widths: str | None = typer.Option(None, help="the global MLP's widths, e.g. 96,192"),
    head_widths: str | None = typer.Option(None, help="the class head's widths, e.g. 64,32"),
    seed: int = typer.Option(0),
    learning_rate: float = typer.Option(1e-3, help="Adam's learning rate (thesis: 1e-3)"),
    init: Path | None = typer.Option(None, help="go on from these weights instead of from scratch"),
    teacher: Path | None = typer.Option(
        None, help="learn from these trained weights' class probabilities too (a smaller network from a larger)"
    ),
    distill_weight: float | None = typer.Option(
        None, min=0.0, max=1.0, help="with --teacher: the loss's share given to matching it (default: TrainConfig's)"
    ),
    out: Path | None = typer.Option(None, help="checkpoint path (default with one world: its own pointnet.pt)"),
) -> None:
    """Train the segmenter and descriptor on the worlds' datasets (80/20 split), report per-epoch metrics."""
    from dataclasses import replace

    import numpy as np

    from pimm_agents.perception.files import own_checkpoint_path
    from pimm_agents.perception.pointnet import PointNetConfig, load_checkpoint, save_checkpoint
    from pimm_env.errors import PerceptionError
    from training import cloud_dataset
    from training.dataset import load, pool, split
    from training.train import TrainConfig, check_teacher, describe
    from training.train import train as fit

    if out is None and (len(worlds) > 1 or cloud_sets):
        raise typer.BadParameter("pooling several worlds: say where the weights go", param_hint="--out")
    if distill_weight is not None and teacher is None:
        raise typer.BadParameter("a share of the loss for a teacher, but no --teacher", param_hint="--distill-weight")
    config = TrainConfig(epochs=epochs, seed=seed, learning_rate=learning_rate)
    if distill_weight is not None:
        config = replace(config, distill_weight=distill_weight)
    widths = _widths(local_widths=local_widths, global_widths=global_widths, head_widths=head_widths)
    if widths and init is not None:
        raise typer.BadParameter(
            "--init goes on with its own network's widths; leave the widths out", param_hint="--init"
        )
    scans: Any
    if cloud_sets:
        paths = list(cloud_sets)
        scans = cloud_dataset.pool([cloud_dataset.load(path) for path in paths])
        order = np.random.default_rng(seed).permutation(len(scans))
        cut = round(0.8 * len(scans))
        train_set, test_set = scans.subset(np.sort(order[:cut])), scans.subset(np.sort(order[cut:]))
        network = replace(PointNetConfig(points=points, inputs="cloud", context_offsets=()), **widths)
        worlds = sorted(set(str(w) for w in scans.worlds))
    else:
        paths = [_dataset_paths(world)[0] for world in worlds]
        scans = pool([load(path) for path in paths])
        train_set, test_set = split(scans, 0.8, np.random.default_rng(seed))
        network = replace(PointNetConfig(points=points), **widths)
    main_path = paths[0]
    initial = load_checkpoint(init)[0] if init is not None else None
    if initial is not None:
        network = initial.config
    teacher_model, teacher_record = load_checkpoint(teacher) if teacher is not None else (None, None)
    if teacher_model is not None:
        try:
            check_teacher(teacher_model, network)
        except PerceptionError as error:
            raise typer.BadParameter(f"{teacher}: {error}", param_hint="--teacher") from None

    def report(record: dict) -> None:
        ious = " ".join(f"{k} {v:.3f}" for k, v in record["test_iou"].items())
        typer.echo(
            f"epoch {record['epoch']:>3}  {record['seconds']:5.0f} s  loss {record['loss']:.3f} "
            f"(ce {record['cross_entropy']:.3f}, descriptor {record['descriptor_loss']:.3f}"
            + (f", teacher {record['distillation_loss']:.3f}" if teacher is not None else "")
            + ")  "
            f"train acc {record['train_accuracy']:.3f}  test mIoU {record['test_miou']:.3f} ({ious})"
        )

    model, history = fit(train_set, test_set, config, network, on_epoch=report, initial=initial, teacher=teacher_model)
    target = out or own_checkpoint_path(worlds[0])
    record = {
        "command": "python -m training " + shlex.join(sys.argv[1:]) if sys.argv[1:] else "python -m training",
        "dataset": {
            "path": str(main_path),
            "worlds": worlds,
            "scans": len(scans),
            "train": len(train_set),
            "test": len(test_set),
        },
        "initial_weights": str(init) if init is not None else None,
        "teacher_weights": (
            {"path": str(teacher), "sha256": teacher_record["sha256"]} if teacher_record is not None else None
        ),
        **describe(config, network, model),
        "history": history,
    }
    record = save_checkpoint(model, target, record)  # its record, checked on every load, goes beside it
    size = target.stat().st_size / 1e6
    typer.echo(f"wrote {target} ({size:.2f} MB, {record['parameters']} parameters)")


def _widths(**given: str | None) -> dict[str, Any]:
    """The network widths given on the command line (comma-separated positive integers), by field name."""
    widths: dict[str, Any] = {}
    for name, text in given.items():
        if text is None:
            continue
        try:
            values = _comma_integers(text)
        except ValueError:
            values = ()
        if not values or min(values) < 1:
            option = "--" + name.replace("_", "-")
            raise typer.BadParameter(f"{text!r}: give positive integers separated by commas", param_hint=option)
        widths[name] = values
    return widths


@command_line.command(app)
def validate(
    world: str = typer.Option("iilab", help="world name or world file"),
    checkpoint: Path | None = typer.Option(None, help="weights to score (default: the weights the world uses)"),
) -> None:
    """Per-class IoU on the separate validation set, every return labelled as the localizer does; the result
    is also written into the checkpoint's .json record."""
    from pimm_agents.measurement.perception_quality import segmentation_scores
    from pimm_agents.perception.files import checkpoint_path
    from pimm_agents.perception.segmenter import Segmenter
    from pimm_agents.results.tables import format_segmentation
    from training.dataset import load
    from training.validate import scan_set_confusion

    _, val_path = _dataset_paths(world)
    target = checkpoint or checkpoint_path(world)
    scans = load(val_path)
    scores = segmentation_scores(scan_set_confusion(Segmenter(target), scans), len(scans))
    typer.echo("\n".join(format_segmentation(scores, f"{len(scans)} validation scans")))
    result = {"scans": len(scans), "path": str(val_path), "iou": scores["iou"], "mean_iou": scores["miou"]}
    record_path = target.with_suffix(".json")
    if record_path.is_file():
        record = json.loads(record_path.read_text())
        record["validation"] = result
        record_path.write_text(json.dumps(record, indent=1) + "\n")
        typer.echo(f"recorded in {record_path}")


@command_line.command(app)
def fingerprints(
    world: str = typer.Option("iilab", help="world name or world file"),
    spacing: float = typer.Option(0.5, min=0.05, help="grid spacing of the map positions (m)"),
    seed: int = typer.Option(0, help="seed of the headings and noise"),
    workers: int = typer.Option(1, min=1, help="worker processes (or Ray CPUs); the map is the same for any"),
    backend: str = typer.Option("local", help="local (worker processes) or ray (a local Ray, or --address)"),
    address: str | None = typer.Option(None, help="a Ray cluster to join, e.g. ray://head:10001 or auto"),
) -> None:
    """Descriptors of scans on a grid of free positions, saved as the world's fingerprint map."""
    from pimm_agents.perception.files import checkpoint_path, fingerprint_path
    from pimm_agents.perception.segmenter import load_segmenter
    from pimm_agents.preparation.fingerprints import build_fingerprint_map

    _check_backend(backend, address)
    _prepare(world)
    segmenter = load_segmenter(checkpoint_path(world))
    fmap = build_fingerprint_map(world, segmenter, spacing, seed, workers=workers, backend=backend, address=address)
    target = fingerprint_path(world)
    fmap.save(target, segmenter.weights_sha256, {"spacing_m": str(spacing), "seed": str(seed)})
    typer.echo(f"wrote {target} ({len(fmap)} positions, {fmap.dim}-d descriptors)")


def _check_backend(backend: str, address: str | None) -> None:
    from pimm_agents.experiments.engines import check_backend
    from pimm_env.errors import PimmError

    try:
        check_backend(backend, address)
    except PimmError as error:
        raise typer.BadParameter(str(error), param_hint="--backend") from None


@command_line.command(app)
def policy(
    world: list[str] = typer.Option([], "--world", help="worlds to train in (default: the policy training seeds)"),
    algo: str = typer.Option("ppo", help="the stable-baselines3 algorithm (ppo)"),
    steps: int = typer.Option(20_000, min=1, help="environment steps (motion primitives) in all"),
    seed: int = typer.Option(0, help="seed of the policy, the envs and their episodes"),
    localizer: str = typer.Option("pimm", help="the localizer in the loop"),
    workers: int = typer.Option(1, min=1, help="envs, each in a worker process when more than one"),
    imitate: int = typer.Option(0, min=0, help="steps of the greedy policy the network first learns from"),
    dagger: int = typer.Option(0, min=0, help="then steps of its own drives, labelled by greedy (DAgger)"),
    critic: bool = typer.Option(False, help="the imitation fits the value head to the drives' returns too"),
    backend: str = typer.Option("local", help="local (worker processes) or ray (the envs as Ray actors)"),
    address: str | None = typer.Option(None, help="a Ray cluster's address (with --backend ray)"),
    worlds_dir: Path = typer.Option(Path("build/worlds"), "--worlds", help="folder of the generated worlds"),
    out: Path = typer.Option(Path("build/policies/active_ppo.zip"), help="the policy's .zip (record beside it)"),
) -> None:
    """Train an active-localization policy (pimm/ActiveLocalization-v0) with stable-baselines3."""
    _check_backend(backend, address)
    from training.buildings import POLICY_TRAINING_SEEDS
    from training.heldout import ready_building
    from training.policy import train_policy

    chosen = list(world) or [str(ready_building(building, worlds_dir)) for building in POLICY_TRAINING_SEEDS]
    path = train_policy(chosen, steps, out, seed, localizer, workers, algo, imitate, dagger, critic, backend, address)
    typer.echo(f"wrote {path} and {path.with_suffix('.json')} (training log: {path.with_suffix('')}_log/)")


def _comma_integers(text: str) -> tuple[int, ...]:
    """Integers separated by commas (``--seeds A,B,C``, ``--local-widths A,B``); ValueError if a part is not one."""
    return tuple(int(part) for part in text.split(","))


@command_line.command(app)
def rebuild(
    world: str = typer.Option("iilab", help="world name or world file"),
    scans: int = typer.Option(2300, min=10),
    validation: int = typer.Option(400, min=1),
    epochs: int = typer.Option(40, min=1),
    spacing: float = typer.Option(0.5, min=0.05, help="fingerprint grid spacing (m)"),
    seed: int = typer.Option(0),
) -> None:
    """Dataset, then weights, then fingerprint map: everything perception needs for a world."""
    from pimm_agents.perception.pointnet import PointNetConfig

    dataset(world=world, scans=scans, validation=validation, seed=seed, workers=1, backend="local", address=None)
    train(
        worlds=[world],
        cloud_sets=[],
        epochs=epochs,
        points=PointNetConfig().points,
        local_widths=None,
        global_widths=None,
        head_widths=None,
        seed=seed,
        learning_rate=1e-3,
        init=None,
        teacher=None,
        distill_weight=None,
        out=None,
    )
    validate(world=world, checkpoint=None)
    fingerprints(world=world, spacing=spacing, seed=seed, workers=1, backend="local", address=None)


app.registered_commands += benchmark_commands.app.registered_commands  # buildings, heldout, suite


def main() -> int:
    """``python -m training``, with ``--world a b`` and ``--localizers a b`` read as the docs write them."""
    return command_line.run_app(app, ("--world", "--localizers"))


if __name__ == "__main__":
    sys.exit(main())
