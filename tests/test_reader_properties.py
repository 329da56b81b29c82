"""The readers on damaged input, generated: every file a user might hand over is either read or refused with the
project's own error naming it, never a traceback, a hang or a silent wrong result (docs/localizers.md, odd
input). Each property runs a few dozen generated cases."""

import gzip
import io
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from pimm_env.bags.carmen import read_carmen
from pimm_env.clouds.read import read_cloud
from pimm_env.errors import BagError, CloudFileError

#: the same generated cases on every run (a CI that fails must fail again where it is run next)
FEW = settings(
    max_examples=40, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
RNG = np.random.default_rng(5)
POINTS = RNG.uniform(-5, 5, (200, 3))


def _valid(kind: str) -> bytes:
    """A good file of ``kind`` (its bytes), written by Open3D or NumPy."""
    import open3d as o3d

    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / f"cloud.{kind.split('-')[0]}"
        if kind == "npy":
            np.save(path, POINTS)
        else:
            cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(POINTS))
            if kind == "pcd-compressed":
                o3d.io.write_point_cloud(str(path), cloud, compressed=True)
            else:
                o3d.io.write_point_cloud(str(path), cloud, write_ascii=kind == "pcd-ascii")
        return path.read_bytes()


VALID = {kind: _valid(kind) for kind in ("pcd-ascii", "pcd-binary", "pcd-compressed", "ply", "npy")}


def _read(data: bytes, suffix: str):
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / f"damaged{suffix}"
        path.write_bytes(data)
        try:
            cloud = read_cloud(path)
        except CloudFileError as error:
            assert str(path) in str(error)  # the file is named
            return None
        assert np.isfinite(cloud.points).all() and len(cloud.points) > 0
        return cloud


@FEW
@given(kind=st.sampled_from(sorted(VALID)), cut=st.floats(0.0, 1.0))
def test_a_cloud_file_cut_anywhere_is_read_whole_or_refused(kind, cut):
    data = VALID[kind]
    cloud = _read(data[: int(len(data) * cut)], "." + kind.split("-")[0])
    if cloud is not None:  # whatever was read is a prefix of the true points, never garbage
        assert len(cloud.points) <= len(POINTS)
        np.testing.assert_allclose(cloud.points, POINTS[: len(cloud.points)].astype(np.float32), atol=1e-3)


@FEW
@given(kind=st.sampled_from(sorted(VALID)), at=st.integers(0, 400), byte=st.integers(0, 255))
def test_a_cloud_file_with_one_byte_changed_is_read_or_refused(kind, at, byte):
    """(Found by this test: one byte of an .npy's float64 made a value beyond float32's range, stored as inf.)"""
    data = bytearray(VALID[kind])
    data[min(at, len(data) - 1)] = byte
    _read(bytes(data), "." + kind.split("-")[0])


@FEW
@given(header=st.text(alphabet="0123456789 -.eEnaifTYPESIZEWDHCOUNTFIELDSxyz\n", max_size=200))
def test_a_pcd_header_of_any_text_is_read_or_refused(header):
    _read(("VERSION 0.7\n" + header + "\nDATA ascii\n1 2 3\n").encode(), ".pcd")


CARMEN_WORDS = st.sampled_from(["ODOM", "FLASER", "ROBOTLASER1", "0", "1", "2", "-1", "3.5", "nan", "inf", "x", "1e9"])


@FEW
@given(lines=st.lists(st.lists(CARMEN_WORDS, min_size=0, max_size=14), max_size=8), gz=st.booleans())
def test_a_carmen_log_of_any_lines_is_read_or_refused_naming_its_line(lines, gz):
    text = "\n".join(" ".join(words) for words in lines) + "\n"
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / ("log.gz" if gz else "log")
        if gz:
            buffer = io.BytesIO()
            with gzip.GzipFile(fileobj=buffer, mode="wb") as handle:
                handle.write(text.encode())
            path.write_bytes(buffer.getvalue())
        else:
            path.write_text(text)
        try:
            read = list(read_carmen(path))
        except BagError as error:
            assert str(path) in str(error)
            return
        assert all(line.kind in ("odom", "laser", "robotlaser") for line in read)


@pytest.mark.parametrize("shape", [(0, 3), (5,), (3, 40), (2, 2, 2), (10, 2), (4, 4, 1)])
def test_arrays_of_other_shapes_are_refused_naming_the_shape(shape):
    buffer = io.BytesIO()
    np.save(buffer, np.ones(shape))
    assert _read(buffer.getvalue(), ".npy") is None


def test_a_value_beyond_float32s_range_is_no_return():
    buffer = io.BytesIO()
    np.save(buffer, np.vstack([POINTS, [[1e300, 0.0, 0.0]]]))
    assert _read(buffer.getvalue(), ".npy") is None  # an unorganized cloud: refused, naming the file
