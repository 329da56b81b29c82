"""Keep a C library's banners off our console (pybullet prints its build time on import and ``argv[0]=`` on
connect, which would break ``--json`` output and cut into progress bars)."""

from __future__ import annotations

import ctypes
import os
import sys
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager


def _flush_c_stdio() -> None:
    try:
        ctypes.CDLL(None).fflush(None)
    except (OSError, AttributeError):  # no C library to ask (not on POSIX): nothing buffered there to lose
        pass


@contextmanager
def _silenced(fd: int) -> Iterator[None]:
    try:
        saved = os.dup(fd)
    except OSError:  # no such descriptor (an embedded interpreter): nothing to silence
        yield
        return
    try:
        with open(os.devnull, "w") as devnull:
            os.dup2(devnull.fileno(), fd)
            try:
                yield
            finally:
                _flush_c_stdio()
                os.dup2(saved, fd)
    finally:
        os.close(saved)


@contextmanager
def silenced_console() -> Iterator[None]:
    """Send what C code writes to file descriptors 1 and 2 to /dev/null for the duration. Python's own streams
    are flushed first, so nothing of ours is lost or reordered; keep the block to the noisy call alone."""
    sys.stdout.flush()
    sys.stderr.flush()
    with ExitStack() as stack:
        stack.enter_context(_silenced(1))
        stack.enter_context(_silenced(2))
        yield
