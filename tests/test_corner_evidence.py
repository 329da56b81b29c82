import numpy as np
import pytest

from pimm_agents.corners.lookup import NearestCornerGrid
from pimm_agents.pimm.corner_evidence import corner_exponents
from pimm_env.mapping.corner_map import CornerMap


def numpy_exponents(grid: NearestCornerGrid, f: np.ndarray, x: np.ndarray, y: np.ndarray, theta: np.ndarray):
    """The whole-array NumPy expression the compiled loop replaced (float32, same order of operations)."""
    cos, sin = np.cos(theta), np.sin(theta)
    fx, fy = f[:, 0:1], f[:, 1:2]
    mx = fx * cos
    mx -= fy * sin
    mx += x
    my = fy * cos
    my += fx * sin
    my += y
    da = theta + f[:, 2:3]
    cell = grid.cells(mx, my, da)
    corner = np.take(grid.cell_xy, cell)
    mx -= corner.real
    my -= corner.imag
    da -= np.take(grid.cell_theta, cell)
    da -= np.float32(2 * np.pi) * np.rint(da * np.float32(1 / (2 * np.pi)))
    mx *= mx
    my *= my
    mx += my
    mx *= -1.5 / f[:, 3:4] ** 2
    da *= da
    da *= -1.5 / f[:, 4:5] ** 2
    mx += da
    return mx


@pytest.mark.parametrize("bins", [1, 6, 8])
def test_the_compiled_exponents_equal_numpys_to_the_bit(bins: int) -> None:
    rng = np.random.default_rng(bins)
    corners = CornerMap(xy=rng.uniform(-10, 10, (30, 2)), z=np.full(30, 3.0), theta=rng.uniform(-np.pi, np.pi, 30))
    grid = NearestCornerGrid(corners, resolution=0.1, margin=3.0, orientation_bins=bins)
    for n in (1, 7, 2000):
        # particles inside the grid and far outside it (their cells are clipped to the grid's range)
        x, y = rng.uniform(-30, 30, n).astype(np.float32), rng.uniform(-30, 30, n).astype(np.float32)
        theta = rng.uniform(-7, 7, n).astype(np.float32)
        f = np.column_stack(
            [rng.uniform(-8, 8, (5, 2)), rng.uniform(-np.pi, np.pi, 5), rng.uniform(0.05, 1, (5, 2))]
        ).astype(np.float32)
        compiled = corner_exponents(grid, f, x, y, theta)
        assert compiled.dtype == np.float32 and compiled.shape == (5, n)
        assert np.array_equal(compiled, numpy_exponents(grid, f, x, y, theta))
