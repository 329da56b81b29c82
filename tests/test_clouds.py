"""Point cloud files: every format and PCD encoding reads back the same points; bad files name what is wrong."""

import numpy as np
import pytest

from pimm_env.clouds.pcd import lzf_decompress
from pimm_env.clouds.read import read_cloud
from pimm_env.errors import CloudFileError


@pytest.fixture
def points():
    rng = np.random.default_rng(3)
    return rng.uniform(-5, 5, (500, 3)).astype(np.float32)


def _open3d_cloud(points):
    import open3d as o3d

    return o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points.astype(np.float64)))


@pytest.mark.parametrize("encoding", ["ascii", "binary", "binary_compressed"])
def test_pcd_of_each_encoding_reads_back_its_points(tmp_path, points, encoding):
    import open3d as o3d

    path = tmp_path / f"{encoding}.pcd"
    o3d.io.write_point_cloud(
        str(path), _open3d_cloud(points), write_ascii=encoding == "ascii", compressed=encoding == "binary_compressed"
    )
    assert f"DATA {encoding}".encode() in path.read_bytes()[:400]
    cloud = read_cloud(path)
    assert cloud.points.shape == (500, 3) and cloud.left_out == 0 and cloud.organized is None
    assert np.allclose(cloud.points, points, atol=1e-5)


def test_ply_las_laz_npy_and_kitti_read_back_their_points(tmp_path, points):
    import laspy
    import open3d as o3d

    o3d.io.write_point_cloud(str(tmp_path / "scan.ply"), _open3d_cloud(points))
    np.save(tmp_path / "scan.npy", points)
    np.column_stack([points, np.zeros(len(points), np.float32)]).astype("<f4").tofile(tmp_path / "scan.bin")
    for suffix in (".las", ".laz"):
        header = laspy.LasHeader(point_format=3, version="1.2")
        header.scales = np.array([0.0001] * 3)
        las = laspy.LasData(header)
        las.x, las.y, las.z = points[:, 0], points[:, 1], points[:, 2]
        las.write(str(tmp_path / f"scan{suffix}"))
    for name in ("scan.ply", "scan.npy", "scan.bin", "scan.las", "scan.laz"):
        cloud = read_cloud(tmp_path / name)
        assert cloud.points.shape == (500, 3), name
        assert np.allclose(cloud.points, points, atol=2e-4), name


def test_an_organized_cloud_keeps_its_rows_and_leaves_out_rays_without_a_return(tmp_path, points):
    grid = points[:480].reshape(16, 30, 3).copy()
    grid[3, 4] = np.nan  # a ray that saw nothing
    grid[5, 6] = 0.0  # a driver that marks it with zeros
    np.save(tmp_path / "organized.npy", grid)
    cloud = read_cloud(tmp_path / "organized.npy")
    assert cloud.organized == (16, 30) and cloud.left_out == 2 and len(cloud.points) == 478
    assert cloud.ring is not None and cloud.ring[0] == 0 and cloud.ring[-1] == 15
    assert cloud.total == 480 and 3 * 30 + 4 not in cloud.rows


def _ascii_pcd(path, rows, fields="x y z", extra=""):
    count = len(rows)
    names = fields.split()
    header = (
        f"VERSION 0.7\nFIELDS {fields}\nSIZE {' '.join('4' for _ in names)}\nTYPE {' '.join('F' for _ in names)}\n"
        f"COUNT {' '.join('1' for _ in names)}\nWIDTH {count}\nHEIGHT 1\n{extra}POINTS {count}\nDATA ascii\n"
    )
    path.write_text(header + "".join(" ".join(str(v) for v in row) + "\n" for row in rows))
    return path


def test_the_viewpoint_moves_the_points_into_the_sensor_frame(tmp_path):
    path = _ascii_pcd(tmp_path / "moved.pcd", [[2.0, 0.0, 1.0]], extra="VIEWPOINT 1 0 1 0.7071068 0 0 0.7071068\n")
    # the sensor sits at (1, 0, 1), turned 90 deg left: a point 1 m ahead of it in the cloud's x is to its right
    assert np.allclose(read_cloud(path).points, [[0.0, -1.0, 0.0]], atol=1e-6)


def test_bad_files_are_named_with_what_is_wrong(tmp_path, points):
    import open3d as o3d

    full = tmp_path / "full.pcd"
    o3d.io.write_point_cloud(str(full), _open3d_cloud(points), compressed=True)
    cut = tmp_path / "cut.pcd"
    cut.write_bytes(full.read_bytes()[: len(full.read_bytes()) // 2])
    with pytest.raises(CloudFileError, match=r"cut.pcd: .*compressed data, its size word says .* \(cut short\)"):
        read_cloud(cut)
    binary = tmp_path / "binary.pcd"
    o3d.io.write_point_cloud(str(binary), _open3d_cloud(points))
    short = tmp_path / "short.pcd"
    short.write_bytes(binary.read_bytes()[:-100])
    with pytest.raises(CloudFileError, match=r"short.pcd: \d+ bytes of binary data, 500 points of 12 bytes need 6000"):
        read_cloud(short)
    with pytest.raises(CloudFileError, match=r"noz.pcd: no z field \(fields: x, y, intensity\)"):
        read_cloud(_ascii_pcd(tmp_path / "noz.pcd", [[1, 2, 3]], fields="x y intensity"))
    with pytest.raises(CloudFileError, match=r"twice.pcd: FIELDS names x more than once \(x x z\)"):
        read_cloud(_ascii_pcd(tmp_path / "twice.pcd", [[1, 2, 3]], fields="x x z"))
    padded = read_cloud(_ascii_pcd(tmp_path / "padded.pcd", [[1, 9, 2, 9, 3]], fields="x _ y _ z"))
    assert padded.points.tolist() == [[1, 2, 3]]  # PCL's padding fields, named "_", may repeat
    nan_rows = _ascii_pcd(tmp_path / "nan.pcd", [[1, 2, 3], [float("nan"), 0, 0], [4, 5, 6]])
    with pytest.raises(CloudFileError, match=r"nan.pcd: 1 of 3 points have NaN .* \(first: row 1\).*--drop-invalid"):
        read_cloud(nan_rows)
    dropped = read_cloud(nan_rows, drop_invalid=True)
    assert len(dropped.points) == 2 and dropped.left_out == 1 and dropped.rows.tolist() == [0, 2]
    with pytest.raises(CloudFileError, match=r"empty.pcd: the cloud has no points"):
        read_cloud(_ascii_pcd(tmp_path / "empty.pcd", []))
    with pytest.raises(CloudFileError, match=r"rows.pcd: 6 bytes of ASCII data cannot hold POINTS 2 x 3 values"):
        path = _ascii_pcd(tmp_path / "rows.pcd", [[1, 2, 3], [4, 5, 6]])
        path.write_text(path.read_text().rsplit("\n", 2)[0] + "\n")
        read_cloud(path)
    (tmp_path / "odd.bin").write_bytes(b"\0" * 20)
    with pytest.raises(CloudFileError, match=r"odd.bin: 20 bytes is not a whole number of KITTI points"):
        read_cloud(tmp_path / "odd.bin")
    np.save(tmp_path / "flat.npy", np.zeros(5))
    with pytest.raises(CloudFileError, match=r"flat.npy: array of shape \(5,\)"):
        read_cloud(tmp_path / "flat.npy")
    (tmp_path / "scan.xyz").write_text("1 2 3\n")
    with pytest.raises(CloudFileError, match=r"scan.xyz: unknown point cloud suffix '.xyz'"):
        read_cloud(tmp_path / "scan.xyz")
    with pytest.raises(FileNotFoundError, match="missing.pcd"):
        read_cloud(tmp_path / "missing.pcd")
    (tmp_path / "text.pcd").write_text("hello\nworld\n")
    with pytest.raises(CloudFileError, match=r"text.pcd: the PCD header ends before its DATA line"):
        read_cloud(tmp_path / "text.pcd")
    (tmp_path / "junk.laz").write_bytes(b"not a laz file at all")
    with pytest.raises(CloudFileError, match=r"junk.laz: not a readable LAS/LAZ file"):
        read_cloud(tmp_path / "junk.laz")


def test_lzf_back_references_that_overlap_repeat_what_was_just_written():
    # a literal "ab", then a back-reference of 6 bytes starting 2 back: "abababab"
    packed = bytes([1]) + b"ab" + bytes([(4 << 5) | 0, 1])
    assert lzf_decompress(packed, 8) == b"abababab"
    with pytest.raises(CloudFileError, match="damaged"):
        lzf_decompress(packed[:-1], 8)


def test_a_header_that_promises_more_than_the_file_holds_is_refused_before_allocating(tmp_path):
    """A 300-byte file must not ask for gigabytes: the sizes are checked against the file first."""
    import struct

    head = (
        "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH {n}\nHEIGHT 1\nPOINTS {n}\nDATA {kind}\n"
    )
    points = 300_000_000  # 3.6 GB of rows
    bomb = tmp_path / "bomb.pcd"
    bomb.write_bytes(
        head.format(n=points, kind="binary_compressed").encode() + struct.pack("<II", 4, points * 12) + b"\0" * 4
    )
    with pytest.raises(CloudFileError, match=r"bomb.pcd: 4 compressed bytes cannot unpack to the 3600000000"):
        read_cloud(bomb)
    text = tmp_path / "text.pcd"
    text.write_bytes(head.format(n=points, kind="ascii").encode() + b"1 2 3\n")
    with pytest.raises(CloudFileError, match=r"text.pcd: 6 bytes of ASCII data cannot hold POINTS 300000000 x 3"):
        read_cloud(text)


def test_odd_arrays_and_georeferenced_files(tmp_path):
    """A (3, N) array is not 3 points; a survey's UTM coordinates keep their centimetres (moved by an offset)."""
    np.save(tmp_path / "rows.npy", np.zeros((3, 50)) + 1.0)
    with pytest.raises(CloudFileError, match=r"rows.npy: array of shape \(3, 50\) looks like x, y, z as rows"):
        read_cloud(tmp_path / "rows.npy")
    rng = np.random.default_rng(0)
    utm = np.array([651_234.0, 5_123_456.0, 310.0]) + rng.uniform(-20, 20, (500, 3))
    np.save(tmp_path / "utm.npy", utm)
    cloud = read_cloud(tmp_path / "utm.npy")
    assert np.allclose(cloud.points.astype(np.float64) + cloud.offset, utm, atol=1e-5)  # float32 alone: 0.5 m


def test_a_truncated_binary_ply_is_refused_not_read_with_rows_of_garbage(tmp_path, points):
    import open3d as o3d

    full = tmp_path / "full.ply"
    o3d.io.write_point_cloud(str(full), _open3d_cloud(points), write_ascii=False)
    cut = tmp_path / "cut.ply"
    cut.write_bytes(full.read_bytes()[:-40])
    with pytest.raises(CloudFileError, match=r"cut.ply: \d+ bytes, its header's elements need \d+ \(the file is cut"):
        read_cloud(cut)
    assert len(read_cloud(full).points) == len(points)


def test_a_kitti_file_without_reflectance_is_read_as_its_points(tmp_path):
    rng = np.random.default_rng(1)
    xyz = rng.uniform(-20, 20, (400, 3)).astype("<f4")  # 4 800 bytes: a whole number of 16-byte rows too
    (tmp_path / "xyz.bin").write_bytes(xyz.tobytes())
    np.testing.assert_array_equal(read_cloud(tmp_path / "xyz.bin").points, xyz)
    xyzr = np.column_stack([xyz, rng.uniform(0, 1, 400)]).astype("<f4")
    (tmp_path / "xyzr.bin").write_bytes(xyzr.tobytes())
    np.testing.assert_array_equal(read_cloud(tmp_path / "xyzr.bin").points, xyz)


def test_a_short_ascii_ply_one_without_xyz_and_an_empty_kitti_file_are_refused(tmp_path, points):
    import open3d as o3d

    full = tmp_path / "full.ply"
    o3d.io.write_point_cloud(str(full), _open3d_cloud(points), write_ascii=True)
    assert len(read_cloud(full).points) == len(points)
    cut = tmp_path / "cut.ply"
    cut.write_text("\n".join(full.read_text().splitlines()[:-3]) + "\n")
    with pytest.raises(CloudFileError, match=rf"cut.ply: {len(points) - 3} data rows, .* declare {len(points)}"):
        read_cloud(cut)
    header = "ply\nformat binary_little_endian 1.0\nelement vertex 2\nproperty float a\nproperty float b\nend_header\n"
    (tmp_path / "ab.ply").write_bytes(header.encode() + np.zeros(4, "<f4").tobytes())
    with pytest.raises(CloudFileError, match="ab.ply: no vertices with x, y, z"):
        read_cloud(tmp_path / "ab.ply")
    (tmp_path / "empty.bin").write_bytes(b"")
    with pytest.raises(CloudFileError, match=r"empty.bin: an empty file \(0 bytes\)"):
        read_cloud(tmp_path / "empty.bin")
