"""A trial replayed as an animation: map, 2D scan, particles, truth, estimate and (for PIMM) detected corners.

Trials are deterministic given their seed, so a trial chosen after a run (the best, the worst) is simulated
again with a watcher that keeps one frame per few scans; nothing has to be recorded during the run itself.
Written as MP4 where ffmpeg is installed, else as a GIF (Pillow).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pimm_env.errors import ResultsError
from pimm_env.mapping.occupancy import OccupancyGrid

#: Frames per second of the animation; with one frame per ``EVERY_SCANS`` scans of the 10 Hz 2D LiDAR, a
#: second of the video shows two seconds of the trial, a pace a person can follow.
FPS = 10
EVERY_SCANS = 2


@dataclass(frozen=True)
class Frame:
    time: float
    true: np.ndarray  # (3,) map frame
    estimate: np.ndarray  # (3,)
    scan: np.ndarray  # (B, 2) the 2D scan's returns in the map frame, placed at the true pose
    inner: dict[str, np.ndarray]  # the estimate's inside: particles, corners, suggestions (what it offers)
    kidnapped: bool  # after the kidnap
    status: str = "localized"  # the localizer's status with this estimate
    hypotheses: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))  # (K, 3) its modes (and rivals)


def write_video(
    frames: list[Frame], occupancy: OccupancyGrid, map_corners: np.ndarray, path: Path, title: str, fps: int = FPS
) -> Path:
    """Animate ``frames`` over the map; ``path``'s suffix becomes .mp4 (where ffmpeg is installed) or .gif.

    The map and everything that does not move is drawn once; each frame restores that picture and draws only
    the moving artists on it (blitting), which keeps a frame to a few milliseconds."""
    import shutil

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from pimm_env.envs.render import show_map

    if not frames:
        raise ResultsError(f"{path}: no frames to animate")
    offered = set(frames[0].inner)
    fig, ax = plt.subplots(figsize=(7, 6), dpi=80)
    show_map(ax, occupancy)
    if len(map_corners):
        ax.plot(map_corners[:, 0], map_corners[:, 1], "s", ms=3, mfc="none", mec="0.45", label="map corners")

    def label(text: str, key: str | None = None) -> str:
        return text if key is None or key in offered else "_hidden"

    particles = ax.scatter([], [], s=2, c="tab:purple", alpha=0.35, label=label("particles", "particles"))
    scan = ax.scatter([], [], s=2, c="tab:cyan", label="2D scan")
    (trail,) = ax.plot([], [], "-", color="tab:green", lw=1, label="true path")
    (truth,) = ax.plot([], [], "o", color="tab:green", ms=7)
    (estimate,) = ax.plot([], [], "o", color="tab:red", ms=6, label="estimate")
    (heading,) = ax.plot([], [], "-", color="tab:red", lw=2)
    hypotheses = ax.scatter([], [], s=90, marker="o", facecolors="none", edgecolors="tab:blue", linewidths=1.2,
                            label="hypotheses")  # fmt: skip
    corners = ax.scatter([], [], s=30, marker="x", c="tab:orange", label=label("detected corners", "corners"))
    suggestions = ax.scatter([], [], s=40, marker="*", c="gold", edgecolors="k", linewidths=0.4,
                             label=label("fingerprint suggestions", "suggestions"))  # fmt: skip
    caption = ax.text(0.01, 0.99, "", transform=ax.transAxes, va="top", fontsize=9,
                      bbox={"facecolor": "white", "alpha": 0.8, "lw": 0})  # fmt: skip
    moving = [particles, scan, trail, corners, suggestions, hypotheses, truth, estimate, heading, caption]
    for artist in moving:
        artist.set_animated(True)
    ax.set_title(title, fontsize=10)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.legend(loc="lower right", fontsize=7, markerscale=2)
    fig.tight_layout()
    canvas = fig.canvas
    canvas.draw()
    background = canvas.copy_from_bbox(fig.bbox)  # type: ignore[attr-defined]
    t0 = frames[0].time

    def offsets(points: np.ndarray | None) -> np.ndarray:
        return np.zeros((0, 2)) if points is None or len(points) == 0 else np.asarray(points)[:, :2]

    def render(i: int) -> np.ndarray:
        f = frames[i]
        particles.set_offsets(offsets(f.inner.get("particles")))
        corners.set_offsets(offsets(f.inner.get("corners")))
        suggestions.set_offsets(offsets(f.inner.get("suggestions")))
        scan.set_offsets(offsets(f.scan))
        hypotheses.set_offsets(offsets(f.hypotheses))
        since = [g.true for g in frames[: i + 1] if g.kidnapped == f.kidnapped]
        trail.set_data([p[0] for p in since], [p[1] for p in since])
        truth.set_data([f.true[0]], [f.true[1]])
        estimate.set_data([f.estimate[0]], [f.estimate[1]])
        heading.set_data(
            [f.estimate[0], f.estimate[0] + 0.8 * np.cos(f.estimate[2])],
            [f.estimate[1], f.estimate[1] + 0.8 * np.sin(f.estimate[2])],
        )
        error = np.hypot(*(f.estimate[:2] - f.true[:2]))
        caption.set_text(
            f"t = {f.time - t0:5.1f} s   {f.status}   error {error:5.2f} m" + ("   (after the kidnap)" * f.kidnapped)
        )
        canvas.restore_region(background)  # type: ignore[attr-defined]
        for artist in moving:
            ax.draw_artist(artist)
        return np.asarray(canvas.buffer_rgba())[:, :, :3].copy()  # type: ignore[attr-defined]

    images = [render(i) for i in range(len(frames))]
    plt.close(fig)
    ffmpeg = shutil.which("ffmpeg")
    if ffmpeg:
        return _write_mp4(ffmpeg, images, Path(path).with_suffix(".mp4"), fps)
    return _write_gif(images, Path(path).with_suffix(".gif"), fps)


def _write_gif(images: list[np.ndarray], path: Path, fps: int) -> Path:
    from PIL import Image

    pictures = [Image.fromarray(image).quantize(colors=64, method=Image.Quantize.FASTOCTREE) for image in images]
    pictures[0].save(path, save_all=True, append_images=pictures[1:], duration=round(1000 / fps), loop=0)
    return path


def _write_mp4(ffmpeg: str, images: list[np.ndarray], path: Path, fps: int) -> Path:
    import subprocess

    height, width = images[0].shape[:2]
    source = ["-f", "rawvideo", "-pix_fmt", "rgb24", "-s", f"{width}x{height}", "-r", str(fps), "-i", "-"]
    even = ["-vf", "pad=ceil(iw/2)*2:ceil(ih/2)*2", "-pix_fmt", "yuv420p"]  # H.264 wants even sides
    command = [ffmpeg, "-y", "-loglevel", "error", *source, *even, str(path)]
    subprocess.run(command, input=b"".join(image.tobytes() for image in images), check=True)
    return path


def chosen_trials(which: str, best: int | None, worst: int | None, count: int) -> list[tuple[str, int]]:
    """(label, index) of the trials ``--video best|worst|all`` asks for; best and worst once if the same."""
    if which == "all":
        return [(f"trial{i:02d}", i) for i in range(count)]
    picks = {"best": [("best", best)], "worst": [("worst", worst)]}[which]
    return [(label, i) for label, i in picks if i is not None]
