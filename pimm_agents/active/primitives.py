"""The active-localization env's actions: three motion primitives, each about a second of driving.

Primitives rather than velocities: a policy choosing among "forward 0.5 m", "turn left 45 deg" and "turn right
45 deg" sees the effect of each choice in the next belief (a velocity held for one 32 ms control step changes
nothing a localizer can see), an episode is tens of decisions instead of thousands, and a guard can keep each
one safe. The forward primitive stops when the 2D scan shows anything within ``stop_range`` in a 60 deg cone
ahead (what a robot's own bumper-less safety layer does) or in the lane its body sweeps, and stands still for
the rest of its second, so a policy cannot drive into a wall by choice and every primitive takes its time (a
blocked forward that took none would let a policy that keeps choosing it stop the clock); a turn in place
cannot hit anything the robot is not already touching.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np


@dataclass(frozen=True)
class Primitive:
    name: str
    linear: float  # m/s
    angular: float  # rad/s
    duration: float  # s


#: forward 0.5 m at 0.5 m/s (the generated routes' speed); turns of 45 deg at 0.785 rad/s
PRIMITIVES: tuple[Primitive, ...] = (
    Primitive("forward", 0.5, 0.0, 1.0),
    Primitive("left", 0.0, np.pi / 4, 1.0),
    Primitive("right", 0.0, -np.pi / 4, 1.0),
)

STOP_RANGE = 0.5  # m from the LiDAR: the forward primitive stops when anything ahead is closer
STOP_CONE = np.radians(30.0)  # half-width of the cone ahead that the stop looks at
#: half-width of the lane the body sweeps (its 0.25 m radius, robot.py, and 5 cm): the stop also looks along it,
#: out of the cone, so that the body does not graze a doorway's edge it passes (a trained policy did, once)
SWEPT_HALF_WIDTH = 0.3


def blocked_ahead(scan: np.ndarray, bearings: np.ndarray, stop_range: float = STOP_RANGE) -> bool:
    """Whether the 2D scan (ranges at ``bearings``, robot frame) sees anything within ``stop_range`` ahead: in
    the cone ahead, or in the lane the body sweeps (ahead of the robot's centre, up to ``stop_range`` on)."""
    ahead = np.abs(np.arctan2(np.sin(bearings), np.cos(bearings))) <= STOP_CONE
    return bool(np.any(scan[ahead] < stop_range) or in_lane(scan, bearings, 0.05, stop_range, SWEPT_HALF_WIDTH))


def in_lane(scan: np.ndarray, bearings: np.ndarray, start: float, end: float, half_width: float) -> bool:
    """Whether any return of the 2D scan (ranges at ``bearings``, robot frame) lies in the lane ahead from
    ``start`` to ``end`` metres along the heading and within ``half_width`` of it."""
    along, across = scan * np.cos(bearings), scan * np.sin(bearings)
    return bool(np.any((along > start) & (along < end) & (np.abs(across) < half_width)))


def drive(
    sim: Any,
    primitive: Primitive,
    obs: dict[str, np.ndarray],
    on_step: Callable[[dict[str, np.ndarray], dict[str, Any]], bool],
    bearings: np.ndarray,
) -> tuple[dict[str, np.ndarray], dict[str, Any], int, bool]:
    """Drive ``primitive`` in ``sim`` (a LidarRobotEnv, or a wrapper of one) from its current observation
    ``obs``, calling ``on_step(obs, info)`` after each control step (it returns True to end the primitive early).
    Returns the last observation and info, the steps taken and whether the forward guard stopped the robot (it
    then stood still for the primitive's remaining steps)."""
    steps = max(1, round(primitive.duration / sim.unwrapped.config.robot.control_dt))
    info: dict[str, Any] = {}
    stopped = False
    for k in range(steps):
        stopped = stopped or (primitive.linear > 0 and blocked_ahead(obs["scan"], bearings))
        command = (0.0, 0.0) if stopped else (primitive.linear, primitive.angular)
        obs, _, _, _, info = sim.step(np.array(command, dtype=np.float32))
        if on_step(obs, info):
            return obs, info, k + 1, stopped
    return obs, info, steps, stopped
