from pathlib import Path

import pytest

SHARED = Path(__file__).resolve().parents[2] / "shared" / "data"
ROOM_WORLD = """
format: pimm-world/1
name: room
floor_z: 0.0
areas:
  room: [[0, 0], [6, 0], [6, 4], [0, 4]]
elements:
  - {name: floor, class: floor, box: {min: [-0.5, -0.5, -0.1], max: [6.5, 4.5, 0.0]}}
  - {name: ceiling, class: ceiling, box: {min: [-0.5, -0.5, 3.0], max: [6.5, 4.5, 3.1]}}
  - {name: south, class: wall, box: {min: [-0.2, -0.2, 0.0], max: [6.2, 0.0, 3.0]}}
  - {name: north, class: wall, wall: {path: [[-0.1, 4.1], [6.1, 4.1]], thickness: 0.2, z: [0.0, 3.0]}}
  - {name: west, class: wall, box: {min: [-0.2, 0.0, 0.0], max: [0.0, 4.0, 3.0]}}
  - {name: east, class: wall, box: {min: [6.0, 0.0, 0.0], max: [6.2, 4.0, 3.0]}}
  - {name: post, class: clutter, cylinder: {center: [4.5, 2.0], radius: 0.2, z: [0.0, 3.0]}}
"""


@pytest.fixture
def room_file(tmp_path: Path) -> Path:
    """A 6 m x 4 m room with a post, written as a world file in a fresh folder."""
    folder = tmp_path / "room"
    folder.mkdir()
    path = folder / "world.yaml"
    path.write_text(ROOM_WORLD)
    return path


def shared_file(*parts: str) -> Path:
    path = SHARED.joinpath(*parts)
    if not path.is_file():
        pytest.skip(f"reference data {path} is not present")
    return path


@pytest.fixture
def ros_domain(monkeypatch: pytest.MonkeyPatch) -> int:
    """A ROS 2 domain of this test's own on loopback only: ROS_DOMAIN_ID from the process id (tests running side
    by side do not hear each other) and CYCLONEDDS_URI bound to 127.0.0.1, multicast off, 127.0.0.1 the only
    peer, for every participant this test or its subprocesses open."""
    import os

    from pimm_env.ros2.domain import LOCALHOST_CONFIG

    domain = 100 + os.getpid() % 100
    monkeypatch.setenv("ROS_DOMAIN_ID", str(domain))
    monkeypatch.setenv("CYCLONEDDS_URI", LOCALHOST_CONFIG)
    return domain
