"""Where independent jobs run: in this process, in local worker processes (the default, no Ray needed), or as
Ray tasks on a local Ray or a cluster. Trials (``experiments/runner.py``) and the training data steps
(``training/``) hand their jobs here; each job is a picklable function of one picklable argument."""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from typing import Any, TypeVar

from pimm_env.errors import ExperimentError

#: ``local`` worker processes or a Ray cluster.
BACKENDS = ("local", "ray")

T = TypeVar("T")
R = TypeVar("R")


def check_backend(backend: str, address: str | None) -> None:
    """``ValueError`` unless ``backend`` is one of ``BACKENDS`` and ``address`` comes only with ``ray``."""
    if backend not in BACKENDS or (address is not None and backend != "ray"):
        raise ExperimentError(f"expected local or ray (--address only with ray), got {backend!r}")


def limit_threads(threads: int) -> None:
    """Keep each worker's torch to its share of the cores: oversubscribed threads slow every worker down."""
    import torch

    torch.set_num_threads(threads)


def _on_one_thread(job: tuple[Callable[[Any], Any], Any]) -> Any:
    """A Ray task: one CPU each, so torch keeps to one thread."""
    fn, argument = job
    limit_threads(1)
    return fn(argument)


def run_jobs(
    fn: Callable[[T], R],
    arguments: Sequence[T],
    workers: int = 1,
    backend: str = "local",
    address: str | None = None,
    on_done: Callable[[int, R], None] | None = None,
) -> list[R]:
    """``fn(a)`` for every ``a`` of ``arguments``, in this process (``workers`` <= 1, local), in ``workers``
    local processes, or as Ray tasks (a local Ray with ``workers`` CPUs unless one runs or ``address`` names a
    cluster). ``on_done(i, result)`` sees each result as it comes; the results return in argument order."""
    check_backend(backend, address)
    results: dict[int, R] = {}

    def finish(i: int, result: R) -> None:
        results[i] = result
        if on_done:
            on_done(i, result)

    if backend == "ray":
        _run_on_ray(fn, arguments, workers, address, finish)
    elif workers <= 1 or len(arguments) <= 1:
        for i, argument in enumerate(arguments):
            finish(i, fn(argument))
    else:
        threads = max(1, (os.cpu_count() or 1) // workers)
        with ProcessPoolExecutor(max_workers=workers, initializer=limit_threads, initargs=(threads,)) as pool:
            futures = {pool.submit(fn, argument): i for i, argument in enumerate(arguments)}
            for future in as_completed(futures):
                finish(futures[future], future.result())
    return [results[i] for i in range(len(arguments))]


def start_ray(workers: int, address: str | None) -> tuple[Any, bool]:
    """Ray, connected: to the running one, to the cluster at ``address``, or to a local one started here with
    ``workers`` CPUs; and whether it was started here (the caller then shuts it down)."""
    try:
        import ray
    except ImportError:
        raise ExperimentError(
            "--backend ray needs Ray: pip install 'ray>=2.9' (or the project's [ray] extra)"
        ) from None
    started = not ray.is_initialized()
    if started:
        ray.init(
            address=address,
            num_cpus=None if address else max(1, workers),
            include_dashboard=False,
            log_to_driver=False,
            configure_logging=False,
        )
    return ray, started


def _run_on_ray(
    fn: Callable[[Any], Any],
    arguments: Sequence[Any],
    workers: int,
    address: str | None,
    finish: Callable[[int, Any], None],
) -> None:
    ray, started = start_ray(workers, address)
    try:
        task = ray.remote(num_cpus=1)(_on_one_thread)
        pending = {task.remote((fn, argument)): i for i, argument in enumerate(arguments)}
        while pending:
            ready, _ = ray.wait(list(pending), num_returns=1)
            for ref in ready:
                finish(pending.pop(ref), ray.get(ref))
    finally:
        if started:
            ray.shutdown()
