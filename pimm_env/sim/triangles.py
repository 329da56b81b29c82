"""Every world shape as a triangle mesh, for triangle ray casters (Embree) and pybullet's static meshes."""

from __future__ import annotations

import numpy as np

from pimm_env.world.shapes import Box, Cylinder, Mesh, Prism, Shape

#: Sides of the polygon that stands in for a cylinder: the chord is off the circle by r (1 - cos(pi/48)),
#: 0.2 % of the radius (0.4 mm for a 0.2 m post).
CYLINDER_SIDES = 48


def _extrude(rings: list[np.ndarray], caps: np.ndarray, z0: float, z1: float) -> tuple[np.ndarray, np.ndarray]:
    """Vertical walls along every ring and the cap triangles ``caps`` (T, 3, 2) at both heights."""
    vertices: list[np.ndarray] = []
    triangles: list[np.ndarray] = []
    offset = 0
    for ring in rings:
        n = len(ring)
        vertices += [np.column_stack([ring, np.full(n, z0)]), np.column_stack([ring, np.full(n, z1)])]
        i = np.arange(n)
        j = (i + 1) % n
        bottom, top = offset + i, offset + n + i
        triangles += [np.stack([bottom, offset + j, top], 1), np.stack([offset + j, offset + n + j, top], 1)]
        offset += 2 * n
    if len(caps):
        flat = caps.reshape(-1, 2)
        m = len(flat)
        vertices += [np.column_stack([flat, np.full(m, z0)]), np.column_stack([flat, np.full(m, z1)])]
        idx = np.arange(m).reshape(-1, 3)
        triangles += [offset + idx[:, ::-1], offset + m + idx]
    return np.concatenate(vertices), np.concatenate(triangles).astype(np.int32)


def box_mesh(box: Box) -> tuple[np.ndarray, np.ndarray]:
    ring = box.corners_xy()
    caps = np.array([[ring[0], ring[1], ring[2]], [ring[0], ring[2], ring[3]]])
    return _extrude([ring], caps, *box.z_range)


def cylinder_mesh(cylinder: Cylinder) -> tuple[np.ndarray, np.ndarray]:
    angles = 2 * np.pi * np.arange(CYLINDER_SIDES) / CYLINDER_SIDES
    ring = np.asarray(cylinder.center) + cylinder.radius * np.column_stack([np.cos(angles), np.sin(angles)])
    caps = np.stack([np.broadcast_to(cylinder.center, ring.shape), ring, np.roll(ring, -1, axis=0)], axis=1)
    return _extrude([ring], caps, *cylinder.z_range)


def prism_mesh(prism: Prism) -> tuple[np.ndarray, np.ndarray]:
    """Side walls along the outline and the holes, and both caps (constrained Delaunay of the polygon)."""
    return _extrude(prism.rings(), _cap_triangles(prism), *prism.z_range)


def _cap_triangles(prism: Prism) -> np.ndarray:
    """Triangles (T, 3, 2) covering the prism's polygon: constrained Delaunay of each valid part, or, where
    GEOS refuses a part (rings that touch themselves), Delaunay triangles whose centroid lies inside it."""
    import shapely
    from shapely.errors import GEOSException
    from shapely.geometry import Polygon

    valid = shapely.make_valid(Polygon(prism.outline, list(prism.holes)))
    triangles = []
    for part in getattr(valid, "geoms", [valid]):
        if part.geom_type != "Polygon" or part.is_empty:
            continue
        try:
            pieces = list(shapely.constrained_delaunay_triangles(part).geoms)
        except GEOSException:
            pieces = [t for t in shapely.delaunay_triangles(part).geoms if part.contains(t.centroid)]
        triangles += [np.asarray(t.exterior.coords)[:3] for t in pieces]
    return np.array(triangles, dtype=float).reshape(-1, 3, 2)


def shape_mesh(shape: Shape) -> tuple[np.ndarray, np.ndarray]:
    """(vertices (V, 3) float, triangles (T, 3) int) of any world shape."""
    if isinstance(shape, Box):
        return box_mesh(shape)
    if isinstance(shape, Cylinder):
        return cylinder_mesh(shape)
    if isinstance(shape, Prism):
        return prism_mesh(shape)
    if isinstance(shape, Mesh):
        return np.asarray(shape.vertices, dtype=float), np.asarray(shape.triangles, dtype=np.int32)
    raise TypeError(f"no triangle mesh for shape {type(shape).__name__}")
