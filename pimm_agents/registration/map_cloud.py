"""The map as a point cloud: the world's surfaces sampled evenly, the faces no sensor in free space can see
left out, and FPFH features (Rusu et al. 2009, Open3D's implementation) for global matching."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from pimm_env.mapping.occupancy import OccupancyGrid
from pimm_env.world.model import World


@dataclass(frozen=True)
class MapCloud:
    points: np.ndarray  # (M, 3) map frame, z above the world's floor
    normals: np.ndarray  # (M, 3)
    features: np.ndarray  # (M, 33) FPFH, float32


def sample_surfaces(world: World, spacing: float, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Points about ``spacing`` apart over every element's surface, with each face's normal (z from the
    world's floor)."""
    from pimm_env.sim.triangles import shape_mesh

    points, normals = [], []
    for element in world.elements:
        vertices, triangles = shape_mesh(element.shape)
        corners = vertices[triangles]  # (T, 3, 3)
        cross = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
        area = 0.5 * np.linalg.norm(cross, axis=1)
        keep = area > 1e-9
        corners, cross, area = corners[keep], cross[keep], area[keep]
        count = rng.poisson(area / spacing**2)
        face = np.repeat(np.arange(len(area)), count)
        u, v = rng.random((2, len(face)))
        flip = u + v > 1
        u, v = np.where(flip, 1 - u, u), np.where(flip, 1 - v, v)
        c = corners[face]
        points.append(c[:, 0] + u[:, None] * (c[:, 1] - c[:, 0]) + v[:, None] * (c[:, 2] - c[:, 0]))
        normals.append(cross[face] / (2 * area[face, None]))
    p, n = np.vstack(points), np.vstack(normals)
    p[:, 2] -= world.floor_z
    return p, n


def visible(points: np.ndarray, occupancy: OccupancyGrid, reach: float) -> np.ndarray:
    """Points whose (x, y) lies within ``reach`` of a free cell: floors, ceilings and wall faces over or
    beside the free space, not the outside of the building or the inside of a thick wall."""
    from scipy import ndimage

    near_free = ndimage.distance_transform_edt(~occupancy.free) * occupancy.grid.resolution <= reach
    rows, cols, inside = occupancy.grid.cells_of(points[:, :2])
    keep = np.zeros(len(points), dtype=bool)
    keep[inside] = near_free[rows[inside], cols[inside]]
    return keep


def to_open3d(points: np.ndarray, normals: np.ndarray | None = None) -> Any:
    import open3d as o3d

    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.asarray(points, dtype=np.float64)))
    if normals is not None:
        cloud.normals = o3d.utility.Vector3dVector(np.asarray(normals, dtype=np.float64))
    return cloud


def fpfh(cloud: Any, voxel: float) -> np.ndarray:
    """Open3D's FPFH of ``cloud`` (which has normals) over a radius of 5 voxels: (N, 33) float32."""
    import open3d as o3d

    search = o3d.geometry.KDTreeSearchParamHybrid(radius=5 * voxel, max_nn=100)
    feature = o3d.pipelines.registration.compute_fpfh_feature(cloud, search)  # type: ignore[call-arg]
    return np.asarray(feature.data, dtype=np.float32).T.copy()


def build_map_cloud(world: World, occupancy: OccupancyGrid, voxel: float, seed: int = 0) -> MapCloud:
    """The world's visible surfaces, sampled at a quarter voxel and thinned to one point per ``voxel``."""
    points, normals = sample_surfaces(world, voxel / 4, np.random.default_rng(seed))
    keep = visible(points, occupancy, reach=0.15)
    cloud = to_open3d(points[keep], normals[keep]).voxel_down_sample(voxel)
    outward = np.asarray(cloud.normals).copy()  # faces' normals averaged per voxel: they point to free space
    estimate_normals(cloud, voxel)  # the local plane's (a thin wall's two faces cancel in the average)
    normals = np.asarray(cloud.normals)
    normals[np.einsum("ij,ij->i", normals, outward) < 0] *= -1
    cloud.normals = to_open3d(normals).points
    return MapCloud(np.asarray(cloud.points), normals.copy(), fpfh(cloud, voxel))


def estimate_normals(cloud: Any, voxel: float) -> None:
    """Normals of the local planes (2 voxels around, at most 30 points), in place."""
    import open3d as o3d

    cloud.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(radius=2 * voxel, max_nn=30))
