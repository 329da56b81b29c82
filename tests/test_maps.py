from dataclasses import replace

import numpy as np
import pytest

from pimm_env.mapping.corner_map import derive_corner_map, load_corner_map
from pimm_env.mapping.derived_maps import (
    StaleMapsError,
    build_derived_maps,
    corner_matches,
    ensure_derived_maps,
    fidelity_iou,
    load_derived_maps,
)
from pimm_env.mapping.map_server import load_map_server
from pimm_env.mapping.occupancy import occupancy_from_world, save_map_server, tolerant_iou
from pimm_env.world.files import load_world

from .conftest import shared_file


def test_map_server_round_trip(tmp_path, room_file):
    occupancy = occupancy_from_world(load_world(room_file), 0.05, 0.3)
    save_map_server(occupancy, tmp_path / "m.yaml")
    text = (tmp_path / "m.yaml").read_text()
    for field in ("image: m.pgm", "resolution: 0.05", "origin:", "negate: 0", "occupied_thresh", "free_thresh"):
        assert field in text
    loaded = load_map_server(tmp_path / "m.yaml")
    assert np.array_equal(loaded.occupied, occupancy.occupied)
    assert np.array_equal(loaded.free, occupancy.free)
    assert loaded.grid.origin == pytest.approx(occupancy.grid.origin)


def test_room_occupancy_has_walls_post_and_free_inside(room_file):
    occupancy = occupancy_from_world(load_world(room_file), 0.05, 0.3)
    rows, cols, _ = occupancy.grid.cells_of(np.array([[3.0, 2.0], [4.5, 2.0], [-0.1, 2.0], [8.0, 2.0]]))
    assert occupancy.free[rows[0], cols[0]] and occupancy.occupied[rows[1], cols[1]]
    assert occupancy.occupied[rows[2], cols[2]]


def test_tolerant_iou():
    a = np.zeros((10, 10), bool)
    b = np.zeros((10, 10), bool)
    a[5, :] = True
    b[6, :] = True
    assert tolerant_iou(a, b, 0) == 0.0
    assert tolerant_iou(a, b, 1) == 1.0
    assert tolerant_iou(a, a, 0) == 1.0


def test_room_corners_are_exact(room_file):
    corners = derive_corner_map(load_world(room_file))
    assert len(corners) == 4, "a post is clutter and makes no corner"
    expected = {(0.0, 0.0): 45.0, (6.0, 0.0): 135.0, (6.0, 4.0): -135.0, (0.0, 4.0): -45.0}
    for (x, y), theta in expected.items():
        d = np.hypot(corners.xy[:, 0] - x, corners.xy[:, 1] - y)
        i = int(np.argmin(d))
        assert d[i] <= 0.05 + 1e-9  # one cell of the 0.05 m grid
        assert np.degrees(corners.theta[i]) == pytest.approx(theta)
        assert corners.z[i] == pytest.approx(3.0)


def test_doorway_wall_ends_make_no_corner(tmp_path, room_file):
    text = room_file.read_text().replace(
        "  - {name: south, class: wall, box: {min: [-0.2, -0.2, 0.0], max: [6.2, 0.0, 3.0]}}",
        "  - {name: south_a, class: wall, box: {min: [-0.2, -0.2, 0.0], max: [2.5, 0.0, 3.0]}}\n"
        "  - {name: south_b, class: wall, box: {min: [3.5, -0.2, 0.0], max: [6.2, 0.0, 3.0]}}",
    )
    room_file.write_text(text)
    corners = derive_corner_map(load_world(room_file))
    assert len(corners) == 4
    assert not np.any((corners.xy[:, 0] > 2.0) & (corners.xy[:, 0] < 4.0) & (corners.xy[:, 1] < 1.0))


def test_a_corner_is_kept_where_the_scan_saw_a_face_past_the_furniture_standing_in_it(room_file):
    """A scan saw the south face from 0.6 m east of the room's south-west corner on (a cabinet hides the first
    stretch), and nothing else: that corner is kept, the south-east one (its face seen from 4 m off) and the two
    of unseen faces are not; a face first seen 1.2 m off keeps no corner."""
    world = load_world(room_file)
    along = np.arange(0.6, 2.0, 0.05)
    face = np.column_stack([along, np.zeros_like(along)])
    kept = derive_corner_map(replace(world, seen_walls=face))
    assert len(kept) == 1 and np.allclose(kept.xy, [[0.0, 0.0]], atol=0.05 + 1e-9)
    assert len(derive_corner_map(replace(world, seen_walls=face[12:]))) == 0


def test_no_ceiling_no_corner(room_file):
    room_file.write_text("\n".join(l for l in room_file.read_text().splitlines() if "ceiling" not in l))
    assert len(derive_corner_map(load_world(room_file))) == 0


def test_derived_maps_are_read_only_and_rebuilt_by_the_ensure_step(room_file):
    with pytest.raises(StaleMapsError, match="missing or older.*python -m pimm_env.mapping"):
        load_derived_maps(load_world(room_file))
    assert not (room_file.parent / "occupancy.pgm").exists(), "reading must never write"
    build_derived_maps(load_world(room_file))
    assert (room_file.parent / "occupancy.pgm").is_file() and (room_file.parent / "corners.yaml").is_file()
    again = load_derived_maps(load_world(room_file))
    assert len(again.corners) == 4
    room_file.write_text(room_file.read_text().replace("max: [6.2, 4.0, 3.0]", "max: [6.2, 4.0, 2.0]"))
    with pytest.raises(StaleMapsError):
        load_derived_maps(load_world(room_file))
    changed = ensure_derived_maps(load_world(room_file))
    assert len(changed.corners) == 2, "the east wall no longer reaches the ceiling"
    assert len(load_derived_maps(load_world(room_file)).corners) == 2


def test_iilab_occupancy_matches_the_thesis_map():
    reference = load_map_server(shared_file("iilab", "iilab.yaml"))
    ours = load_derived_maps(load_world("iilab")).occupancy
    assert ours.grid.resolution == 0.05
    assert fidelity_iou(ours, reference, tolerance=0.1) >= 0.8


def test_every_thesis_corner_has_a_derived_corner():
    reference = load_corner_map(shared_file("iilab", "corners_thesis.yaml"))
    assert len(reference) == 10
    ours = load_derived_maps(load_world("iilab")).corners
    matches = corner_matches(ours, reference, max_dist=0.3, max_angle_deg=20.0)
    missing = [tuple(reference.xy[i]) for i, m in enumerate(matches) if m is None]
    assert not missing, f"thesis corners without a derived corner: {missing}"


def test_bad_map_server_and_corner_files_name_the_file_and_the_field(tmp_path):
    (tmp_path / "map.pgm").write_bytes(b"P5\n4 3\n255\n" + bytes([0, 254, 254, 0] * 3))
    good = "image: map.pgm\nresolution: 0.05\norigin: [0, 0, 0]\noccupied_thresh: 0.65\nfree_thresh: 0.196\n"
    (tmp_path / "map.yaml").write_text(good)
    assert load_map_server(tmp_path / "map.yaml").grid.shape == (3, 4)
    (tmp_path / "map.yaml").write_text(good.replace("0.05", "5e-2"))  # YAML 1.1 text; a number to ROS
    assert load_map_server(tmp_path / "map.yaml").grid.shape == (3, 4)
    for bad, message in (
        (
            good.replace("0.05", "-0.05"),
            r"resolution: expected metres per pixel \(a positive number up to 10\), got -0.05",
        ),
        (good.replace("0.05", "1e9"), r"resolution: expected metres per pixel .*, got 1000000000.0"),
        (good.replace("[0, 0, 0]", "[0, .nan, 0]"), "origin: expected a finite number"),
        (good.replace("0.65", "1.5"), "free_thresh 0.196 and occupied_thresh 1.5"),
        ("image: [", r"not valid YAML: expected the node content, .* \(line 1, column 9\)$"),
    ):
        (tmp_path / "map.yaml").write_text(bad)
        with pytest.raises(ValueError, match=f"map.yaml: {message}" if "YAML" not in message else message):
            load_map_server(tmp_path / "map.yaml")
    (tmp_path / "map.yaml").write_text(good)
    (tmp_path / "map.pgm").write_bytes(b"P5\n4 3\n255\n" + bytes([254] * 5))
    with pytest.raises(ValueError, match=r"map.pgm: truncated: 5 bytes of pixels, the header says 4 x 3 = 12"):
        load_map_server(tmp_path / "map.yaml")
    corners = tmp_path / "corners.yaml"
    for text, message in (
        ("corners:\n  - {x: 1, y: 2, theta: 90}\n  - {x: 1, y: 2}\n", r"corners\[1\]: missing field 'theta'"),
        ("corners:\n  - {x: 1, y: a, theta: 90}\n", r"corners\[0\].y: expected a finite number, got 'a'"),
        ("corners:\n  - {x: .nan, y: 1, theta: 90}\n", r"corners\[0\].x: expected a finite number"),
        ("corners: [\n", r"not valid YAML: .* \(line 2, column 1\)$"),
    ):
        corners.write_text(text)
        with pytest.raises(ValueError, match=message):
            load_corner_map(corners)
    corners.write_text("corners:\n  - {x: 1, y: 2, theta: 90}\n")  # z may be left out
    assert load_corner_map(corners).z.tolist() == [0.0]


def test_map_images_of_other_depths_read_as_map_server_reads_them_and_a_cut_header_is_refused(tmp_path):
    from PIL import Image

    from pimm_env.mapping.map_server import read_image
    from pimm_env.mapping.occupancy import read_pgm

    (tmp_path / "cut.pgm").write_bytes(b"P5\n4")
    with pytest.raises(ValueError, match=r"cut.pgm: expected a binary PGM \(P5\) header"):
        read_pgm(tmp_path / "cut.pgm")
    (tmp_path / "low.pgm").write_bytes(b"P5 2 1 100\n" + bytes([100, 0]))  # maxval 100: 100 is white
    assert read_pgm(tmp_path / "low.pgm").tolist() == [[255, 0]]
    (tmp_path / "deep.pgm").write_bytes(b"P5 2 1 65535\n" + np.array([65535, 254], ">u2").tobytes())
    assert read_pgm(tmp_path / "deep.pgm").tolist() == [[255, 1]]
    Image.fromarray(np.array([[65535, 254]], np.uint16)).save(tmp_path / "deep.png")
    assert read_image(tmp_path / "deep.png").tolist() == [[255, 1]]  # 254 of 65 535 is near black
