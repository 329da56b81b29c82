"""The true pose from a bag's ``/tf``: the robot's base in the map frame, as a SLAM or a motion-capture system
publishes it.

A ``tf2_msgs/TFMessage`` carries a list of ``TransformStamped``; the pose is taken from a transform map -> base
when the bag has one, else composed from the latest map -> odom and odom -> base (the usual ROS chain, REP 105).
Frame names are compared without a leading slash (ROS 1 writes ``/map``). A message that changes neither link
gives no new pose.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from pimm_env.bags.messages import BagError, planar_pose
from pimm_env.geometry import compose

#: Frame names a robot's base goes by.
BASE_FRAMES = ("base_link", "base_footprint")


def _frame(name: str) -> str:
    return name.lstrip("/")


class TfTruth:
    """Follows the transforms of one ``/tf`` stream and gives the base's pose in ``map_frame``."""

    def __init__(self, map_frame: str = "map", odom_frame: str = "odom", base_frames: tuple[str, ...] = BASE_FRAMES):
        self.map_frame, self.odom_frame, self.base_frames = map_frame, odom_frame, base_frames
        self._map_odom: np.ndarray | None = None
        self._odom_base: np.ndarray | None = None
        self._map_base: np.ndarray | None = None

    def update(self, msg: Any, where: str) -> np.ndarray | None:
        """The base's pose after ``msg`` (a TFMessage), or None when it says nothing new about it."""
        transforms = getattr(msg, "transforms", None)
        if transforms is None:
            raise BagError(f"{where}: a {type(msg).__name__} is not a tf2_msgs/TFMessage")
        changed = False
        for transform in transforms:
            parent, child = _frame(transform.header.frame_id), _frame(transform.child_frame_id)
            if parent == self.map_frame and child in self.base_frames:
                self._map_base, changed = planar_pose(transform, where), True
            elif parent == self.map_frame and child == self.odom_frame:
                self._map_odom, changed = planar_pose(transform, where), True
            elif parent == self.odom_frame and child in self.base_frames:
                self._odom_base, changed = planar_pose(transform, where), True
        if not changed:
            return None
        if self._map_base is not None:
            return self._map_base.copy()
        if self._map_odom is not None and self._odom_base is not None:
            return compose(self._map_odom, self._odom_base)[0]
        return None
