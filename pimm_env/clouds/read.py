"""One 3D scan from a file, whatever wrote it: ``read_cloud(path) -> CloudFile``.

=================  ======================================================================================
suffix             read as
=================  ======================================================================================
``.pcd``           PCL's format, ``ascii``, ``binary`` or ``binary_compressed`` (``pcd.py``); ``VIEWPOINT``
                   applied, so the points are in the sensor's frame
``.ply``           the vertices' x, y, z (Open3D)
``.las``, ``.laz`` the points' scaled x, y, z (laspy, with lazrs for LAZ)
``.npy``           an (N, >= 3) array (x, y, z first) or an organized (rows, columns, >= 3) one
``.bin``           KITTI's Velodyne scans: float32 x, y, z, reflectance per point
=================  ======================================================================================

A point with a NaN or infinite coordinate, or at the origin, is no return. In an organized cloud (a PCD of
HEIGHT > 1, a 3-d ``.npy``) that is how a sensor marks a ray that saw nothing, and such points are left out and
counted; in an unorganized cloud it is damage, and an error names the first such row unless ``drop_invalid``
says to leave them out (counted the same way). A ``ring`` field (PCD, ``.npy`` of an organized cloud: its
row) is kept. Nothing else about the layout is assumed: the points may come from any LiDAR.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pimm_env.errors import CloudFileError, MissingFileError

SUFFIXES = (".pcd", ".ply", ".las", ".laz", ".npy", ".bin")


@dataclass(frozen=True)
class CloudFile:
    """A scan's returns in the sensor's frame, and what the file said about its layout."""

    points: np.ndarray  # (N, 3) float32, finite, none at the origin
    source: str
    organized: tuple[int, int] | None  # (rows, columns) of an organized file
    ring: np.ndarray | None  # (N,) the ring (row) of each point, where the file has one
    rows: np.ndarray  # (N,) each return's row in the file
    total: int  # points in the file, returns or not
    left_out: int  # points that were no return (NaN, infinite or at the origin)
    #: (3,) what was taken off the file's coordinates to keep them exact in float32 (georeferenced files)
    offset: np.ndarray = field(default_factory=lambda: np.zeros(3))


#: Coordinates beyond this (m) lose centimetres in float32 (a georeferenced survey, UTM): the cloud is then moved
#: by its rounded median (``CloudFile.offset``) before it is stored, and says so.
FLOAT32_EXACT_M = 1.0e4


def read_cloud(path: Path | str, drop_invalid: bool = False) -> CloudFile:
    """The returns of the scan in ``path``; an unusable file is a ``CloudFileError`` naming it and what is wrong."""
    path = Path(path)
    if not path.is_file():
        raise MissingFileError(f"{path}: no such point cloud file")
    suffix = path.suffix.lower()
    if suffix not in SUFFIXES:
        raise CloudFileError(f"{path}: unknown point cloud suffix {suffix!r}; give one of {', '.join(SUFFIXES)}")
    reader = {".pcd": _pcd, ".ply": _ply, ".las": _las, ".laz": _las, ".npy": _npy, ".bin": _kitti}[suffix]
    xyz, ring, organized = reader(path)
    return _returns(path, np.asarray(xyz, dtype=np.float64), ring, organized, drop_invalid)


def _returns(
    path: Path, xyz: np.ndarray, ring: np.ndarray | None, organized: tuple[int, int] | None, drop_invalid: bool
) -> CloudFile:
    if len(xyz) == 0:
        raise CloudFileError(f"{path}: the cloud has no points")
    with np.errstate(invalid="ignore"):  # beyond float32's range is infinite in the cloud kept: no return
        finite = (np.abs(xyz) < np.finfo(np.float32).max).all(axis=1)
    good = finite & np.any(xyz != 0, axis=1)
    if organized is None and not finite.all() and not drop_invalid:
        first = int(np.flatnonzero(~finite)[0])
        raise CloudFileError(
            f"{path}: {int((~finite).sum())} of {len(xyz)} points have NaN or infinite coordinates (first: row "
            f"{first}); an unorganized cloud has no rays without returns: repair the file, or pass --drop-invalid "
            "to leave them out (a coordinate beyond float32's range counts as infinite)"
        )
    if not good.any():
        raise CloudFileError(f"{path}: none of its {len(xyz)} points is a return (all NaN, infinite or at the origin)")
    offset = np.zeros(3)
    if np.abs(xyz[good]).max() > FLOAT32_EXACT_M:  # georeferenced: float32 would round to decimetres
        offset = np.round(np.median(xyz[good], axis=0))
    return CloudFile(
        offset=offset,
        points=(xyz[good] - offset).astype(np.float32),
        source=str(path),
        organized=organized,
        ring=None if ring is None else np.asarray(ring)[good].astype(np.int32),
        rows=np.flatnonzero(good),
        total=len(xyz),
        left_out=int((~good).sum()),
    )


def _pcd(path: Path) -> tuple[np.ndarray, np.ndarray | None, tuple[int, int] | None]:
    from pimm_env.clouds.pcd import read_pcd

    header, rows = read_pcd(path)
    missing = [name for name in "xyz" if name not in header.fields]
    if missing:
        raise CloudFileError(f"{path}: no {'/'.join(missing)} field (fields: {', '.join(header.fields)})")
    xyz = np.column_stack([rows[name].astype(np.float64) for name in "xyz"])
    xyz = _from_viewpoint(xyz, header.viewpoint)
    organized = (header.height, header.width) if header.height > 1 else None
    ring = rows["ring"] if "ring" in header.fields else None
    if ring is None and organized is not None:
        ring = np.repeat(np.arange(header.height), header.width)
    return xyz, ring, organized


def _from_viewpoint(xyz: np.ndarray, viewpoint: tuple[float, ...]) -> np.ndarray:
    """Points given in a frame where the sensor sits at ``viewpoint`` (t, q w x y z), moved into the sensor's."""
    t = np.asarray(viewpoint[:3])
    w, x, y, z = viewpoint[3:]
    norm = np.sqrt(w * w + x * x + y * y + z * z) or 1.0
    w, x, y, z = w / norm, x / norm, y / norm, z / norm
    rotation = np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )
    if np.allclose(rotation, np.eye(3)) and not t.any():
        return xyz
    return (xyz - t) @ rotation


#: PLY's property types and their sizes in bytes
PLY_SIZES = {
    "char": 1, "uchar": 1, "int8": 1, "uint8": 1, "short": 2, "ushort": 2, "int16": 2, "uint16": 2,
    "int": 4, "uint": 4, "int32": 4, "uint32": 4, "float": 4, "float32": 4, "double": 8, "float64": 8,
}  # fmt: skip


def _check_ply_size(path: Path) -> None:
    """A PLY must hold every row its header declares: a truncated binary one (whose elements all have rows of one
    size) is refused, as is an ASCII one with fewer rows (read as they are, a binary one's missing rows would be
    whatever memory held, an ASCII one's points fewer than it says)."""
    with path.open("rb") as handle:
        head = handle.read(65536)
    end = head.find(b"end_header")
    if not head.startswith(b"ply") or end < 0:
        raise CloudFileError(f"{path}: not a PLY file (no 'ply' ... 'end_header' header)")
    lines = head[:end].decode("ascii", errors="replace").splitlines()
    start = head.index(b"\n", end) + 1
    elements = _ply_elements(lines)
    if not any(line.startswith("format binary") for line in lines):
        _check_ascii_ply_rows(path, sum(count for count, _ in elements), start)
        return
    if any(kind == "list" or kind not in PLY_SIZES for _, kinds in elements for kind in kinds):
        return  # rows of varying size (faces): the reader checks what it can
    need = start + sum(count * sum(PLY_SIZES[kind] for kind in kinds) for count, kinds in elements)
    size = path.stat().st_size
    if size < need:
        raise CloudFileError(f"{path}: {size} bytes, its header's elements need {need} (the file is cut short)")


def _ply_elements(header: list[str]) -> list[tuple[int, list[str]]]:
    """Each element a PLY header declares: its row count and its properties' types (``list`` for a list)."""
    elements: list[tuple[int, list[str]]] = [(0, [])]  # properties before any element count for none
    for words in (line.split() for line in header):
        if words[:1] == ["element"] and len(words) == 3 and words[2].isdigit():
            elements.append((int(words[2]), []))
        elif words[:1] == ["property"] and len(words) >= 3:
            elements[-1][1].append(words[1])
    return elements


def _check_ascii_ply_rows(path: Path, declared: int, start: int) -> None:
    """An ASCII PLY must hold the ``declared`` rows after its header (from byte ``start``)."""
    rows = 0
    with path.open("rb") as handle:
        handle.seek(start)
        for line in handle:
            rows += bool(line.strip())
    if rows < declared:
        raise CloudFileError(
            f"{path}: {rows} data rows, its header's elements declare {declared} (the file is cut short)"
        )


def _ply(path: Path) -> tuple[np.ndarray, None, None]:
    import open3d as o3d

    _check_ply_size(path)
    try:
        with _quiet_open3d():
            cloud = o3d.t.io.read_point_cloud(path, remove_nan_points=False, remove_infinite_points=False)
        found = "positions" in cloud.point
    except RuntimeError:  # Open3D asserts when the vertices carry no x, y, z
        found = False
    if not found:
        raise CloudFileError(f"{path}: no vertices with x, y, z could be read (not a PLY point set, or damaged)")
    return cloud.point.positions.numpy(), None, None


class _quiet_open3d:
    """Open3D's reader prints its warnings; the error we raise says what went wrong instead."""

    def __enter__(self) -> None:
        import open3d as o3d

        self.level = o3d.utility.get_verbosity_level()
        o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)

    def __exit__(self, *exc: object) -> None:
        import open3d as o3d

        o3d.utility.set_verbosity_level(self.level)


def _las(path: Path) -> tuple[np.ndarray, None, None]:
    import laspy

    try:
        las = laspy.read(str(path))
    except (laspy.errors.LaspyException, OSError, ValueError) as error:
        raise CloudFileError(f"{path}: not a readable LAS/LAZ file ({error})") from None
    return np.column_stack([np.asarray(las.x), np.asarray(las.y), np.asarray(las.z)]), None, None


def _npy(path: Path) -> tuple[np.ndarray, np.ndarray | None, tuple[int, int] | None]:
    import tokenize

    try:
        array = np.load(path, allow_pickle=False)
    except (ValueError, OSError, EOFError, SyntaxError, tokenize.TokenError) as error:  # a damaged header too
        raise CloudFileError(f"{path}: not a readable .npy array ({error})") from None
    if array.dtype.kind not in "fiu":
        raise CloudFileError(f"{path}: array of {array.dtype}; give numbers (x, y, z first)")
    if array.ndim == 3 and array.shape[2] >= 3:
        rows, columns = array.shape[:2]
        return array[..., :3].reshape(-1, 3), np.repeat(np.arange(rows), columns), (rows, columns)
    if array.ndim != 2 or array.shape[1] < 3:
        raise CloudFileError(
            f"{path}: array of shape {array.shape}; give (N, 3+) points or an organized (rows, columns, 3+) scan"
        )
    if array.shape[0] in (3, 4) and array.shape[1] > 4:  # (3, N): its rows would be read as 3 points
        raise CloudFileError(
            f"{path}: array of shape {array.shape} looks like x, y, z as rows; save it as (N, 3) points (array.T)"
        )
    return array[:, :3], None, None


def _kitti(path: Path) -> tuple[np.ndarray, None, None]:
    """KITTI's float32 x, y, z, reflectance; a file of x, y, z alone (12 bytes a point) is told apart by its
    "reflectance" column, which would then hold coordinates: negative, or beyond any reflectance scale."""
    size = path.stat().st_size
    if size == 0:
        raise CloudFileError(f"{path}: an empty file (0 bytes), no points")
    raw = np.fromfile(path, dtype="<f4")
    if size % 16 == 0:
        rows = raw.reshape(-1, 4)
        reflectance = rows[:, 3]
        plausible = np.isfinite(reflectance).all() and reflectance.min() >= 0 and reflectance.max() <= 255
        if plausible or size % 12:
            return rows[:, :3], None, None
    if size % 12 == 0:
        return raw.reshape(-1, 3), None, None
    raise CloudFileError(
        f"{path}: {size} bytes is not a whole number of KITTI points (float32 x, y, z, reflectance: 16 bytes each; "
        "or x, y, z: 12)"
    )
