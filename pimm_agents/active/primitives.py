"""The active-localization env's actions: three motion primitives, each about a second of driving.

Primitives rather than velocities: a policy choosing among "forward 0.5 m", "turn left 45 deg" and "turn right
45 deg" sees the effect of each choice in the next belief (a velocity held for one 32 ms control step changes
nothing a localizer can see), an episode is tens of decisions instead of thousands, and a guard can keep each
one safe. The forward primitive stops when the 2D scan shows anything within ``stop_range`` in a 60 deg cone
ahead (what a robot's own bumper-less safety layer does) or in the lane its body sweeps, and stands still for
the rest of its second, so a policy cannot drive into a wall by choice and every primitive takes its time (a
blocked forward that took none would let a policy that keeps choosing it stop the clock); a turn in place
cannot hit anything the robot is not already touching.

A turn squares the robot up with the walls it sees: it turns 45 deg and then by as much as brings its heading to a
multiple of 45 deg from the walls' direction in the 2D scan (``wall_axis``; at most 22.5 deg more or less, and not
at all when the scan shows no dominant direction), in the same second. With plain 45 deg turns every heading
stayed at the start's offset from the building's axes (a start 38 deg off one could face 83 deg, never 90 deg):
the robot drifted toward a corridor's wall, 0.6 m over 5 m, met doorways askew and stood at their jambs.
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
FORWARD, LEFT, RIGHT = 0, 1, 2  # their actions

TURN_SETTLE_S = 0.25  # a turn ends this long before its second does (two scans of a 10 Hz LiDAR)
STOP_RANGE = 0.5  # m from the LiDAR: the forward primitive stops when anything ahead is closer
STOP_CONE = np.radians(30.0)  # half-width of the cone ahead that the stop looks at
#: half-width of the lane the body sweeps (its 0.25 m radius, robot.py, and 5 cm): the stop also looks along it,
#: out of the cone, so that the body does not graze a doorway's edge it passes (a trained policy did, once)
SWEPT_HALF_WIDTH = 0.3


#: a scan's walls have a direction when at least this share of its surface (by length) runs within
#: ``AXIS_SPREAD`` of it or square to it (segments two returns long scatter by about 10 deg at 1 cm of range noise)
AXIS_AGREEMENT = 0.5  # a third would run within 15 deg of any direction if they ran every way
AXIS_SPREAD = np.radians(15.0)
#: returns this close (m), two apart in the scan, are taken as one surface
SEGMENT_GAP = 0.5


def wall_axis(scan: np.ndarray, bearings: np.ndarray, max_range: float = 10.0) -> float | None:
    """The direction (rad, robot frame, modulo 90 deg, in [-45, 45) deg) of the walls the 2D scan (ranges at
    ``bearings``) sees: the most common direction (modulo 90 deg, by length) of the segments between returns two
    apart within ``max_range`` (furniture and clutter spread over all directions, walls do not), refined by the
    segments within ``AXIS_SPREAD`` of it; None when too few run that way (``AXIS_AGREEMENT``)."""
    scan = np.asarray(scan, dtype=float)
    x, y = scan * np.cos(bearings), scan * np.sin(bearings)
    dx, dy = x[2:] - x[:-2], y[2:] - y[:-2]
    length = np.hypot(dx, dy)
    use = (length > 1e-3) & (length < SEGMENT_GAP) & (scan[:-2] < max_range) & (scan[2:] < max_range)
    if not use.any():
        return None
    quarter = np.pi / 2
    angle, w = np.arctan2(dy[use], dx[use]) % quarter, length[use]  # in [0, 90) deg
    bins = np.bincount((angle / quarter * 90).astype(int) % 90, weights=w, minlength=90)
    smooth = sum(np.roll(bins, k) for k in range(-3, 4))
    peak = (int(np.argmax(smooth)) + 0.5) * quarter / 90
    for _ in range(3):  # each segment's direction about the estimate, then the mean of those near it, three times
        off = (angle - peak + quarter / 2) % quarter - quarter / 2
        near = np.abs(off) <= AXIS_SPREAD
        if not near.any():
            return None
        peak += float(np.sum(w[near] * off[near]) / np.sum(w[near]))
    if w[near].sum() < AXIS_AGREEMENT * w.sum():
        return None
    return float((peak + quarter / 2) % quarter - quarter / 2)


def squared_turn(turn: float, scan: np.ndarray, bearings: np.ndarray) -> float:
    """The turn (rad) that a primitive turning ``turn`` makes: the turn plus what brings the heading to a multiple
    of 45 deg from the scan's walls (``wall_axis``); ``turn`` itself when the scan shows no wall direction."""
    axis = wall_axis(scan, bearings)
    if axis is None:
        return turn
    eighth = np.pi / 4
    offset = (axis + eighth / 2) % eighth - eighth / 2  # the walls' direction modulo 45 deg, in [-22.5, 22.5)
    return turn + offset


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
    dt = sim.unwrapped.config.robot.control_dt
    steps = max(1, round(primitive.duration / dt))
    angular, turning = primitive.angular, steps
    if angular != 0.0:  # squared up with the walls; it stands still for the last TURN_SETTLE_S of the second, so
        # that the next primitive starts from a scan taken at rest (one taken while turning is up to 4 deg askew)
        turning = max(1, steps - round(TURN_SETTLE_S / dt))
        turn = squared_turn(angular * primitive.duration, np.asarray(obs["scan"], dtype=float), bearings)
        angular = turn / (turning * dt)
    info: dict[str, Any] = {}
    stopped = False
    for k in range(steps):
        stopped = stopped or (primitive.linear > 0 and blocked_ahead(obs["scan"], bearings))
        command = (0.0, 0.0) if stopped or k >= turning else (primitive.linear, angular)
        obs, _, _, _, info = sim.step(np.array(command, dtype=np.float32))
        if on_step(obs, info):
            return obs, info, k + 1, stopped
    return obs, info, steps, stopped
