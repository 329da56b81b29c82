"""Read a bag (rosbag2 or ROS 1: whatever ``rosbags`` reads) back as the env's observations.

Messages are taken in the bag's order (receive time) and timed by their header stamps (or, with
``BagTopics.stamps`` "receive", by their receive times); messages received at the same time are taken events,
truth, scan, cloud, then odometry, so that the step an odometry message closes holds what arrived with it
(the reader's own order among them is not fixed: it followed the order of a set, which changes with Python's
hash seed). Each cloud is placed into the 3D LiDAR layout's grid
by its points' angles (``layout.organize``), so a driver's ring order or azimuth origin does not matter.
Every odometry message closes a step: it yields one observation holding that odometry and the latest scan
and cloud (with their stamps, so that a localizer tells a fresh scan from a repeated one, as with the live
env), the latest true pose if the bag has one, and whether a scan or cloud arrived since the previous step. A
``kidnap`` event marks the next step.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from pimm_env.bags.bag_file import open_bag
from pimm_env.bags.layout import organize
from pimm_env.bags.messages import (
    KIDNAP,
    TOPICS,
    BagError,
    cloud_points,
    planar_pose,
    scan_ranges,
    stamp_seconds,
)
from pimm_env.bags.tf_truth import TfTruth

STAMPS = ("header", "receive", "order")
#: Odometry messages whose times all agree from the start: a clock that does not advance (all zero, never set).
STALLED_STAMPS = 20


@dataclass(frozen=True)
class BagTopics:
    """Which topics hold what; a missing optional topic (points, truth, events) is simply not read."""

    odom: str = TOPICS["odom"]
    scan: str | None = TOPICS["scan"]
    points: str | None = TOPICS["points"]
    truth: str | None = TOPICS["truth"]
    events: str | None = TOPICS["events"]
    #: the time of each message: its header stamp ("header", when the sensor saw it) or when the bag received it
    #: ("receive": for a log whose stamps are wrong or from unsynchronized clocks), or its header stamps with the
    #: messages that share one spread evenly up to the next ("order": for stamps printed too coarsely to tell the
    #: messages apart, as a classic log written with 6 significant digits)
    stamps: str = "header"

    def __post_init__(self) -> None:
        if self.stamps not in STAMPS:
            raise BagError(f"stamps must be one of {', '.join(STAMPS)}, got {self.stamps!r}")


@dataclass
class Step:
    obs: dict[str, np.ndarray]
    true_pose: np.ndarray | None
    fresh_scan: bool
    fresh_cloud: bool
    kidnapped: bool = False  # the robot was kidnapped just before this step
    info: dict = field(default_factory=dict)


def bag_topics(path: Path) -> dict[str, str]:
    """Topic -> message type of every connection in the bag at ``path``."""
    with open_bag(path) as reader:
        return {c.topic: c.msgtype for c in reader.connections}


def read_steps(
    path: Path, topics: BagTopics, lidar2d, lidar3d, set_aside: dict[str, int] | None = None
) -> Iterator[Step]:
    """The bag's observations, one per odometry message, laid out as the env with these LiDARs gives them. A
    message with a value that is not finite (an odometry or true pose, a stamp) is set aside and counted in
    ``set_aside`` by kind (``non_finite_odometry``, ``non_finite_truth``), and the replay goes on; a scan or cloud
    whose stamp is not newer than the last one's (a localizer takes it for the one it has) is counted
    (``scan_stamp_not_newer``, ``cloud_stamp_not_newer``); odometry whose first ``STALLED_STAMPS`` times all agree
    is a ``BagError`` saying to replay by receive time."""
    path = Path(path)
    aside = set_aside if set_aside is not None else {}
    with open_bag(path) as reader:
        have = {c.topic: c for c in reader.connections}
        wanted = {t for t in (topics.odom, topics.scan, topics.points, topics.truth, topics.events) if t}
        if topics.odom not in have:
            raise BagError(f"{path}: no odometry topic {topics.odom!r}; the bag has {sorted(have)}")
        if not any(t in have for t in (topics.scan, topics.points) if t):
            raise BagError(f"{path}: neither {topics.scan!r} nor {topics.points!r}; the bag has {sorted(have)}")
        connections = [have[t] for t in sorted(wanted) if t in have]
        priority = {topics.events: 0, topics.truth: 1, topics.scan: 2, topics.points: 3, topics.odom: 4}
        n3 = lidar3d.layers * lidar3d.points_per_layer
        cloud, mask = np.zeros((n3, 3), np.float32), np.zeros(n3, np.int8)
        scan = np.full(lidar2d.beams, lidar2d.max_range, np.float32)
        cloud_time = scan_time = 0.0
        truth: np.ndarray | None = None
        tf_truth = TfTruth()
        fresh_scan = fresh_cloud = kidnapped = False
        counts: dict[str, int] = {}
        served = 0  # steps yielded
        first_stamps: list[float] = []  # the first odometry times, to tell a clock that never advances
        first_received: list[float] = []
        by_receipt = topics.stamps == "receive"
        ordered = _ordered_stamps(reader, connections, priority) if topics.stamps == "order" else {}

        def when(msg: Any, received: int, topic: str, index: int) -> float:
            """A message's time: its receive time, its stamp spread in order, or its header stamp."""
            if by_receipt:
                return received * 1e-9
            return float(ordered[topic][index]) if ordered else stamp_seconds(msg)

        for connection, received, raw in in_step_order(reader.messages(connections=connections), priority):
            topic = connection.topic
            index = counts[topic] = counts.get(topic, -1) + 1
            where = f"{path}: {topic} message {index}"
            msg: Any = reader.deserialize(raw, connection.msgtype)
            if topic == topics.events:
                kidnapped = kidnapped or msg.data == KIDNAP
            elif topic == topics.truth:
                if connection.msgtype.endswith("TFMessage"):  # /tf: the base in the map, when a message says it
                    pose = tf_truth.update(msg, where)
                else:
                    pose = planar_pose(msg, where)
                if pose is not None and not np.all(np.isfinite(pose)):
                    aside["non_finite_truth"] = aside.get("non_finite_truth", 0) + 1
                    pose = None
                truth = truth if pose is None else pose
            elif topic == topics.scan:
                stamp = when(msg, received, topic, index)
                if index and stamp <= scan_time:  # a localizer would take it for the scan it already has
                    aside["scan_stamp_not_newer"] = aside.get("scan_stamp_not_newer", 0) + 1
                scan = scan_ranges(msg, lidar2d.beams, lidar2d.max_range, where)
                scan_time, fresh_scan = stamp, True
            elif topic == topics.points:
                stamp = when(msg, received, topic, index)
                if index and stamp <= cloud_time:
                    aside["cloud_stamp_not_newer"] = aside.get("cloud_stamp_not_newer", 0) + 1
                cloud, mask = organize(cloud_points(msg, where), lidar3d, where)
                cloud_time, fresh_cloud = stamp, True
            elif topic == topics.odom:
                # a header stamp that goes back is served as it is: the localizers' guard sets that observation
                # aside and counts it (the bag's receive order is the order)
                t = when(msg, received, topic, index)
                odom = planar_pose(msg, where)
                if not (np.all(np.isfinite(odom)) and np.isfinite(t)):  # set aside: the next one closes the step
                    aside["non_finite_odometry"] = aside.get("non_finite_odometry", 0) + 1
                    continue
                if len(first_stamps) < STALLED_STAMPS:  # only the first ones tell a clock that never advances
                    first_stamps.append(t)
                    first_received.append(received * 1e-9)
                    if len(first_stamps) == STALLED_STAMPS and max(first_stamps) == min(first_stamps):
                        raise BagError(_stalled(path, topic, topics.stamps, t, np.ptp(first_received)))
                obs = {
                    "odom": odom.astype(np.float32),
                    "cloud": cloud.copy(),
                    "cloud_mask": mask.copy(),
                    "scan": scan.copy(),
                    "time": np.array([t]),
                    "cloud_time": np.array([cloud_time]),
                    "scan_time": np.array([scan_time]),
                }
                yield Step(obs, None if truth is None else truth.copy(), fresh_scan, fresh_cloud, kidnapped)
                fresh_scan = fresh_cloud = kidnapped = False
                served += 1
        if not served:
            said = ", ".join(f"{count} {kind}" for kind, count in aside.items()) or "none"
            raise BagError(f"{path}: {topics.odom}: no odometry message could be replayed (set aside: {said})")


def _stalled(path: Path, topic: str, stamps: str, t: float, received_span_s: float) -> str:
    """Why a replay whose first odometry times all agree cannot go on, and which ``--stamps`` would."""
    said = {"header": "header stamps", "receive": "receive times", "order": "stamps, spread in order,"}[stamps]
    if stamps == "header" and received_span_s > 1e-3:
        fix = "the recorder's clock was not set: replay with --stamps receive (the bag's receive times)"
    elif stamps != "order":
        fix = ("neither the stamps nor the receive times tell the messages apart: replay with --stamps order (the "
               "header stamps, those that repeat spread evenly up to the next)")  # fmt: skip
    else:
        fix = "the log holds one stamp only: no order of them gives it a time"
    return (
        f"{path}: {topic}: the first {STALLED_STAMPS} {said} are all {t}: time does not advance, so no localizer "
        f"could move; {fix}"
    )


def _ordered_stamps(reader: Any, connections: list, priority: dict) -> dict[str, np.ndarray]:
    """Every topic's header stamps in the order read, each run of equal ones spread evenly up to the next (the
    last run over the topic's mean step)."""
    stamps: dict[str, list[float]] = {}
    for connection, _, raw in in_step_order(reader.messages(connections=connections), priority):
        msg = reader.deserialize(raw, connection.msgtype)
        header = getattr(msg, "header", None)
        stamps.setdefault(connection.topic, []).append(stamp_seconds(msg) if header is not None else np.nan)
    return {topic: spread_equal(np.array(values)) for topic, values in stamps.items()}


def spread_equal(stamps: np.ndarray) -> np.ndarray:
    """``stamps`` with each run of equal values spread evenly from its value up to the next value (the last
    run at the mean step of the messages before it)."""
    out = np.array(stamps, dtype=float)
    n = len(out)
    last = int(np.flatnonzero(out != out[-1])[-1]) + 1 if n and np.any(out != out[-1]) else 0  # the last run's start
    mean_step = (out[last] - out[0]) / last if last else 0.0
    i = 0
    while i < n:
        j = i + 1
        while j < n and out[j] == out[i]:
            j += 1
        if j - i > 1:
            upto = stamps[j] if j < n else stamps[i] + (j - i) * mean_step
            out[i:j] = stamps[i] + (upto - stamps[i]) * np.arange(j - i) / (j - i)
        i = j
    return out


def in_step_order(messages: Iterable[tuple[Any, int, Any]], priority: dict[str | None, int]) -> Iterator[tuple]:
    """``messages`` (connection, receive time, data) with each run of equal receive times sorted by its topic's
    ``priority`` (the order within a topic kept)."""
    group: list[tuple[Any, int, Any]] = []
    for message in messages:
        if group and message[1] != group[0][1]:
            yield from sorted(group, key=lambda m: priority.get(m[0].topic, len(priority)))
            group = []
        group.append(message)
    yield from sorted(group, key=lambda m: priority.get(m[0].topic, len(priority)))
