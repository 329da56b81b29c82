"""The pybullet scene of a world: one static body per element, each with its semantic class."""

from __future__ import annotations

import numpy as np

from pimm_env.sim.triangles import prism_mesh
from pimm_env.world.files import World
from pimm_env.world.shapes import Box, Cylinder, Mesh, Shape


class BulletScene:
    """A headless pybullet client holding ``world``'s elements and a visual body for the robot."""

    def __init__(self, world: World, robot_radius: float, robot_height: float = 0.4) -> None:
        from pimm_env.sim.quiet import silenced_console

        with silenced_console():  # pybullet's build-time and argv[0] banners
            import pybullet
            from pybullet_utils.bullet_client import BulletClient

            self.client = BulletClient(connection_mode=pybullet.DIRECT)
        self._closed = False
        classes: dict[int, int] = {}
        for element in world.elements:
            body = self._add(element.shape)
            classes[body] = int(element.semantic)
        self.body_classes = np.full(max(classes) + 1, -1, dtype=np.int8)
        for body, semantic in classes.items():
            self.body_classes[body] = semantic
        visual = self.client.createVisualShape(
            pybullet.GEOM_CYLINDER, radius=robot_radius, length=robot_height, rgbaColor=[0.2, 0.3, 0.9, 1]
        )
        # Visual only: rays and collision checks never see the robot's own body.
        self.robot_body = self.client.createMultiBody(baseMass=0, baseVisualShapeIndex=visual)
        self.robot_height = robot_height
        self.floor_z = world.floor_z

    def _add(self, shape: Shape) -> int:
        import pybullet

        c = self.client
        if isinstance(shape, Box):
            col = c.createCollisionShape(pybullet.GEOM_BOX, halfExtents=list(shape.half_extents))
            orientation = c.getQuaternionFromEuler([0.0, 0.0, shape.yaw])
            return c.createMultiBody(0, col, -1, list(shape.center), orientation)
        if isinstance(shape, Cylinder):
            z0, z1 = shape.z_range
            col = c.createCollisionShape(pybullet.GEOM_CYLINDER, radius=shape.radius, height=z1 - z0)
            return c.createMultiBody(0, col, -1, [shape.center[0], shape.center[1], (z0 + z1) / 2])
        vertices, triangles = (shape.vertices, shape.triangles) if isinstance(shape, Mesh) else prism_mesh(shape)
        col = c.createCollisionShape(
            pybullet.GEOM_MESH,
            vertices=vertices.tolist(),
            indices=triangles.reshape(-1).tolist(),
            flags=pybullet.GEOM_FORCE_CONCAVE_TRIMESH,
        )
        return c.createMultiBody(0, col, -1, [0.0, 0.0, 0.0])

    def place_robot(self, pose: np.ndarray) -> None:
        orientation = self.client.getQuaternionFromEuler([0.0, 0.0, float(pose[2])])
        position = [float(pose[0]), float(pose[1]), self.floor_z + self.robot_height / 2]
        self.client.resetBasePositionAndOrientation(self.robot_body, position, orientation)

    def close(self) -> None:
        """Disconnect; safe to call more than once."""
        if not self._closed:
            self._closed = True
            self.client.disconnect()
