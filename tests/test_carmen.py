import gzip
from pathlib import Path

import numpy as np
import pytest
from rosbags.highlevel import AnyReader

from pimm_env.bags.carmen import convert_carmen, read_carmen, scan_layout_of
from pimm_env.bags.messages import planar_pose, typestore
from pimm_env.errors import BagError

SNIPPET = """# message formats defined: PARAM SYNC ODOM FLASER RLASER
PARAM robot_front_laser_max 80.99 nohost 0
ODOM 0 0 0 0 0 0 10.0 pippo 10.0
ODOM 0.1 0 0 0 0 0 10.1 pippo 10.1
FLASER 4 1.0 2.0 81.9 3.0 5.0 6.0 0.0 0.1 0 0 10.15 pippo 10.15
ODOM 5.0 6.0 0.0 0 0 0 0 pippo 0
NEFF 30
ODOM 5.1 6.0 0.0 0 0 0 10.2 pippo 10.2
ODOM 5.2 6.0 0.0 0 0 0 10.2 pippo 10.2
"""


def test_a_carmen_log_converts_to_a_bag_that_rosbags_reads_back(tmp_path):
    log = tmp_path / "snippet.log.gz"
    with gzip.open(log, "wt") as handle:
        handle.write(SNIPPET)
    counts = convert_carmen(log, tmp_path / "bag")
    assert counts == {"odom": 4, "scan": 1, "truth": 1, "resets": 1, "non_finite": 0, "kind": "corrected"}
    got: dict[str, list] = {}
    with AnyReader([tmp_path / "bag"], default_typestore=typestore()) as reader:
        for connection, received, raw in reader.messages():
            got.setdefault(connection.topic, []).append((received, reader.deserialize(raw, connection.msgtype)))
    odom = np.array([planar_pose(m) for _, m in got["/odom"]])
    # the reset line (0 stamp, the corrected pose) is left out, and so is the step into it: the wheels' chain
    assert np.allclose(odom[:, 0], [0.0, 0.1, 0.1 + 0.1, 0.1 + 0.2]) and np.allclose(odom[:, 1:], 0.0)
    (_, scan), (_, truth) = got["/scan"][0], got["/ground_truth"][0]
    assert np.allclose(scan.ranges, [1.0, 2.0, np.inf, 3.0]) and np.isclose(scan.angle_min, -np.pi / 2)
    assert np.isclose(scan.angle_increment, np.radians(45.0))  # 4 beams over 180 deg
    assert np.allclose(planar_pose(truth), [5.0, 6.0, 0.0])
    received = [r for topic in got.values() for r, _ in topic]
    assert len(set(received)) == len(received)  # a repeated stamp still gets its own receive time


def test_layouts_and_bad_lines(tmp_path):
    assert scan_layout_of(181, 80.0).angle_max_deg == 90.0  # both ends
    assert scan_layout_of(360, 80.0).angle_max_deg == pytest.approx(89.5)  # 0.5 deg, without the last
    bad = tmp_path / "bad.log"
    bad.write_text("ODOM 0 0 0 0 0 0 1.0 pippo 1.0\nFLASER 3 1.0 2.0 0 0 0\n")
    with pytest.raises(BagError, match=r"bad.log:2: not a CARMEN FLASER line"):
        list(read_carmen(bad))
    with pytest.raises(FileNotFoundError, match="nope.log: no such CARMEN log"):
        list(read_carmen(Path(tmp_path / "nope.log")))
    (tmp_path / "notes.log").write_text("# a header, no messages\n")
    with pytest.raises(BagError, match=r"notes.log: no ODOM and FLASER .* lines to convert \(found: none\)"):
        convert_carmen(tmp_path / "notes.log", tmp_path / "notes")
    assert not (tmp_path / "notes").exists()


ROBOT_LASER = """ODOM 0 0 0 0 0 0 20.0 h 20.0
ROBOTLASER1 0 -1.5707963 3.1415927 1.5707963 50.0 0.01 0 3 1.0 50.0 2.0 2.1 3.0 0.5 2.0 3.0 0.5 0 0 0 0 20.1 h 20.1
ODOM 0.2 0 0 0 0 0 20.2 h 20.2
ROBOTLASER1 0 -1.5707963 3.1415927 1.5707963 50.0 0.01 0 3 4.0 5.0 6.0 3 7 8 9 1.0 3.0 3.6415927 1.2 3.0 0.5 \
0 0 0 0 20.3 h 20.3
"""


def test_robot_laser_lines_give_their_own_angles_in_the_robots_frame(tmp_path):
    log = tmp_path / "robotlaser.log"
    log.write_text(ROBOT_LASER)
    counts = convert_carmen(log, tmp_path / "bag")
    assert counts["scan"] == 2 and counts["truth"] == 2
    got: dict[str, list] = {}
    with AnyReader([tmp_path / "bag"], default_typestore=typestore()) as reader:
        for connection, _, raw in reader.messages():
            got.setdefault(connection.topic, []).append(reader.deserialize(raw, connection.msgtype))
    front, rear = got["/scan"]
    # 3 beams over 180 deg; the first laser faces forward, the second is turned half a turn on the robot
    assert np.isclose(front.angle_min, -np.pi / 2, atol=1e-6) and np.isclose(front.angle_increment, np.pi / 2)
    assert np.isclose(rear.angle_min, np.pi / 2, atol=1e-6)
    assert np.allclose(front.ranges, [1.0, np.inf, 2.0]) and np.allclose(rear.ranges, [4.0, 5.0, 6.0])
    # the truth is the robot's pose (the second line had 3 remissions before its poses)
    assert np.allclose([planar_pose(m) for m in got["/ground_truth"]], [[2.0, 3.0, 0.5], [1.2, 3.0, 0.5]])


RAW = """ODOM 0 0 0 0 0 0 10.0 pippo 10.0
FLASER 4 1.0 2.0 3.0 4.0 0.05 0 0 0 0 0 10.05 pippo 10.05
ODOM 0.1 0 0 0 0 0 10.1 pippo 10.1
FLASER 4 1.0 2.0 3.0 4.0 0.15 0 0 0.1 0 0 10.15 pippo 10.15
ODOM 0.2 0 0 0 0 0 10.2 pippo 10.2
ODOM nan 0 0 0 0 0 10.25 pippo 10.25
ODOM 0.3 0 0 0 0 0 10.3 pippo 10.3
"""


def test_a_raw_log_keeps_every_odometry_line_and_sets_a_nan_aside(tmp_path):
    log = tmp_path / "raw.log"
    log.write_text(RAW)
    counts = convert_carmen(log, tmp_path / "bag")
    assert counts == {"odom": 4, "scan": 2, "truth": 2, "resets": 0, "non_finite": 1, "kind": "raw"}
    with AnyReader([tmp_path / "bag"], default_typestore=typestore()) as reader:
        odom = [
            planar_pose(reader.deserialize(raw, c.msgtype)) for c, _, raw in reader.messages() if c.topic == "/odom"
        ]
    assert np.allclose(np.array(odom)[:, 0], [0.0, 0.1, 0.2, 0.3])  # every motion, none NaN


def test_a_failed_conversion_leaves_nothing_and_a_bag_name_is_refused(tmp_path):
    bad = tmp_path / "bad.log"
    bad.write_text("ODOM 0 0 0 0 0 0 1.0 pippo 1.0\nFLASER 0 0 0 0 0 0 0 1.0 h 1.0\n")
    with pytest.raises(BagError, match=r"bad.log:2: not a CARMEN FLASER line \(0 readings\)"):
        convert_carmen(bad, tmp_path / "out")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.log"]
    good = tmp_path / "good.log"
    good.write_text(RAW)
    with pytest.raises(BagError, match=r"intel.bag: a name ending in .bag is read as a ROS 1 bag.*--out .*intel"):
        convert_carmen(good, tmp_path / "intel.bag")
    fake = tmp_path / "fake.log.gz"
    fake.write_text(RAW)  # not gzip
    with pytest.raises(BagError, match="fake.log.gz: not a readable CARMEN log"):
        convert_carmen(fake, tmp_path / "out")
    assert not (tmp_path / "out").exists() and not (tmp_path / "intel.bag").exists()
