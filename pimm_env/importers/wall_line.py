"""Objects standing in a wall's line take the wall's class: windows, closed doors, panels filling an opening.

Name rules class a Gazebo world's ``RoomWindow_01`` and ``Door_01`` clutter, yet each stands in its wall's line
(their collision boxes are 0.10-0.15 m thick and fill the wall's opening): a LiDAR sees them where the wall is,
the occupancy map draws them as the wall's line, and a real scan's plane-fit reference counts what lies in a
wall's plane as wall. The import decides it from the geometry, not from names (by name an open door would be
wall too): an object not classed wall, floor or ceiling is in a wall's line when

- its footprint is thin: the narrow side of its smallest enclosing rectangle is at most ``THICKNESS_M``;
- and at least ``MIN_LENGTH_M`` long;
- at its mid-height, no wall runs alongside it (within ``ACROSS_M`` of its mid-line) over half its length or
  more: it fills an opening rather than stands in front of a wall;
- past each of its two ends, the walls' cross-section at that height comes within ``REACH_M`` of the end and
  ``ACROSS_M`` of the mid-line: the wall goes on where the object stops, or meets it. Another such object closes
  an end as a wall does (windows side by side, or round a corner), as long as the chain meets a wall.

A cabinet against a wall is too deep, a picture or a shelf board has the wall alongside it, an open door leaf
has a wall at its hinge and nothing at its other end. The names found are written into the world
file (``wall_line``), where a user can remove any.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from pimm_env.world.model import Element
from pimm_env.world.semantics import SemanticClass
from pimm_env.world.shapes import Mesh, segment_points

THICKNESS_M = 0.3  # a window's or a door's box is 0.10-0.15 m; a wall 0.1-0.3 m
REACH_M = 0.4  # the wall goes on within this beyond each end
ACROSS_M = 0.2  # the wall's faces lie within this of the object's mid-line
MIN_LENGTH_M = 0.5  # and at least this long (not a handle or a switch)
SAMPLE_M = 0.05  # the walls' cross-sections are read as points this far apart
ALONGSIDE_SHARE = 0.5  # a wall alongside over this share of its length: it stands in front of the wall
_STRUCTURE = (SemanticClass.WALL, SemanticClass.FLOOR, SemanticClass.CEILING)


Rectangle = tuple[np.ndarray, np.ndarray, float, float]  # centre, unit vector along, half length, half width


def footprint_rectangle(points: np.ndarray) -> Rectangle:
    """The smallest rectangle enclosing the (N, 2) ``points``: its centre, the unit vector along its long side,
    and its half length and half width."""
    from scipy.spatial import ConvexHull, QhullError

    points = np.asarray(points, dtype=float)
    try:
        hull = points[ConvexHull(points).vertices]
    except (QhullError, ValueError):  # all on a line (or a point): the line is the rectangle
        hull = points
    best: tuple[float, np.ndarray, np.ndarray, float, float] | None = None
    edges = np.diff(np.vstack([hull, hull[:1]]), axis=0)
    for edge in edges[np.linalg.norm(edges, axis=1) > 1e-9]:
        u = edge / np.linalg.norm(edge)
        v = np.array([-u[1], u[0]])
        a, b = hull @ u, hull @ v
        area = float(np.ptp(a) * np.ptp(b))
        if best is None or area < best[0]:
            centre = u * (a.max() + a.min()) / 2 + v * (b.max() + b.min()) / 2
            best = (area, centre, u, float(np.ptp(a)) / 2, float(np.ptp(b)) / 2)
    if best is None:
        return points.mean(axis=0), np.array([1.0, 0.0]), 0.0, 0.0
    _, centre, u, half_a, half_b = best
    if half_b > half_a:  # the long side first
        return centre, np.array([-u[1], u[0]]), half_b, half_a
    return centre, u, half_a, half_b


def _frame(points: np.ndarray, rectangle: Rectangle) -> tuple[np.ndarray, np.ndarray]:
    """``points`` (N, 2) in an object's frame: along its length and across it, from its centre."""
    centre, along, _, _ = rectangle
    across = np.array([-along[1], along[0]])
    return (points - centre) @ along, (points - centre) @ across


def end_closed(points: np.ndarray, rectangle: Rectangle, end: float) -> bool:
    """Whether structure (``points`` of a cross-section, (N, 2)) lies past one end (``end`` +1 or -1 along the
    object's length) of an object's footprint ``rectangle``, within ``REACH_M`` past it and ``ACROSS_M`` of its
    mid-line: the wall goes on there, or meets it."""
    s, c = _frame(points, rectangle)
    half_length = rectangle[2]
    return bool(np.any((end * s > half_length) & (end * s <= half_length + REACH_M) & (np.abs(c) <= ACROSS_M)))


def alongside_clear(points: np.ndarray, rectangle: Rectangle) -> bool:
    """Whether walls (``points`` of their cross-section) run alongside the object, within ``ACROSS_M`` of its
    mid-line, over less than ``ALONGSIDE_SHARE`` of its length: it stands in an opening (whose edges its box
    may overlap by a few centimetres), not in front of a wall."""
    s, c = _frame(points, rectangle)
    half_length = rectangle[2]
    beside = (np.abs(s) < half_length) & (np.abs(c) <= ACROSS_M)
    bins = max(1, int(np.ceil(2 * half_length / SAMPLE_M)))
    covered = np.unique(np.clip(((s[beside] + half_length) / SAMPLE_M).astype(int), 0, bins - 1))
    return len(covered) < ALONGSIDE_SHARE * bins


def wall_line_objects(elements: Iterable[Element]) -> list[str]:
    """The names of the objects (not wall, floor or ceiling) that stand in a wall's line (module docstring)."""
    elements = list(elements)
    walls = [e for e in elements if e.semantic == SemanticClass.WALL and isinstance(e.shape, Mesh)]
    thin: dict[str, tuple[Element, Rectangle, float]] = {}
    for element in elements:
        if element.semantic in _STRUCTURE or not isinstance(element.shape, Mesh):
            continue
        rectangle = footprint_rectangle(element.shape.vertices[:, :2])
        if 2 * rectangle[3] <= THICKNESS_M and 2 * rectangle[2] >= MIN_LENGTH_M:
            thin[element.name] = (element, rectangle, float(np.mean(element.shape.z_range)))
    cache: dict[tuple[str, float], np.ndarray] = {}

    def section(element: Element, z: float) -> np.ndarray:
        if (element.name, z) not in cache:
            assert isinstance(element.shape, Mesh)
            cache[element.name, z] = segment_points(element.shape.section(z), SAMPLE_M)
        return cache[element.name, z]

    def _points(name: str, others: Iterable[Element]) -> np.ndarray:
        z = thin[name][2]
        points = [section(e, z) for e in others if e.name != name]
        return np.concatenate(points) if points else np.zeros((0, 2))

    def ends_closed(name: str, others: Iterable[Element]) -> tuple[bool, bool]:
        points = _points(name, others)
        return end_closed(points, thin[name][1], 1.0), end_closed(points, thin[name][1], -1.0)

    # the objects each of whose ends is closed by a wall or by another such object (windows side by side and
    # round a corner close each other's ends): drop those with an open end until none is left to drop
    standing = {n for n in thin if alongside_clear(_points(n, walls), thin[n][1])}
    while True:
        support = walls + [thin[n][0] for n in standing]
        dropped = {n for n in standing if not all(ends_closed(n, support))}
        if not dropped:
            break
        standing -= dropped
    # and of those, the ones joined to a wall through such ends (not a ring of boards standing on its own)
    joined: set[str] = set()
    while True:
        support = walls + [thin[n][0] for n in joined]
        added = {n for n in standing - joined if any(ends_closed(n, support))}
        if not added:
            return sorted(joined)
        joined |= added
