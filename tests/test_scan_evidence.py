import numpy as np

from pimm_agents.pimm.scan_evidence import summed_scan_evidence


def reference(poses, motions, scan_of, points, log_pz, off, free, origin, res, temperature, off_free):
    """The evidence written pose by pose and point by point in NumPy, as the kernel's docstring states it."""
    out = []
    for x0, y0, a0 in poses:
        then = np.column_stack(
            [
                x0 + np.cos(a0) * motions[:, 0] - np.sin(a0) * motions[:, 1],
                y0 + np.sin(a0) * motions[:, 0] + np.cos(a0) * motions[:, 1],
                a0 + motions[:, 2],
            ]
        )
        total = 0.0
        for j, (tx, ty, ta) in enumerate(then):
            col, row = int(np.floor((tx - origin[0]) / res)), int(np.floor((ty - origin[1]) / res))
            on_free = 0 <= row < free.shape[0] and 0 <= col < free.shape[1] and free[row, col]
            total += 0.0 if on_free else off_free
            for px, py in points[scan_of == j]:
                x = tx + np.cos(ta) * px - np.sin(ta) * py
                y = ty + np.sin(ta) * px + np.cos(ta) * py
                c, r = int(np.floor((x - origin[0]) / res)), int(np.floor((y - origin[1]) / res))
                inside = 0 <= r < log_pz.shape[0] and 0 <= c < log_pz.shape[1]
                total += temperature * (log_pz[r, c] if inside else off)
        out.append(total)
    return np.array(out)


def test_the_compiled_evidence_equals_the_numpy_reference_on_and_off_the_map():
    rng = np.random.default_rng(3)
    log_pz = -rng.uniform(0, 5, (40, 60))
    free = rng.uniform(size=(40, 60)) > 0.3
    origin, res = np.array([-1.0, -2.0]), 0.1
    # poses inside, at the edge and far off the 6 m x 4 m map, so both off-map branches are taken
    poses = np.vstack([rng.uniform([-1, -2, -np.pi], [5, 2, np.pi], (20, 3)), [[30.0, 30.0, 0.0], [-1.0, -2.0, 1.0]]])
    motions = rng.uniform([-2, -2, -1], [2, 2, 1], (6, 3))
    scan_of = np.sort(rng.integers(0, 6, 90))
    points = rng.uniform(-3, 3, (90, 2))
    args = (poses, motions, scan_of, points, log_pz, -7.5, free, origin, res, 0.2, np.log(0.1))
    got = summed_scan_evidence(*args[:7], origin[0], origin[1], *args[8:])
    want = reference(*args)
    assert np.allclose(got, want, rtol=1e-12, atol=1e-9)
    assert np.isclose(got[-2], 0.2 * -7.5 * 90 + 6 * np.log(0.1))  # far off: every point and scan penalized
