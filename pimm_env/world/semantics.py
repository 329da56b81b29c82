"""Semantic classes of the world, shared by the simulator, the maps and the perception stack."""

from __future__ import annotations

from enum import IntEnum

from pimm_env.errors import WorldError


class SemanticClass(IntEnum):
    """What a surface is, as the thesis's segmentation network labels it (section 3.2.2)."""

    WALL = 0
    CEILING = 1
    FLOOR = 2
    CLUTTER = 3


#: Label of a LiDAR ray that hit nothing within range.
NO_RETURN = -1

CLASS_NAMES: tuple[str, ...] = tuple(c.name.lower() for c in SemanticClass)


def parse_class(name: str) -> SemanticClass:
    """Return the class called ``name`` (``wall``, ``ceiling``, ``floor`` or ``clutter``)."""
    try:
        return SemanticClass[name.upper()]
    except KeyError:
        raise WorldError(f"unknown semantic class {name!r}; expected one of {', '.join(CLASS_NAMES)}") from None
