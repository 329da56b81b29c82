"""Whether a scan stood z-up in its file: the floor finder levels a scan on the level surface nearest its z, which
is a wall when the file's up is its x or y (a Y-up export), and the ceiling when the scan is upside down.

Two signs, each with what a user can do:

- the **scan lines**: a spinning LiDAR sweeps all round its spin axis within a narrow vertical field, so its
  returns' elevations about that axis stay in a band; when that band is about the file's x or y, and about z the
  returns spread over most of the sphere, the sensor stood on its side in the file's frame;
- **what stands off the floor**: desks, chairs and cabinets stand on a floor, so more returns lie just off a
  floor (0.15-1.2 m, on no face) than just off a wall or the ceiling. Far more off one of the scan's walls than
  off the floor it was levelled on says the floor is that wall (a full-sphere scanner has no scan lines to tell).
"""

from __future__ import annotations

import numpy as np

#: returns this far off a face count as standing off it (m): furniture on a floor, not the face itself
BAND_M = (0.15, 1.2)
#: a face this many times as well stood on as the floor says the floor is that face (simulated upright scans in
#: generated buildings and the iiLab: at most 2.6; the real room scan turned Y-up or X-up: 3.2-89)
STANDING_RATIO = 3.0
#: a spin axis: 90 % of the returns within this elevation band about it (deg), and beyond ``SPHERE_DEG`` about z
SPIN_BAND_DEG = 70.0
SPHERE_DEG = 110.0
FACES = ("floor", "top", "-x", "+x", "-y", "+y")


def elevation_spans(points: np.ndarray) -> np.ndarray:
    """The 5-95 % span (deg) of the returns' elevations about the file's x, y and z axes."""
    p = np.asarray(points, dtype=float)
    spans = []
    for axis in range(3):
        others = [k for k in range(3) if k != axis]
        elevation = np.degrees(np.arctan2(p[:, axis], np.hypot(p[:, others[0]], p[:, others[1]])))
        low, high = np.percentile(elevation, [5, 95])
        spans.append(high - low)
    return np.array(spans)


def spin_axis(points: np.ndarray) -> str | None:
    """``x``, ``y`` or ``z``: the axis the scan lines run round, when the returns show one (a spinning LiDAR);
    ``None`` for a scanner that covers the sphere."""
    spans = elevation_spans(points)
    axis = int(np.argmin(spans))
    narrow = spans[axis] <= SPIN_BAND_DEG and np.delete(spans, axis).min() >= SPHERE_DEG
    return "xyz"[axis] if narrow else None


def standing_off_faces(level: np.ndarray, sample: int = 20000) -> dict[str, int]:
    """Returns (of up to ``sample``) that stand 0.15-1.2 m off each face of the levelled scan and lie on none:
    the floor, the top, and the extremes along the two main wall directions (from the fullest 5 cm rows)."""
    p = np.asarray(level, dtype=float)
    if len(p) > sample:
        p = p[np.random.default_rng(0).choice(len(p), sample, replace=False)]
    best, fullest = 0.0, -1
    for angle in np.radians(np.arange(0.0, 90.0, 1.0)):  # the walls' direction: the fullest rows of 5 cm
        turned = p[:, :2] @ np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
        rows = sum(int(np.bincount(((v - v.min()) / 0.05).astype(np.int64)).max()) for v in turned.T)
        if rows > fullest:
            best, fullest = angle, rows
    c, s = np.cos(best), np.sin(best)
    q = np.column_stack([p[:, :2] @ np.array([[c, -s], [s, c]]), p[:, 2]])
    low, high = np.percentile(q, 1, axis=0), np.percentile(q, 99, axis=0)
    on_face = ((q - low < 0.1) | (high - q < 0.1)).any(axis=1)
    counts = {}
    for axis, (below, above) in zip((2, 0, 1), (("floor", "top"), ("-x", "+x"), ("-y", "+y")), strict=True):
        for name, off in ((below, q[:, axis] - low[axis]), (above, high[axis] - q[:, axis])):
            counts[name] = int(np.count_nonzero((off > BAND_M[0]) & (off < BAND_M[1]) & ~on_face))
    return {name: counts[name] for name in FACES}


def upright_warnings(points: np.ndarray, standing: dict[str, int], turned_by_mount: bool) -> list[str]:
    """What to tell a user whose scan did not stand z-up: ``points`` as in the file (sensor frame), ``standing``
    from :func:`standing_off_faces`; ``turned_by_mount``: the user gave the mount's roll and pitch."""
    if turned_by_mount:
        return []  # the user said how it stands
    found = []
    axis = spin_axis(points)
    if axis in ("x", "y"):
        found.append(
            f"the scan lines run round the file's {axis} axis, not its z: the file looks {axis.upper()}-up (a"
            f" spinning LiDAR stood on its side); give its mount (--sensors with lidar3d mount_roll_deg or"
            f" mount_pitch_deg 90) or turn the file z-up"
        )
    walls = {k: standing.get(k, 0) for k in FACES[2:]}
    side = max(walls, key=lambda k: walls[k])
    floor = standing.get("floor", 0)
    if not found and walls[side] >= STANDING_RATIO * max(floor, 1) and walls[side] >= 200:
        found.append(
            f"the floor it was levelled on may be a wall: {walls[side]} returns stand just off one of the scan's"
            f" walls, {floor} off its floor (furniture stands on a floor); is the file z-up?"
        )
    return found
