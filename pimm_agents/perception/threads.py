"""How many threads the network runs on, chosen by timing it rather than by counting cores.

One scan through the network is a few milliseconds of small matrix products. On an idle machine torch's threads
(one per core) shorten that a little; with another job on the cores they wait on each other and lengthen it
several times: on 2 cores with other jobs running, 19-21 ms a scan on one thread against 40-88 ms on two (the
fingerprint map, 99 % of a world's preparation, fell tenfold under load for this). Which one wins depends on what
else runs, and that changes while a long job goes on, so :class:`ThreadChooser` times both now and then and keeps
the faster.
"""

from __future__ import annotations

import os
from collections.abc import Callable

import numpy as np


def _torch_threads(count: int) -> None:
    import torch

    torch.set_num_threads(count)


def _torch_allowed() -> int:
    import torch

    return int(torch.get_num_threads())


class ThreadChooser:
    """Every ``period`` calls, the next ``trials`` calls on each of 1 and the most threads this process may use
    (interleaved), then the faster by median until the next check. The most is what torch allows when the
    chooser first runs in a process (``OMP_NUM_THREADS``, a worker's share of the cores); where that is 1 it
    never changes anything. Call :meth:`before` ahead of the timed work and :meth:`after` with its seconds."""

    def __init__(
        self,
        period: int = 200,
        trials: int = 3,
        allowed: Callable[[], int] = _torch_allowed,
        set_threads: Callable[[int], None] = _torch_threads,
    ) -> None:
        self.period = period
        self.trials = trials
        self._allowed = allowed
        self._set = set_threads
        self._pid: int | None = None  # a chooser carried to a worker process starts over there
        self.options = [1]
        self.threads = 1

    def _start(self) -> None:
        self._pid = os.getpid()
        self.options = sorted({1, max(1, self._allowed())})
        self.period = max(self.period, self.trials * len(self.options) + 1)
        self.threads = self.options[-1]
        self._current: int | None = None
        self._calls = 0
        self._timed: dict[int, list[float]] = {n: [] for n in self.options}

    def _checking(self) -> bool:
        return len(self.options) > 1 and self._calls % self.period < self.trials * len(self.options)

    def before(self) -> None:
        """Set the thread count for the coming call."""
        if self._pid != os.getpid():
            self._start()
        if self._checking():
            wanted = self.options[(self._calls % self.period) % len(self.options)]
        else:
            wanted = self.threads
        if wanted != self._current:
            self._set(wanted)
            self._current = wanted

    def after(self, seconds: float) -> None:
        """Record the call's duration; at the end of a check, keep the faster thread count."""
        if self._pid != os.getpid():
            return
        if self._checking():
            self._timed[self._current or self.threads].append(seconds)
            if (self._calls % self.period) + 1 == self.trials * len(self.options):
                self.threads = min(self.options, key=lambda n: float(np.median(self._timed[n])))
                self._timed = {n: [] for n in self.options}
        self._calls += 1
