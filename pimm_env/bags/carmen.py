"""CARMEN text logs (the format of the classic 2D SLAM benchmarks' laser logs) written as a rosbag2.

Lines read: ``ODOM x y theta tv rv accel ipc_timestamp hostname logger_timestamp``, ``FLASER n r1 ... rn x y
theta odom_x odom_y odom_theta ipc_timestamp hostname logger_timestamp`` and ``ROBOTLASER1 laser_type
start_angle field_of_view angular_resolution maximum_range accuracy remission_mode n r1 ... rn [m e1 ... em]
laser_x laser_y laser_theta robot_x robot_y robot_theta ...`` (the remissions, where the logger wrote them); the
rest (PARAM, NEFF, RLASER, ...) is skipped. A log with FLASER lines takes its scans from them, one without from
its ROBOTLASER1 lines. What is written:

- ``/odom``: the wheel odometry as a chain of the relative motions between ODOM lines. In the benchmarks'
  "corrected" logs the ODOM line after each FLASER resets the odometry to the corrected pose (its stamps are 0
  and its pose is the FLASER's): that line is not written and the step into it is left out of the chain. A raw
  log has no such lines, and every ODOM line is a motion; the conversion says which kind it found;
- a line with a value that is not finite (NaN, inf) is set aside and counted, never written;
- ``/scan``: each FLASER's ranges, ``n`` beams over 180 deg from -90 deg (an odd ``n`` with both ends included,
  as 181 beams at 1 deg; an even one without the last, as 360 at 0.5 deg); readings at or beyond ``max_range``
  (the SICK's 81.9 m "no return") become +inf;
- ``/ground_truth``: the FLASER's own pose (in a corrected log the SLAM-corrected pose of the laser, the
  benchmarks' approximate truth);
- a ROBOTLASER1 line gives its own angles: its scan is written in the robot's frame (the beams turned by the
  laser's yaw on the robot, laser_theta - robot_theta, so a rear laser reads backwards) and its truth is the
  robot pose; the laser's offset from the robot's centre (some centimetres) is not modelled, as for FLASER.

Messages keep the log's stamps in their headers (some repeat or step back); the bag's receive times follow the
log's line order, one nanosecond apart where the stamps do not advance.
"""

from __future__ import annotations

import gzip
from collections.abc import Iterator
from dataclasses import dataclass
from itertools import pairwise
from pathlib import Path

import numpy as np

from pimm_env.bags.messages import TOPICS, BagError, laser_scan, odometry, typestore
from pimm_env.errors import MissingFileError
from pimm_env.geometry import compose, relative_motion
from pimm_env.sim.lidar import Lidar2DConfig


@dataclass(frozen=True)
class CarmenLine:
    kind: str  # "odom", "laser" (FLASER) or "robotlaser" (ROBOTLASER1)
    stamp: float
    pose: np.ndarray  # ODOM: the odometry; FLASER: the laser's (corrected) pose; ROBOTLASER1: the robot's
    ranges: np.ndarray | None = None
    #: ROBOTLASER1 only: the first beam's bearing in the robot's frame, the step between beams (rad) and the range
    angles: tuple[float, float, float] | None = None


def _robot_laser(words: list[str]) -> CarmenLine:
    """One ROBOTLASER1 line (split), with or without remissions."""
    start, _, step, max_range = (float(w) for w in words[2:6])
    n = int(words[8])
    if n < 1:
        raise ValueError(f"{n} readings")
    ranges = np.array(words[9 : 9 + n], dtype=float)
    rest = words[9 + n :]
    if rest and rest[0].lstrip("-").isdigit():  # a count: the remissions come first
        rest = rest[1 + int(rest[0]) :]
    poses = np.array(rest[:6], dtype=float)
    if len(ranges) != n or len(poses) != 6:
        raise ValueError(f"{n} ranges and the laser and robot poses expected")
    laser, robot = poses[:3], poses[3:]
    first = start + laser[2] - robot[2]  # the first beam in the robot's frame, in [-pi, pi)
    first = float((first + np.pi) % (2 * np.pi) - np.pi)
    return CarmenLine("robotlaser", float(words[-3]), robot, ranges, (first, step, max_range))


def read_carmen(path: Path) -> Iterator[CarmenLine]:
    """The ODOM, FLASER and ROBOTLASER1 lines of a CARMEN log (plain or .gz), in order; a malformed one is a
    ``BagError`` naming the file and line."""
    path = Path(path)
    if not path.is_file():
        raise MissingFileError(f"{path}: no such CARMEN log")
    opener = gzip.open if path.suffix == ".gz" else open
    try:
        yield from _lines(path, opener)
    except (OSError, EOFError, UnicodeDecodeError) as error:  # a .gz that is not gzip, a truncated one, binary
        raise BagError(f"{path}: not a readable CARMEN log ({error})") from None


def _lines(path: Path, opener) -> Iterator[CarmenLine]:
    with opener(path, "rt") as handle:
        for number, line in enumerate(handle, start=1):
            words = line.split()
            if not words or words[0] not in ("ODOM", "FLASER", "ROBOTLASER1"):
                continue
            try:
                if words[0] == "ODOM":
                    yield CarmenLine("odom", float(words[7]), np.array(words[1:4], dtype=float))
                elif words[0] == "ROBOTLASER1":
                    yield _robot_laser(words)
                else:
                    n = int(words[1])
                    if n < 1:
                        raise ValueError(f"{n} readings")
                    ranges = np.array(words[2 : 2 + n], dtype=float)
                    pose = np.array(words[2 + n : 5 + n], dtype=float)
                    if len(ranges) != n or len(pose) != 3:
                        raise ValueError(f"{n} ranges and a pose expected")
                    yield CarmenLine("laser", float(words[8 + n]), pose, ranges)
            except (IndexError, ValueError) as error:
                raise BagError(f"{path}:{number}: not a CARMEN {words[0]} line ({error})") from None


def scan_layout_of(beams: int, max_range: float) -> Lidar2DConfig:
    """The 2D LiDAR of ``beams`` FLASER readings over 180 deg (see the module's text)."""
    step = 180.0 / (beams - 1 if beams % 2 else beams)
    return Lidar2DConfig(
        beams=beams, angle_min_deg=-90.0, angle_max_deg=-90.0 + step * (beams - 1), max_range=max_range
    )


def robot_laser_layout(beams: int, angles: tuple[float, float, float]) -> Lidar2DConfig:
    """The 2D LiDAR of a ROBOTLASER1 line: ``beams`` from ``angles`` (first bearing, step, both rad; range)."""
    start, step, max_range = angles
    first = float(np.degrees(start))
    return Lidar2DConfig(
        beams=beams,
        angle_min_deg=first,
        angle_max_deg=first + float(np.degrees(step)) * (beams - 1),
        max_range=max_range,
    )


def finite(line: CarmenLine) -> bool:
    """Its stamp and pose finite, and no range NaN (a range at or beyond the maximum is "no return", kept)."""
    nan_range = line.ranges is not None and bool(np.isnan(line.ranges).any())
    return bool(np.all(np.isfinite([line.stamp, *line.pose]))) and not nan_range


def is_reset(line: CarmenLine, laser: CarmenLine | None) -> bool:
    """An ODOM line that resets the odometry to the corrected pose of the laser line just before it (a
    corrected log's): its stamp 0 or its pose the laser's."""
    if laser is None or line.kind != "odom":
        return False
    return line.stamp == 0.0 or bool(np.allclose(line.pose, laser.pose, atol=1e-6))


def convert_carmen(log: Path, out: Path, max_range: float = 80.0) -> dict[str, int | str]:
    """Write ``log`` as the rosbag2 folder ``out`` (which must not exist; written under a temporary name and
    moved into place when complete, so a failure leaves nothing); returns how many messages of each topic were
    written, how many odometry resets were left out, how many lines were set aside (a value not finite) and
    which kind of log it was (``corrected`` when it has reset lines, else ``raw``)."""
    import shutil

    out = Path(out)
    if out.exists():
        raise BagError(f"{out} already exists: give a new folder")
    if out.suffix == ".bag":
        raise BagError(f"{out}: a name ending in .bag is read as a ROS 1 bag; convert writes a rosbag2 folder: "
                       f"give --out {out.with_suffix('')}")  # fmt: skip
    lines = list(read_carmen(log))  # the whole log read (and checked) before anything is written
    if not any(line.kind in ("laser", "robotlaser") for line in lines) or not any(
        line.kind == "odom" for line in lines
    ):
        kinds = sorted({line.kind for line in lines})
        raise BagError(
            f"{log}: no ODOM and FLASER (or ROBOTLASER1) lines to convert (found: {', '.join(kinds) or 'none'});"
            " is it a CARMEN log?"
        )
    partial = out.with_name(f".{out.name}.partial")  # the bag is written inside, under its own name
    shutil.rmtree(partial, ignore_errors=True)
    try:
        partial.mkdir(parents=True)
        counts = _write_bag(lines, partial / out.name, max_range)
        (partial / out.name).rename(out)
    finally:
        shutil.rmtree(partial, ignore_errors=True)
    return counts


def _write_bag(lines: list[CarmenLine], out: Path, max_range: float) -> dict[str, int | str]:
    from rosbags.rosbag2 import Writer

    from pimm_env.sim.lidar import beam_bearings_2d

    store = typestore()
    counts: dict[str, int | str] = {"odom": 0, "scan": 0, "truth": 0, "resets": 0, "non_finite": 0}
    received = -1
    chain: np.ndarray | None = None  # the odometry written, and the raw ODOM pose it stands for
    last_raw: np.ndarray | None = None
    laser: CarmenLine | None = None  # the laser line just before, while no ODOM line has followed it
    set_aside = [line for line in lines if not finite(line)]
    lines = [line for line in lines if finite(line)]
    counts["non_finite"] = len(set_aside)
    # the scans come from the FLASER lines where there are any, else from the ROBOTLASER1 lines
    scans_from = "laser" if any(line.kind == "laser" for line in lines) else "robotlaser"
    resets = sum(is_reset(b, a if a.kind == scans_from else None) for a, b in pairwise(lines))
    counts["kind"] = "corrected" if resets else "raw"
    with Writer(out, version=9) as writer:
        topics = {
            name: writer.add_connection(TOPICS[name], kind, typestore=store)
            for name, kind in (
                ("odom", "nav_msgs/msg/Odometry"),
                ("scan", "sensor_msgs/msg/LaserScan"),
                ("truth", "nav_msgs/msg/Odometry"),
            )
        }

        def write(name: str, stamp: float, msg: object, kind: str) -> None:
            nonlocal received
            received = max(round(stamp * 1e9), received + 1)
            writer.write(topics[name], received, store.serialize_cdr(msg, kind))
            counts[name] = int(counts[name]) + 1

        for line in lines:
            if line.kind in ("laser", "robotlaser"):
                if line.kind != scans_from:
                    continue
                assert line.ranges is not None
                if line.angles is None:
                    lidar = scan_layout_of(len(line.ranges), max_range)
                else:
                    lidar = robot_laser_layout(len(line.ranges), line.angles)
                ranges = np.where(line.ranges >= lidar.max_range, np.inf, line.ranges)
                msg = laser_scan(store, line.stamp, ranges, beam_bearings_2d(lidar), lidar)
                write("scan", line.stamp, msg, "sensor_msgs/msg/LaserScan")
                write("truth", line.stamp, odometry(store, line.stamp, line.pose, "map"), "nav_msgs/msg/Odometry")
                laser = line
                continue
            if chain is None or last_raw is None:
                chain = line.pose.copy()
            elif is_reset(line, laser):  # the corrected log's reset line: not a motion
                counts["resets"] = int(counts["resets"]) + 1
                last_raw, laser = line.pose, None
                continue
            else:
                chain = compose(chain, relative_motion(last_raw, line.pose))[0]
            last_raw, laser = line.pose, None
            write("odom", line.stamp, odometry(store, line.stamp, chain, "odom"), "nav_msgs/msg/Odometry")
    return counts
