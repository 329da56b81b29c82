"""Occupancy grids: cut from a world at one height, and read or written in ROS map_server format."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy import ndimage

from pimm_env.errors import WorldError
from pimm_env.world.files import World
from pimm_env.world.grid import GridSpec

OCCUPIED, UNKNOWN, FREE = 0, 205, 254


@dataclass(frozen=True)
class OccupancyGrid:
    """Occupied and free cells over ``grid``; cells that are neither are unknown."""

    grid: GridSpec
    occupied: np.ndarray
    free: np.ndarray

    def distance_to_occupied(self) -> np.ndarray:
        """Metres from every cell centre to the nearest occupied cell centre."""
        if not self.occupied.any():
            return np.full(self.grid.shape, np.inf)
        return ndimage.distance_transform_edt(~self.occupied) * self.grid.resolution

    def surfaces(self) -> np.ndarray:
        """Occupied cells that touch a free cell (8-neighbourhood): the faces a sensor in free space can see.
        A solid block (a thick outer wall, a filled wall of an imported plan) keeps only its skin."""
        return self.occupied & ndimage.binary_dilation(self.free, structure=np.ones((3, 3), dtype=bool))

    def distance_to_surfaces(self) -> np.ndarray:
        """Metres from every cell centre to the nearest visible face (``surfaces``); inside a solid block,
        the depth below its skin. Falls back to every occupied cell where no occupied cell touches free space."""
        surfaces = self.surfaces()
        if not surfaces.any():
            return self.distance_to_occupied()
        return ndimage.distance_transform_edt(~surfaces) * self.grid.resolution


#: Heights above the floor (m) at which the robot's body is checked for contact (its bumper, deck and top).
BODY_HEIGHTS = (0.05, 0.2, 0.35)


def body_obstacles(world: World, grid: GridSpec) -> np.ndarray:
    """Cells where a wall or clutter stands at any of ``BODY_HEIGHTS``: what the robot's body can touch, which a
    cut at the occupancy map's one height misses (a chair seat, a low table, a book on the floor)."""
    from pimm_env.world.semantics import SemanticClass

    body = grid.empty_mask()
    for height in BODY_HEIGHTS:
        body |= world.footprint(grid, world.floor_z + height, classes=[SemanticClass.WALL, SemanticClass.CLUTTER])
    return body


def occupancy_from_world(world: World, resolution: float, height: float) -> OccupancyGrid:
    """Cells occupied at ``height`` above the floor by elements flagged for the occupancy map."""
    grid = world.grid(resolution)
    occupied = world.footprint(grid, world.floor_z + height, occupancy_only=True)
    free = world.area_mask(grid) & ~occupied
    return OccupancyGrid(grid, occupied, free)


def save_map_server(occupancy: OccupancyGrid, yaml_path: Path) -> None:
    """Write ``<name>.pgm`` and ``<name>.yaml`` as ROS map_server reads them (trinary, not negated).

    Free is 254, occupied 0 and unknown 205, with map_saver's thresholds, so that 205 reads back unknown.
    """
    yaml_path = Path(yaml_path)
    image = np.full(occupancy.grid.shape, UNKNOWN, dtype=np.uint8)
    image[occupancy.free] = FREE
    image[occupancy.occupied] = OCCUPIED
    pgm_path = yaml_path.with_suffix(".pgm")
    rows, cols = image.shape
    with pgm_path.open("wb") as handle:
        handle.write(f"P5\n{cols} {rows}\n255\n".encode())
        handle.write(np.flipud(image).tobytes())
    ox, oy = occupancy.grid.origin
    yaml_path.write_text(
        f"image: {pgm_path.name}\nmode: trinary\nresolution: {occupancy.grid.resolution}\n"
        f"origin: [{ox:.4f}, {oy:.4f}, 0.0]\nnegate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n"
    )


def read_pgm(path: Path) -> np.ndarray:
    """Read a binary (P5) PGM image, top row first, as 8-bit grey: a ``maxval`` other than 255 (16-bit ones
    included) is scaled to 0-255, as map_server's image library does."""
    data = Path(path).read_bytes()
    tokens: list[bytes] = []
    pos = 0
    while len(tokens) < 4 and pos < len(data):
        if data[pos : pos + 1].isspace():
            pos += 1
        elif data[pos : pos + 1] == b"#":
            newline = data.find(b"\n", pos)
            pos = len(data) if newline < 0 else newline
        else:
            end = pos
            while end < len(data) and not data[end : end + 1].isspace():
                end += 1
            tokens.append(data[pos:end])
            pos = end
    numbers = [t.decode("ascii", "replace") for t in tokens[1:]]
    if (
        len(tokens) < 4
        or tokens[0] != b"P5"
        or not all(n.isdigit() for n in numbers)
        or not 0 < int(numbers[2]) < 65536
    ):
        raise WorldError(f"{path}: expected a binary PGM (P5) header 'P5 width height maxval', got {tokens!r}")
    cols, rows, maxval = (int(n) for n in numbers)
    size = 1 if maxval < 256 else 2
    have = len(data) - (pos + 1)
    if have < rows * cols * size:
        raise WorldError(
            f"{path}: truncated: {have} bytes of pixels, the header says {cols} x {rows} = {rows * cols}"
            + (f" of {size} bytes" if size > 1 else "")
        )
    pixels = np.frombuffer(data, dtype=np.uint8 if size == 1 else ">u2", count=rows * cols, offset=pos + 1)
    if maxval != 255:
        pixels = np.round(np.minimum(pixels, maxval) * (255.0 / maxval)).astype(np.uint8)
    return pixels.reshape(rows, cols)


def resample_occupied(source: OccupancyGrid, target: GridSpec) -> np.ndarray:
    """Occupied cells of ``source`` drawn onto the cells of ``target`` (any source pixel inside marks a cell)."""
    gx, gy = source.grid.cell_centers()
    points = np.stack([gx[source.occupied], gy[source.occupied]], axis=1)
    rows, cols, valid = target.cells_of(points)
    mask = target.empty_mask()
    mask[rows[valid], cols[valid]] = True
    return mask


def tolerant_iou(a: np.ndarray, b: np.ndarray, tolerance_cells: int) -> float:
    """IoU of two occupied masks on one grid, where a cell matches if the other mask is within tolerance.

    Matched cells are those of ``a`` near ``b`` plus those of ``b`` near ``a``; the score is the share of
    the union ``a | b`` they make up. With zero tolerance this is the plain IoU.
    """
    structure = ndimage.generate_binary_structure(2, 1)
    near_a = ndimage.binary_dilation(a, structure, iterations=tolerance_cells) if tolerance_cells else a
    near_b = ndimage.binary_dilation(b, structure, iterations=tolerance_cells) if tolerance_cells else b
    union = a | b
    if not union.any():
        return 1.0
    matched = (a & near_b) | (b & near_a)
    return float(matched.sum() / union.sum())
