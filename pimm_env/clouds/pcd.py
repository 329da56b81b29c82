"""PCL's ``.pcd`` files: the header, and the data in its three encodings (``ascii``, ``binary``,
``binary_compressed``).

The format (PCD v0.7, as PCL writes it): a text header of ``FIELDS``, ``SIZE``, ``TYPE`` (``F`` float, ``I``
signed, ``U`` unsigned), ``COUNT``, ``WIDTH``, ``HEIGHT`` (1 for an unorganized cloud), ``VIEWPOINT`` (the
sensor's pose in the cloud's frame: translation, then a quaternion w x y z), ``POINTS`` and ``DATA``. Binary data
is row after row; compressed data is two little-endian ``uint32`` sizes (compressed, raw) and an LZF block
whose raw bytes hold each field's values for all points, one field after the other.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pimm_env.errors import CloudFileError

_TYPES = {("F", 4): "<f4", ("F", 8): "<f8", ("I", 1): "i1", ("I", 2): "<i2", ("I", 4): "<i4", ("I", 8): "<i8",
          ("U", 1): "u1", ("U", 2): "<u2", ("U", 4): "<u4", ("U", 8): "<u8"}  # fmt: skip
_ENCODINGS = ("ascii", "binary", "binary_compressed")


@dataclass(frozen=True)
class PcdHeader:
    fields: tuple[str, ...]
    dtypes: tuple[str, ...]
    counts: tuple[int, ...]
    width: int
    height: int
    viewpoint: tuple[float, ...]
    points: int
    encoding: str

    def row_dtype(self) -> np.dtype:
        """One point's bytes as a structured dtype (a field of count > 1 is a sub-array)."""
        return np.dtype(
            [
                (self._name(i), d, (c,) if c > 1 else ())
                for i, (d, c) in enumerate(zip(self.dtypes, self.counts, strict=True))
            ]
        )

    def _name(self, i: int) -> str:
        # PCL writes padding fields as "_"; they may repeat, so each gets its own name
        return self.fields[i] if self.fields[i] != "_" else f"_{i}"


def read_pcd(path: Path) -> tuple[PcdHeader, np.ndarray]:
    """The header and a structured array of ``header.points`` rows; a damaged file is named with what is wrong."""
    raw = Path(path).read_bytes()
    header, data = _split_header(path, raw)
    if header.encoding == "ascii":
        rows = _ascii_rows(path, header, data)
    elif header.encoding == "binary":
        rows = _binary_rows(path, header, data)
    else:
        rows = _compressed_rows(path, header, data)
    return header, rows


def _split_header(path: Path, raw: bytes) -> tuple[PcdHeader, bytes]:
    entries: dict[str, list[str]] = {}
    offset = 0
    while True:
        end = raw.find(b"\n", offset)
        if end < 0:
            raise CloudFileError(f"{path}: the PCD header ends before its DATA line (not a PCD file, or cut short)")
        try:
            line = raw[offset:end].decode("ascii").strip()
        except UnicodeDecodeError:
            raise CloudFileError(f"{path}: not a PCD file (binary bytes before a DATA line)") from None
        offset = end + 1
        if not line or line.startswith("#"):
            continue
        key, *values = line.split()
        entries[key.upper()] = values
        if key.upper() == "DATA":
            break
    return _header(path, entries), raw[offset:]


def _header(path: Path, entries: dict[str, list[str]]) -> PcdHeader:
    missing = [k for k in ("FIELDS", "SIZE", "TYPE", "WIDTH", "HEIGHT", "DATA") if k not in entries]
    if missing:
        raise CloudFileError(f"{path}: the PCD header lacks {', '.join(missing)}")
    fields = tuple(entries["FIELDS"])
    counts = entries.get("COUNT", ["1"] * len(fields))
    if not (len(entries["SIZE"]) == len(entries["TYPE"]) == len(counts) == len(fields)):
        raise CloudFileError(
            f"{path}: FIELDS, SIZE, TYPE and COUNT list {len(fields)}, {len(entries['SIZE'])}, "
            f"{len(entries['TYPE'])} and {len(counts)} entries; they must agree"
        )
    dtypes = []
    for name, size, kind in zip(fields, entries["SIZE"], entries["TYPE"], strict=True):
        key = (kind.upper(), _integer(path, "SIZE", size))
        if key not in _TYPES:
            raise CloudFileError(f"{path}: field {name!r} has TYPE {kind} SIZE {size}, not a PCD number type")
        dtypes.append(_TYPES[key])
    width, height = _integer(path, "WIDTH", entries["WIDTH"][0]), _integer(path, "HEIGHT", entries["HEIGHT"][0])
    points = _integer(path, "POINTS", entries.get("POINTS", [str(width * height)])[0])
    if points != width * height:
        raise CloudFileError(f"{path}: POINTS {points} is not WIDTH x HEIGHT = {width} x {height}")
    encoding = entries["DATA"][0].lower() if entries["DATA"] else ""
    if encoding not in _ENCODINGS:
        raise CloudFileError(f"{path}: DATA {encoding!r}; a PCD file's data is one of {', '.join(_ENCODINGS)}")
    try:
        viewpoint = tuple(float(v) for v in entries.get("VIEWPOINT", ["0", "0", "0", "1", "0", "0", "0"]))
    except ValueError:
        raise CloudFileError(f"{path}: VIEWPOINT {entries['VIEWPOINT']} is not 7 numbers") from None
    if len(viewpoint) != 7:
        raise CloudFileError(f"{path}: VIEWPOINT has {len(viewpoint)} numbers; it is tx ty tz qw qx qy qz")
    twice = sorted({name for name in fields if name != "_" and fields.count(name) > 1})
    if twice:
        raise CloudFileError(f"{path}: FIELDS names {', '.join(twice)} more than once ({' '.join(fields)})")
    counts_int = tuple(_integer(path, "COUNT", c) for c in counts)
    return PcdHeader(fields, tuple(dtypes), counts_int, width, height, viewpoint, points, encoding)


def _integer(path: Path, key: str, text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise CloudFileError(f"{path}: {key} {text!r} is not a whole number") from None
    if value < 0 or (value == 0 and key in ("SIZE", "COUNT")):
        raise CloudFileError(f"{path}: {key} {value} is out of range")
    return value


def _ascii_rows(path: Path, header: PcdHeader, data: bytes) -> np.ndarray:
    columns = sum(header.counts)
    if header.points * columns * 2 > len(data):  # every value takes a digit and a separator: checked before
        raise CloudFileError(  # anything is allocated
            f"{path}: {len(data)} bytes of ASCII data cannot hold POINTS {header.points} x {columns} values "
            "(cut short, or a damaged header)"
        )
    text = data.decode("ascii", errors="replace")
    if text.strip() and not text.endswith(("\n", "\r")):  # a row cut mid-number would be read as another value
        raise CloudFileError(f"{path}: the last data row does not end its line (the file is cut short)")
    lines = [line for line in text.splitlines() if line.strip()]
    if len(lines) != header.points:
        raise CloudFileError(f"{path}: {len(lines)} data rows, the header says POINTS {header.points} (cut short?)")
    values = np.empty((len(lines), columns))
    for i, line in enumerate(lines):
        parts = line.split()
        if len(parts) != columns:
            raise CloudFileError(f"{path}: data row {i} has {len(parts)} values, the header's fields give {columns}")
        try:
            values[i] = [float(p) for p in parts]
        except ValueError:
            raise CloudFileError(f"{path}: data row {i} holds a value that is not a number: {line[:80]!r}") from None
    rows = np.empty(len(lines), dtype=header.row_dtype())
    column = 0
    for i, count in enumerate(header.counts):
        name = rows.dtype.names[i]  # type: ignore[index]
        block = values[:, column : column + count]
        rows[name] = block[:, 0] if count == 1 else block
        column += count
    return rows


def _binary_rows(path: Path, header: PcdHeader, data: bytes) -> np.ndarray:
    dtype = header.row_dtype()
    need = header.points * dtype.itemsize
    if len(data) < need:
        raise CloudFileError(
            f"{path}: {len(data)} bytes of binary data, {header.points} points of {dtype.itemsize} bytes need {need} "
            "(the file is cut short)"
        )
    return np.frombuffer(data[:need], dtype=dtype).copy()


def _compressed_rows(path: Path, header: PcdHeader, data: bytes) -> np.ndarray:
    dtype = header.row_dtype()
    if len(data) < 8:
        raise CloudFileError(f"{path}: binary_compressed data shorter than its two size words (cut short)")
    packed, size = (int(v) for v in np.frombuffer(data[:8], "<u4"))
    if size != header.points * dtype.itemsize:
        raise CloudFileError(
            f"{path}: compressed data unpacks to {size} bytes, {header.points} points of {dtype.itemsize} bytes are "
            f"{header.points * dtype.itemsize}"
        )
    if len(data) - 8 < packed:
        raise CloudFileError(
            f"{path}: {len(data) - 8} bytes of compressed data, its size word says {packed} (cut short)"
        )
    if size > LZF_MAX_RATIO * packed + LZF_MAX_RATIO:  # before anything is allocated
        raise CloudFileError(
            f"{path}: {packed} compressed bytes cannot unpack to the {size} its size word says (LZF unpacks at most "
            f"{LZF_MAX_RATIO} times); the data is damaged"
        )
    raw = lzf_decompress(data[8 : 8 + packed], size, path)
    rows = np.empty(header.points, dtype=dtype)
    offset = 0
    for name in dtype.names or ():
        field = dtype.fields[name][0]  # type: ignore[index]
        nbytes = header.points * field.itemsize
        rows[name] = np.frombuffer(raw[offset : offset + nbytes], dtype=field.base).reshape(rows[name].shape)
        offset += nbytes
    return rows


#: The most LZF can expand: a 3-byte back-reference writes at most 264 bytes (liblzf's format).
LZF_MAX_RATIO = 88


def lzf_decompress(packed: bytes, size: int, path: Path | str = "data") -> bytes:
    """LZF (liblzf's format, which PCL compresses with): literal runs and back-references into the output."""
    out = bytearray(size)
    i = o = 0
    n = len(packed)
    try:
        while i < n:
            ctrl = packed[i]
            i += 1
            if ctrl < 32:  # a run of ctrl + 1 literal bytes
                length = ctrl + 1
                if i + length > n or o + length > size:
                    raise IndexError
                out[o : o + length] = packed[i : i + length]
                i += length
                o += length
                continue
            length = ctrl >> 5
            if length == 7:
                length += packed[i]
                i += 1
            length += 2
            ref = o - ((ctrl & 0x1F) << 8) - packed[i] - 1
            i += 1
            if ref < 0 or o + length > size:
                raise IndexError
            if o - ref >= length:  # no overlap: one slice
                out[o : o + length] = out[ref : ref + length]
            else:  # the copy repeats what it has just written
                for k in range(length):
                    out[o + k] = out[ref + k]
            o += length
    except IndexError:
        raise CloudFileError(f"{path}: the compressed data is damaged (LZF block breaks off at byte {i})") from None
    if o != size:
        raise CloudFileError(f"{path}: the compressed data unpacks to {o} bytes, expected {size} (damaged)")
    return bytes(out)


def write_pcd(path: Path, points: np.ndarray) -> Path:
    """``points`` (N, 3) as a binary PCD (x y z float32, unorganized), written under a temporary name and moved
    into place when complete."""
    xyz = np.ascontiguousarray(np.asarray(points, dtype="<f4").reshape(-1, 3))
    header = (
        "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\n"
        f"COUNT 1 1 1\nWIDTH {len(xyz)}\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {len(xyz)}\nDATA binary\n"
    )
    path = Path(path)
    partial = path.with_name(f".{path.name}.partial")
    partial.write_bytes(header.encode("ascii") + xyz.tobytes())
    partial.replace(path)
    return path
