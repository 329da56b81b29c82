"""The node and the simulated robot as two processes on loopback, seen from a third participant as nav2 would
see them: PIMM localizes from a global start, notices a kidnap through ``/sim/kidnap`` within 2 s, and a known
start from ``/initialpose`` is taken. Every process and participant is ended by the test."""

import os
import subprocess
import sys
import time
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest

from pimm_env.bags.messages import planar_pose
from pimm_env.ros2 import domain as qos
from pimm_env.ros2.domain import Domain
from pimm_env.ros2.frames import header, quaternion
from pimm_env.ros2.messages import ros_types

ROOT = Path(__file__).resolve().parents[1]
pytestmark = pytest.mark.expensive
#: a free pose in the iiLab's hall A, far from area B where the drive runs
HALL_A = [-20.0, 5.5, 0.0]


def start(log: Path, *args: str) -> subprocess.Popen:
    """``evaluate.py ARGS`` in a process of its own, its output in ``log`` (a pipe left unread would stall it)."""
    with open(log, "w") as out:
        return subprocess.Popen(
            [sys.executable, str(ROOT / "evaluate.py"), *args],
            cwd=ROOT,
            env=dict(os.environ),
            stdout=out,
            stderr=subprocess.STDOUT,
        )


def stop(*processes: subprocess.Popen) -> None:
    for process in processes:
        if process.poll() is None:
            process.terminate()
    for process in processes:
        try:
            process.wait(timeout=10)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait(timeout=5)


class Watcher:
    """nav2's view: the pose, the node's status and the robot's truth, newest of each with its arrival."""

    def __init__(self, domain: Domain) -> None:
        self.subs = {
            "pose": domain.subscription("amcl_pose", "geometry_msgs/msg/PoseWithCovarianceStamped", qos.LATCHED),
            "status": domain.subscription("/diagnostics", "diagnostic_msgs/msg/DiagnosticArray"),
            "truth": domain.subscription("/ground_truth", "nav_msgs/msg/Odometry"),
        }
        self.newest: dict = {}
        self.statuses: list[tuple[float, str]] = []

    def poll(self) -> None:
        for key, sub in self.subs.items():
            for arrival, msg in sub.take():
                self.newest[key] = msg
                if key == "status":
                    self.statuses.append((arrival, msg.status[0].message))

    def error_m(self) -> float:
        if "pose" not in self.newest or "truth" not in self.newest:
            return np.inf
        estimate, truth = planar_pose(self.newest["pose"]), planar_pose(self.newest["truth"])
        return float(np.hypot(*(estimate[:2] - truth[:2])))

    def wait(self, condition, seconds: float, what: str, *processes) -> float:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.poll()
            if condition():
                return time.monotonic()
            for process in processes:
                if process.poll() is not None:
                    raise AssertionError(f"{what}: {process.args[2:4]} ended early, exit {process.returncode}")
            time.sleep(0.01)
        raise AssertionError(f"{what}: not within {seconds} s (statuses: {self.statuses[-3:]})")


@contextmanager
def node_and_robot(tmp_path: Path, node: list[str], robot: list[str]):
    """``evaluate.py node NODE...`` and ``sim-robot ROBOT...`` running, and a participant watching them as nav2
    would: yields (node process, robot process, domain, watcher); both processes are ended whatever happens."""
    processes = (start(tmp_path / "node.log", "node", *node), start(tmp_path / "robot.log", "sim-robot", *robot))
    try:
        with Domain() as domain:
            yield (*processes, domain, Watcher(domain))
    finally:
        stop(*processes)


def pose_stamped(pose: list[float]):
    t = ros_types().types
    return t["geometry_msgs/msg/PoseStamped"](
        header=header(0.0, "map"),
        pose=t["geometry_msgs/msg/Pose"](
            position=t["geometry_msgs/msg/Point"](x=pose[0], y=pose[1], z=0.0), orientation=quaternion(0, 0, pose[2])
        ),
    )


def test_pimm_through_the_node_localizes_and_notices_a_kidnap(ros_domain, tmp_path) -> None:
    pimm, drive = ["--localizer", "pimm", "--seconds", "120"], ["--scenario", "area_b", "--seed", "1"]
    with node_and_robot(tmp_path, pimm, drive) as (node, robot, domain, watcher):
        kidnap = domain.publisher("/sim/kidnap", "geometry_msgs/msg/PoseStamped")
        right = lambda: watcher.statuses and watcher.statuses[-1][1] == "localized" and watcher.error_m() < 1.0  # noqa: E731
        watcher.wait(right, 90, "PIMM right and localized", node, robot)
        watcher.wait(lambda: kidnap.matched() > 0, 10, "the robot hears /sim/kidnap")
        sent = time.monotonic()
        kidnap.publish(pose_stamped(HALL_A))
        noticed = watcher.wait(
            lambda: any(t > sent and s != "localized" for t, s in watcher.statuses), 10, "kidnap noticed", node
        )
        assert noticed - sent <= 2.0
        assert np.hypot(*(planar_pose(watcher.newest["truth"])[:2] - HALL_A[:2])) < 1.0  # it was carried


def test_a_known_start_from_initialpose(ros_domain, tmp_path) -> None:
    amcl, drive = ["--localizer", "amcl", "--seconds", "90"], ["--scenario", "area_a", "--seed", "2"]
    with node_and_robot(tmp_path, amcl, drive) as (node, _, domain, watcher):
        initial = domain.publisher("/initialpose", "geometry_msgs/msg/PoseWithCovarianceStamped")
        watcher.wait(lambda: "truth" in watcher.newest and "pose" in watcher.newest, 60, "node running", node)
        truth = planar_pose(watcher.newest["truth"])
        t = ros_types().types
        cov = np.zeros(36)
        cov[[0, 7, 35]] = [0.25, 0.25, 0.068]  # nav2's RViz "2D Pose Estimate" covariance
        pose = pose_stamped(list(truth)).pose
        msg = t["geometry_msgs/msg/PoseWithCovarianceStamped"](
            header=header(0.0, "map"), pose=t["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=cov)
        )
        watcher.wait(lambda: initial.matched() > 0, 10, "the node hears /initialpose")
        initial.publish(msg)
        sent = time.monotonic()
        watcher.wait(lambda: watcher.statuses and watcher.statuses[-1][0] > sent + 1.0, 10, "updates after it")
        assert watcher.error_m() < 0.5


def test_the_node_agrees_with_a_replay_of_the_same_drive(ros_domain, tmp_path) -> None:
    """The same drive (area_b, seed 0) recorded and replayed, and published by sim-robot to the node: once both
    are localized, the node's poses lie within 0.15 m of the replay's at the same sim time. They are not equal:
    the node starts where its localizer is ready (after the mount on /tf_static and PIMM's loading) rather than
    at the drive's first step, and when it falls behind it closes a step with the newest odometry, so its
    particles draw other random numbers; both follow the truth to a few centimetres."""
    import csv
    import json

    bag, results = tmp_path / "bag", tmp_path / "results"
    subprocess.run([sys.executable, str(ROOT / "evaluate.py"), "record", "--scenario", "area_b", "--seed", "0",
                    "--out", str(bag)], cwd=ROOT, check=True, capture_output=True, timeout=600)  # fmt: skip
    done = subprocess.run([sys.executable, str(ROOT / "evaluate.py"), "replay", str(bag), "--localizers", "pimm",
                           "--out", str(results), "--json"], cwd=ROOT, check=True, capture_output=True, text=True,
                          timeout=600)  # fmt: skip
    folder = Path(json.loads(done.stdout)["folder"])
    with next(folder.rglob("*.csv")).open() as handle:
        rows = [(float(r["timestamp_real"]), float(r["est_x"]), float(r["est_y"])) for r in csv.DictReader(handle)]
    replayed = np.array(rows)
    poses = []
    pimm, drive = ["--localizer", "pimm", "--seconds", "150"], ["--scenario", "area_b", "--seed", "0"]
    with node_and_robot(tmp_path, pimm, drive) as (_, robot, _, watcher):
        end = time.monotonic() + 150
        while robot.poll() is None and time.monotonic() < end:
            for _, msg in watcher.subs["pose"].take():
                stamp = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
                status = watcher.statuses[-1][1] if watcher.statuses else "lost"
                poses.append((stamp, *planar_pose(msg)[:2], status == "localized"))
            watcher.poll()
            time.sleep(0.01)
    published = np.array(poses)
    localized = published[published[:, 3] > 0]
    assert len(localized) > 100
    # the replay's row at each published stamp, from the time both are localized and settled
    index = np.clip(np.searchsorted(replayed[:, 0], localized[:, 0]), 0, len(replayed) - 1)
    settled = localized[:, 0] >= max(localized[0, 0], replayed[0, 0]) + 5.0
    gap = np.hypot(
        localized[settled, 1] - replayed[index[settled], 1], localized[settled, 2] - replayed[index[settled], 2]
    )
    assert np.median(gap) < 0.05 and np.percentile(gap, 95) < 0.15
