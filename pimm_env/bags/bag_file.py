"""Opening a bag: ``rosbags``' reader, with what it cannot read said as a ``BagError`` naming the file."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from pimm_env.bags.messages import typestore
from pimm_env.errors import BagError, MissingFileError


@contextmanager
def open_bag(path: Path) -> Iterator[Any]:
    """``rosbags``' reader of the bag at ``path`` (a rosbag2 folder or a ROS 1 ``.bag``). What rosbags or the
    storage under it cannot read, on opening or while messages are read (a folder without ``metadata.yaml``, a
    truncated ``.db3``, a file that is no bag), is a ``BagError`` naming the file, not a traceback."""
    import sqlite3

    from rosbags.highlevel import AnyReader, AnyReaderError
    from rosbags.rosbag1 import ReaderError as Rosbag1Error
    from rosbags.rosbag2 import ReaderError as Rosbag2Error

    path = Path(path)
    if not path.exists():
        raise MissingFileError(f"{path}: no such bag")
    if path.is_dir() and path.suffix == ".bag":
        raise BagError(f"{path}: a rosbag2 folder whose name ends in .bag, which is read as a ROS 1 bag file; "
                       f"rename it to {path.with_suffix('')}")  # fmt: skip
    if path.is_dir() and not (path / "metadata.yaml").is_file():
        have = sorted(p.name for p in path.iterdir())[:5]
        raise BagError(f"{path}: a rosbag2 folder holds a metadata.yaml, this one has none (it has {have})")
    try:
        with AnyReader([path], default_typestore=typestore()) as reader:
            yield reader
    except (AnyReaderError, Rosbag1Error, Rosbag2Error, sqlite3.Error, EOFError, UnicodeDecodeError) as error:
        raise BagError(f"{path}: not a readable bag ({type(error).__name__}: {error})") from None
