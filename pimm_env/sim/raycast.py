"""Ray casting for the LiDARs: pybullet's ``rayTestBatch`` and Open3D's Embree scene for any world, and an
exact fast path for worlds made only of boxes with vertical sides and vertical cylinders.

Every LiDAR ray of one scan leaves the same origin. A vertical plane through the origin at azimuth ``a``
cuts each prism in a rectangle: the stretch ``[s_in, s_out]`` of horizontal distance where the 2D ray is
inside the prism's footprint, times the prism's height range ``[z0, z1]``. A ray at elevation ``e`` is the
line ``z = z_origin + s tan(e)`` in that plane, so its first hit is a closed-form test against a handful
of rectangles per azimuth. This is about ten times faster than pybullet on the iilab and gives the
same ranges, which a test checks. Embree (Open3D) is faster still and its cost does not grow with the number
of elements (``evaluate.py bench``: ``lidar3d_*_ms``), so it is the default for every world.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from pimm_env.errors import EnvError
from pimm_env.sim.lidar import cast_rays
from pimm_env.sim.triangles import shape_mesh
from pimm_env.world.files import World
from pimm_env.world.shapes import Box, Cylinder


class RayCaster(Protocol):
    def cast(
        self, origin: np.ndarray, azimuths: np.ndarray, elevations: np.ndarray, max_range: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """Range (``inf`` for no hit within ``max_range``) and semantic label (-1) of every ray, shape (E, A).

        ``azimuths`` are in the map frame; rays are ordered elevation-major.
        """
        ...


class DirectionCaster(Protocol):
    def cast_directions(
        self, origin: np.ndarray, directions: np.ndarray, max_range: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """Range and label of rays along unit ``directions`` (N, 3) in the map frame, shape (N,): for a
        tilted sensor, whose rays are no grid of azimuths and elevations."""
        ...


def _directions(azimuths: np.ndarray, elevations: np.ndarray) -> np.ndarray:
    """Unit vectors (E, A, 3) of the rays; each sine and cosine taken once per angle, not once per ray."""
    cos_el, sin_el = np.cos(elevations)[:, None], np.sin(elevations)[:, None]
    out = np.empty((len(elevations), len(azimuths), 3))
    np.multiply(cos_el, np.cos(azimuths)[None, :], out=out[..., 0])
    np.multiply(cos_el, np.sin(azimuths)[None, :], out=out[..., 1])
    out[..., 2] = sin_el
    return out


class BulletRayCaster:
    """Casts rays in a pybullet scene (any shapes, meshes included)."""

    def __init__(self, client, body_classes: np.ndarray) -> None:
        self.client = client
        self.body_classes = body_classes

    def cast(self, origin, azimuths, elevations, max_range):
        ranges, labels = self.cast_directions(origin, _directions(azimuths, elevations).reshape(-1, 3), max_range)
        shape = (len(elevations), len(azimuths))
        return ranges.reshape(shape), labels.reshape(shape)

    def cast_directions(self, origin, directions, max_range):
        origins = np.broadcast_to(origin, directions.shape)
        fractions, bodies = cast_rays(self.client, origins, origins + directions * max_range)
        hit = bodies >= 0
        ranges = np.where(hit, fractions * max_range, np.inf)
        labels = np.full(len(bodies), -1, dtype=np.int8)
        labels[hit] = self.body_classes[bodies[hit]]
        return ranges, labels


class PrismRayCaster:
    """Exact ray casting against boxes with vertical sides and vertical cylinders, vectorized in numpy."""

    def __init__(self, world: World) -> None:
        boxes = [e for e in world.elements if isinstance(e.shape, Box)]
        cylinders = [e for e in world.elements if isinstance(e.shape, Cylinder)]
        if len(boxes) + len(cylinders) != len(world.elements):
            raise EnvError(f"world {world.name!r} has shapes other than boxes and cylinders")
        box_shapes = [b.shape for b in boxes if isinstance(b.shape, Box)]
        cylinder_shapes = [c.shape for c in cylinders if isinstance(c.shape, Cylinder)]
        self.box_center = np.array([b.center[:2] for b in box_shapes]).reshape(-1, 2)
        self.box_half = np.array([b.half_extents[:2] for b in box_shapes]).reshape(-1, 2)
        yaw = np.array([b.yaw for b in box_shapes])
        self.box_cos, self.box_sin = np.cos(yaw), np.sin(yaw)
        self.cyl_center = np.array([c.center for c in cylinder_shapes]).reshape(-1, 2)
        self.cyl_radius = np.array([c.radius for c in cylinder_shapes])
        z_ranges = [s.z_range for s in box_shapes] + [s.z_range for s in cylinder_shapes]
        self.z_range = np.array(z_ranges).reshape(-1, 2)
        self.labels = np.array([int(e.semantic) for e in boxes + cylinders], dtype=np.int8)

    @staticmethod
    def supports(world: World) -> bool:
        return all(isinstance(e.shape, (Box, Cylinder)) for e in world.elements)

    def _spans(self, origin_xy: np.ndarray, azimuths: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Horizontal entry and exit distance of each azimuth's 2D ray through each footprint, (A, P)."""
        ux, uy = np.cos(azimuths)[:, None], np.sin(azimuths)[:, None]
        with np.errstate(divide="ignore", invalid="ignore"):
            # Boxes: slab test in each box's own frame.
            px = origin_xy[0] - self.box_center[:, 0]
            py = origin_xy[1] - self.box_center[:, 1]
            lx = self.box_cos * px + self.box_sin * py
            ly = -self.box_sin * px + self.box_cos * py
            dx = self.box_cos * ux + self.box_sin * uy
            dy = -self.box_sin * ux + self.box_cos * uy
            tx1, tx2 = (-self.box_half[:, 0] - lx) / dx, (self.box_half[:, 0] - lx) / dx
            ty1, ty2 = (-self.box_half[:, 1] - ly) / dy, (self.box_half[:, 1] - ly) / dy
            # A ray parallel to a slab is inside it for all s or for none.
            inside_x = np.abs(lx) <= self.box_half[:, 0]
            inside_y = np.abs(ly) <= self.box_half[:, 1]
            tx_lo = np.where(dx == 0, np.where(inside_x, -np.inf, np.inf), np.minimum(tx1, tx2))
            tx_hi = np.where(dx == 0, np.where(inside_x, np.inf, -np.inf), np.maximum(tx1, tx2))
            ty_lo = np.where(dy == 0, np.where(inside_y, -np.inf, np.inf), np.minimum(ty1, ty2))
            ty_hi = np.where(dy == 0, np.where(inside_y, np.inf, -np.inf), np.maximum(ty1, ty2))
            box_in = np.maximum(tx_lo, ty_lo)
            box_out = np.minimum(tx_hi, ty_hi)
        # Cylinders: 2D ray against a circle.
        fx = origin_xy[0] - self.cyl_center[:, 0]
        fy = origin_xy[1] - self.cyl_center[:, 1]
        b = fx * ux + fy * uy
        disc = b * b - (fx * fx + fy * fy - self.cyl_radius**2)
        root = np.sqrt(np.maximum(disc, 0.0))
        cyl_in = np.where(disc >= 0, -b - root, np.inf)
        cyl_out = np.where(disc >= 0, -b + root, -np.inf)
        s_in = np.concatenate([box_in, cyl_in], axis=1)
        s_out = np.concatenate([box_out, cyl_out], axis=1)
        return np.maximum(s_in, 0.0), s_out

    def cast(self, origin, azimuths, elevations, max_range):
        origin = np.asarray(origin, dtype=float)
        s_in, s_out = self._spans(origin[:2], np.asarray(azimuths, dtype=float))
        valid = (s_out >= s_in) & (s_in <= max_range)
        k = max(1, int(valid.sum(axis=1).max()))
        # Keep only the k candidate prisms of each azimuth (most prisms are behind or beside the ray).
        order = np.argsort(~valid, axis=1, kind="stable")[:, :k]
        s_in = np.take_along_axis(s_in, order, axis=1)[None]
        s_out = np.take_along_axis(s_out, order, axis=1)[None]
        ok = np.take_along_axis(valid, order, axis=1)[None]
        s_in = np.where(ok, s_in, 0.0)  # padding columns: keep them finite, they are masked below
        s_out = np.where(ok, s_out, -1.0)
        z0 = self.z_range[order, 0][None]
        z1 = self.z_range[order, 1][None]
        slope = np.tan(np.asarray(elevations, dtype=float))[:, None, None]
        z_at_entry = origin[2] + slope * s_in
        side = (z_at_entry >= z0) & (z_at_entry <= z1)
        with np.errstate(divide="ignore", invalid="ignore"):
            s_bottom = (z0 - origin[2]) / slope  # rising ray meets the underside
            s_top = (z1 - origin[2]) / slope  # falling ray meets the top
        below = (slope > 0) & (z_at_entry < z0) & (s_bottom <= s_out)
        above = (slope < 0) & (z_at_entry > z1) & (s_top <= s_out)
        s_hit = np.where(side, s_in, np.where(below, s_bottom, np.where(above, s_top, np.inf)))
        s_hit = np.where(ok, s_hit, np.inf)
        nearest = np.argmin(s_hit, axis=2)
        s_best = np.take_along_axis(s_hit, nearest[..., None], axis=2)[..., 0]
        ranges = s_best / np.cos(np.asarray(elevations, dtype=float))[:, None]
        hit = ranges <= max_range
        prism = order[np.arange(order.shape[0])[None, :], nearest]
        labels = np.where(hit, self.labels[prism], -1)
        return np.where(hit, ranges, np.inf), labels.astype(np.int8)


class EmbreeRayCaster:
    """Open3D's ``RaycastingScene`` (Embree's bounding-volume hierarchy) over every element as triangles.

    Any world, meshes and floor-plan prisms included; its cost grows with the log of the triangle count, not
    with the number of elements as the prism caster's does. Cylinders become 48-sided prisms.
    """

    def __init__(self, world: World) -> None:
        import open3d as o3d

        self.scene = o3d.t.geometry.RaycastingScene()
        elements: dict[int, int] = {}  # Open3D's geometry id -> index in world.elements
        for index, element in enumerate(world.elements):
            vertices, triangles = shape_mesh(element.shape)
            geometry = self.scene.add_triangles(
                o3d.core.Tensor.from_numpy(vertices.astype(np.float32)),
                o3d.core.Tensor.from_numpy(triangles.astype(np.uint32)),
            )
            elements[int(geometry)] = index
        self.elements = np.full(max(elements) + 2, -1, dtype=np.int64)  # the last entry: Open3D's "no geometry"
        self.labels = np.full(len(self.elements), -1, dtype=np.int8)
        for geometry, index in elements.items():
            self.elements[geometry], self.labels[geometry] = index, int(world.elements[index].semantic)

    def cast(self, origin, azimuths, elevations, max_range):
        ranges, labels = self.cast_directions(origin, _directions(azimuths, elevations).reshape(-1, 3), max_range)
        shape = (len(elevations), len(azimuths))
        return ranges.reshape(shape), labels.reshape(shape)

    def cast_directions(self, origin, directions, max_range):
        t_hit, geometry = self._first_hits(origin, directions)
        hit = np.isfinite(t_hit) & (t_hit <= max_range)
        ranges = np.where(hit, t_hit.astype(float), np.inf)
        labels = np.where(hit, self.labels[np.clip(geometry, 0, len(self.labels) - 1)], -1).astype(np.int8)
        return ranges, labels

    def cast_elements(self, origin, directions, max_range):
        """Per ray along ``directions`` from ``origin``, the index in ``world.elements`` of what it hits first
        within ``max_range`` (-1: nothing)."""
        t_hit, geometry = self._first_hits(origin, directions)
        hit = np.isfinite(t_hit) & (t_hit <= max_range)
        return np.where(hit, self.elements[np.clip(geometry, 0, len(self.elements) - 1)], -1)

    def _first_hits(self, origin, directions) -> tuple[np.ndarray, np.ndarray]:
        """Distance to the first hit (float32, inf: none) and Open3D's geometry id of it, per ray."""
        import open3d as o3d

        rays = np.empty((len(directions), 6), dtype=np.float32)
        rays[:, :3] = origin
        rays[:, 3:] = directions
        answer = self.scene.cast_rays(o3d.core.Tensor.from_numpy(rays))
        return answer["t_hit"].numpy(), answer["geometry_ids"].numpy().astype(np.int64)
