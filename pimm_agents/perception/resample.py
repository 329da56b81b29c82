"""A 3D scan of one LiDAR layout as the network's layout: each of the network's rays takes the return of the
nearest ray of the sensor (by elevation ring and azimuth column), or none where the sensor does not look.

PIMM's network was trained on the thesis's 40 x 360 organized scans over 120 deg; a real sensor (an Ouster OS0-64:
64 x 1024 over 90 deg) is read through this instead of retraining. Rays of the network's layout outside the
sensor's vertical field (beyond half a ring spacing) get no return, as the thesis's LiDAR gets none in open space.
"""

from __future__ import annotations

import numpy as np

from pimm_env.errors import ObservationError
from pimm_env.sim.lidar import Lidar3DConfig, azimuths_3d, elevations_3d


class LayoutResampler:
    """``resampler(cloud, mask) -> (cloud, mask)`` from ``source``'s layout to ``target``'s."""

    def __init__(self, source: Lidar3DConfig, target: Lidar3DConfig) -> None:
        self.source, self.target = source, target
        src_el, src_az = elevations_3d(source), azimuths_3d(source)
        tgt_el, tgt_az = elevations_3d(target), azimuths_3d(target)
        ring = np.abs(tgt_el[:, None] - src_el[None, :]).argmin(axis=1)
        spacing = np.radians(source.vertical_fov_deg) / max(1, source.layers - 1)
        covered = np.abs(tgt_el - src_el[ring]) <= spacing / 2 + 1e-9
        step = 2 * np.pi / source.points_per_layer
        column = np.round((tgt_az - src_az[0]) / step).astype(int) % source.points_per_layer
        index = ring[:, None] * source.points_per_layer + column[None, :]
        self.index = np.where(covered[:, None], index, -1).reshape(-1)

    def __call__(self, cloud: np.ndarray, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        cloud, mask = np.asarray(cloud), np.asarray(mask).astype(bool)
        if len(cloud) != self.source.num_points or len(mask) != len(cloud):
            raise ObservationError(
                f"observation 'cloud' has {len(cloud)} points (mask {len(mask)}); the {self.source.layers} x "
                f"{self.source.points_per_layer} LiDAR gives {self.source.num_points} (see --sensors)"
            )
        have = self.index >= 0
        taken = np.where(have, self.index, 0)
        out_mask = have & mask[taken]
        out = np.where(out_mask[:, None], cloud[taken], 0.0).astype(np.float32)
        return out, out_mask
