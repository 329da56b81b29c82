"""Keep a C library's banners off our stdout (pybullet prints its build time on import and ``argv[0]=`` on
connect, which would break ``--json`` output and cut into progress bars)."""

from __future__ import annotations

import ctypes
import os
import sys
from collections.abc import Iterator
from contextlib import contextmanager


def _flush_c_stdio() -> None:
    try:
        ctypes.CDLL(None).fflush(None)
    except (OSError, AttributeError):  # no C library to ask (not on POSIX): nothing buffered there to lose
        pass


@contextmanager
def silenced_stdout() -> Iterator[None]:
    """Send what C code writes to file descriptor 1 to /dev/null for the duration; Python's own prints are
    flushed first, so nothing of ours is lost or reordered."""
    sys.stdout.flush()
    try:
        saved = os.dup(1)
    except OSError:  # no file descriptor 1 (an embedded interpreter): nothing to silence
        yield
        return
    try:
        with open(os.devnull, "w") as devnull:
            os.dup2(devnull.fileno(), 1)
            try:
                yield
            finally:
                _flush_c_stdio()
                os.dup2(saved, 1)
    finally:
        os.close(saved)
