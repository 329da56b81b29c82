"""Where a Gazebo world's URIs lead, found as Gazebo finds them.

``model://NAME/...`` is looked for in the model paths (``--model-path`` folders, the world's ``models/`` folders,
then ``GAZEBO_MODEL_PATH``); ``file://`` and plain paths as they are, else against the file's folder, the model
paths and their parents, the world's folder and its parents, and ``GAZEBO_RESOURCE_PATH``. A name that differs
only in case is taken and said (Gazebo on a case-blind disk loads it). A model or mesh that cannot be found is
counted and left out, as Gazebo loads the rest, or stops the import with ``strict``.
"""

from __future__ import annotations

import os
import re
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from pathlib import Path

from pimm_env.errors import MapFileError, MissingFileError

#: Models Gazebo ships that hold no building, when they are not on the model path: a light (nothing to leave
#: out) and the endless ground plane (left out, with a warning: the building's own floor is used).
BUILTIN_MODELS = {"sun": "", "ground_plane": "Gazebo's ground plane (the building's own floor is used)"}


def model_path(extra: Sequence[Path] = ()) -> list[Path]:
    """Folders searched for ``model://NAME``: the given ones, then ``GAZEBO_MODEL_PATH``'s."""
    env = [Path(p) for p in os.environ.get("GAZEBO_MODEL_PATH", "").split(os.pathsep) if p]
    return [Path(p) for p in extra] + env


class GazeboPaths:
    """Resolves one world's URIs; ``missing`` and ``case_fixed`` say what was not found or found by case."""

    def __init__(self, model_paths: list[Path], world_folder: Path | None = None, strict: bool = False) -> None:
        self.model_paths, self.world_folder, self.strict = model_paths, world_folder, strict
        self.missing: list[str] = []  # models and meshes not found, left out
        self.case_fixed: list[str] = []  # files found only by a name differing in case

    def resolve(self, uri: str, path: Path, element: str) -> Path | None:
        """The file or model folder ``uri`` (in ``path``'s ``element``) names; None: a built-in model that holds
        no building, or (not ``strict``) one not found, which is counted."""
        if uri.startswith("model://"):
            rest = uri[len("model://") :].strip("/")
            head, _, tail = rest.partition("/")
            for folder in self.model_paths:
                found = self._existing(folder / head, uri)
                if found is not None and found.is_dir():
                    return self._found(found / tail, uri, path, element) if tail else found
            if not tail and head in BUILTIN_MODELS:
                return None
            searched = ", ".join(dict.fromkeys(str(f) for f in self.model_paths)) or "no folders"
            return self._missing(f"{path}: {element} {uri}: model {head!r} not found (searched {searched}); give its "
                                 "folder with --model-path DIR or GAZEBO_MODEL_PATH", uri)  # fmt: skip
        if re.match(r"^[a-z][a-z0-9+.-]*://", uri) and not uri.startswith("file://"):
            raise MapFileError(f"{path}: {element} {uri}: unknown URI scheme (use model://, file:// or a path)")
        relative = Path(uri[len("file://") :] if uri.startswith("file://") else uri)
        if relative.is_absolute():
            return self._found(relative, uri, path, element)
        for base in self._search_bases(path):
            found = self._existing(base / relative, uri)
            if found is not None:
                return found
        return self._found(path.parent / relative, uri, path, element)

    def _search_bases(self, path: Path) -> list[Path]:
        """Where a relative URI is looked for, in Gazebo's order."""
        bases = [path.parent]
        for folder in self.model_paths:
            bases += [folder, folder.parent]
        if self.world_folder is not None:
            bases += [self.world_folder, *self.world_folder.parents]
        bases += [Path(p) for p in os.environ.get("GAZEBO_RESOURCE_PATH", "").split(os.pathsep) if p]
        return list(dict.fromkeys(bases))

    def _existing(self, target: Path, uri: str) -> Path | None:
        """``target`` if it exists, else the one entry of its folder whose name differs from it only in case."""
        if target.exists():
            return target
        folder = target.parent
        if not folder.is_dir():
            return None
        matches = [p for p in folder.iterdir() if p.name.lower() == target.name.lower()]
        if len(matches) != 1:
            return None
        self.case_fixed.append(f"{uri}: {matches[0]}")
        return matches[0]

    def _found(self, target: Path, uri: str, path: Path, element: str) -> Path | None:
        found = self._existing(target, uri)
        if found is not None:
            return found
        return self._missing(f"{path}: {element} {uri}: {target} does not exist", uri)

    def _missing(self, message: str, uri: str) -> Path | None:
        """Nothing found: an error with ``strict``, else counted (and said by the reader at the end)."""
        if self.strict:
            raise MapFileError(message)
        self.missing.append(uri)
        return None


def model_file(folder: Path) -> Path:
    """A model folder's SDF file: the one its ``model.config`` names, else ``model.sdf``."""
    config = folder / "model.config"
    if config.is_file():
        try:
            names = [e.text.strip() for e in ET.parse(config).getroot().iter("sdf") if e.text and e.text.strip()]
        except ET.ParseError:
            names = []
        for name in reversed(names):  # the newest version is usually listed last
            if (folder / name).is_file():
                return folder / name
    if (folder / "model.sdf").is_file():
        return folder / "model.sdf"
    raise MissingFileError(f"model folder {folder} has no model.sdf (nor a model.config naming one)")
