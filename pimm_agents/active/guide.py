"""The active-localization env's ``guide`` observation: where to drive to tell the belief's hypotheses apart.

A robot knows its map and its belief, so the env works out for the policy where going would settle the doubt
(the map's predicted views, views.py). :class:`Guide` gives, per step, the bearing of a waypoint in the robot's
frame and how well the place it leads to tells the hypotheses apart, computed only while the localizer says
``ambiguous``. It plans far first: the map's own twins of the estimate (``MapTwins``, as PIMM's rival check finds
them) and the localizer's listed hypotheses whose predicted view fits the 2D scan nearly as well as the
estimate's (a rival listed with a wrong heading would otherwise make every place look telling) are told apart,
each, where the view at the same offset differs from the estimate's; the plan goes to the nearest place (within
60 m of path) of those that tell the most of them apart. A localizer can only be sure once every twin has
fallen, which in a corridor of look-alike bays is at its end, often beyond any near horizon. The plan is kept
while the robot follows it: when the estimate jumps to another twin the plan keeps its course relative to the
robot while that runs through open space in the new estimate's map (a plan made again at every jump turned the
robot back and forth along a corridor). Only when no place tells any twin apart does the near search (within
10 m, scored by how much better a place tells the listed hypotheses apart than where the robot is, less its
distance) show a place.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from pimm_agents.active.views import ViewConfig, ViewPredictor, in_frame, place
from pimm_env.geometry import compose, wrap_angle
from pimm_env.mapping.occupancy import OccupancyGrid
from pimm_env.mapping.twins import MapTwins, TwinConfig

if TYPE_CHECKING:
    from pimm_agents.localizer import PoseEstimate

#: the ``guide`` observation: sine and cosine of the waypoint's bearing, the place's gain, and 1 when there is one
GUIDE_SIZE = 4


@dataclass(frozen=True)
class FarPlanConfig:
    """Ours (docs/design.md#measured-choices): the far plan, made before the near search."""

    reach_m: float = 60.0  # to the nearest place within this much path (active_bound.py's reach)
    twins: int = 20  # of those that tell the estimate from the most of this many map twins (active_bound.py's)
    min_share: float = 0.1  # a place tells two views apart by this share of bearings (active_bound.py's)
    jump_m: float = 1.0  # an estimate this far from where the odometry carried the last one took another place
    jump_deg: float = 15.0  # or turned this much from it
    off_path_m: float = 2.0  # a robot this far from the plan's path (it went round something) plans again
    #: a plan made again while the robot is still in doubt counts a path that leaves backwards this much longer
    #: (views.py, ``telling_path``): a robot that had driven half a corridor toward one end, then reached the end
    #: of its plan (carried there by a jump between twins), turned back for the other end, 2 m nearer
    back_m: float = 10.0


def distinct_hypotheses(
    estimate: PoseEstimate, right_m: float = 1.0, right_deg: float = 10.0
) -> tuple[np.ndarray, np.ndarray]:
    """The estimate and its hypotheses that are not within ``right_m`` and ``right_deg`` of one listed before
    (poses (H, 3), weights (H,)); the estimate first, with the weight of its hypothesis; all 1 when every weight
    is 0."""
    poses, weights = [estimate.pose], [0.0]
    for h in estimate.hypotheses:
        pose = np.array([h.x, h.y, h.theta])
        near = [
            i
            for i, p in enumerate(poses)
            if np.hypot(*(p[:2] - pose[:2])) <= right_m and abs(wrap_angle(p[2] - pose[2])) <= np.radians(right_deg)
        ]
        if near:
            weights[near[0]] = max(weights[near[0]], float(h.weight))
        else:
            poses.append(pose)
            weights.append(float(h.weight))
    w = np.array(weights)
    return np.array(poses), (w if w.max() > 0 else np.ones_like(w))


class Guide:
    """The ``guide`` observation of one episode (see the module docstring); ``reset`` at each episode."""

    def __init__(
        self, occupancy: OccupancyGrid, config: ViewConfig | None = None, far: FarPlanConfig | None = None
    ) -> None:
        self.views = ViewPredictor(occupancy, config)
        self.far_config = far or FarPlanConfig()
        self.twins = MapTwins(occupancy, TwinConfig(max_twins=self.far_config.twins))
        self.reset()

    def reset(self) -> None:
        self.target: np.ndarray | None = None  # the place chosen last, in the robot's frame
        self.far: np.ndarray | None = None  # the far plan's path (map points, as the estimate placed it)
        self.far_share = 0.0  # the share of the estimate's twins the far plan's place tells apart
        self.carried: np.ndarray | None = None  # the estimate of the last step, carried by the odometry since
        self.failed_at: np.ndarray | None = None  # where a far plan was last looked for and none found
        self.followed = False  # a far plan was followed in this spell of doubt

    def __call__(
        self, estimate: PoseEstimate | None, scan: np.ndarray, bearings: np.ndarray, delta: np.ndarray
    ) -> np.ndarray:
        """The observation after a primitive that moved the robot by ``delta`` (x, y, heading in its frame at
        the primitive's start), with the localizer's ``estimate`` and the 2D ``scan`` (ranges at ``bearings``)."""
        out = np.zeros(GUIDE_SIZE, dtype=np.float32)
        delta = np.asarray(delta, dtype=float)
        if self.target is not None:  # carried into the robot's frame after the primitive's motion
            self.target = in_frame(delta, self.target[None, :])[0]
        carried, self.carried = self.carried, None
        if estimate is None or estimate.status != "ambiguous":
            self.target = self.far = None
            self.followed = False
            return out
        pose = np.asarray(estimate.pose, dtype=float)
        self.carried = pose.copy()
        if carried is not None:
            carried = compose(carried, delta)[0]
            c = self.far_config
            moved = np.hypot(*(pose[:2] - carried[:2]))
            if moved > c.jump_m or abs(wrap_angle(pose[2] - carried[2])) > np.radians(c.jump_deg):
                # the estimate took another place: the far plan keeps its course relative to the robot (a plan
                # dropped at every jump between twins turned the robot back and forth along a corridor)
                # while it runs through open space in the map as the new estimate places it
                if self.far is not None:
                    self.far = place(pose, in_frame(carried, self.far))
                    if not self.views.open_along(self.far):
                        self.far = None
                self.failed_at = None
        config = self.views.config
        poses, weights = distinct_hypotheses(estimate)
        misfit = self.views.misfit(poses, scan, bearings)
        plausible = misfit <= misfit[0] + config.plausible_misfit
        shown = self._far_waypoint(pose, poses[1:][plausible[1:]])
        if shown is not None:
            self.target = None
            return _shown(out, *shown)
        if plausible.sum() >= 2:
            found = self.views.best_waypoint(
                pose, poses[plausible], weights[plausible], keep=self.target, min_move=config.min_move_m
            )
            if found is not None:
                waypoint, self.target, gain = found
                return _shown(out, waypoint, gain)
        self.target = None
        return out

    def _far_waypoint(self, pose: np.ndarray, others: np.ndarray) -> tuple[np.ndarray, float] | None:
        """The far plan's waypoint (in the robot's frame) and the share of the twins its place tells apart,
        planned again when there is none, the robot reached its end or strayed from it; None when no place
        tells the estimate from any of its twins."""
        c, far = self.views.config, self.far_config
        if self.far is not None:
            gap = np.hypot(self.far[:, 0] - pose[0], self.far[:, 1] - pose[1])
            if gap[-1] < c.min_move_m or gap.min() > far.off_path_m:
                self.far = None
        if self.far is None:
            if self.failed_at is not None and np.hypot(*(pose[:2] - self.failed_at[:2])) < c.min_move_m:
                return None  # looked for from about here already
            twins = np.vstack([self.twins.of(pose), np.asarray(others, dtype=float).reshape(-1, 3)])
            back = far.back_m if self.followed else 0.0
            plan = self.views.telling_path(pose, twins, far.reach_m, far.min_share, c.min_move_m, back)
            if plan is None:
                self.failed_at = pose.copy()
                return None
            self.failed_at = None
            self.far, self.far_share = plan
            self.followed = True
        nearest = int(np.argmin(np.hypot(self.far[:, 0] - pose[0], self.far[:, 1] - pose[1])))
        return in_frame(pose, self.views.steer(self.far, nearest, pose)[None, :])[0], self.far_share


def _shown(out: np.ndarray, waypoint: np.ndarray, gain: float) -> np.ndarray:
    """The guide observation of a waypoint (robot frame) toward a place that tells apart by ``gain``."""
    bearing = float(np.arctan2(waypoint[1], waypoint[0]))
    out[:] = (np.sin(bearing), np.cos(bearing), np.clip(gain, 0.0, 1.0), 1.0)
    return out
