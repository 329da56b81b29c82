from pathlib import Path

import numpy as np
from PIL import Image

from pimm_agents.experiments.frames import collect_frames
from pimm_agents.results.video import EVERY_SCANS, chosen_trials, write_video
from pimm_agents.scoring.trial import TrialSpec
from pimm_env.mapping.derived_maps import ensure_derived_maps
from pimm_env.world.files import load_world
from tests.rooms import AMCL, ROUTES


def test_a_trial_replays_as_an_animation_with_its_particles(room_file: Path, tmp_path, monkeypatch):
    (room_file.parent / "scenarios.yaml").write_text(ROUTES)
    maps = ensure_derived_maps(load_world(room_file))
    spec = TrialSpec("there_kidnap", "amcl", 0, 2, str(room_file), AMCL)
    frames = collect_frames(spec)
    assert len(frames) > 20 and frames[-1].time > frames[0].time
    assert all(len(f.inner["particles"]) <= 400 and np.isfinite(f.inner["particles"]).all() for f in frames)
    assert not frames[0].kidnapped and frames[-1].kidnapped  # the replay sees the kidnap
    assert all(np.all(np.abs(f.scan - f.true[:2]) <= 10.0) for f in frames)  # returns lie around the robot
    assert frames[1].time - frames[0].time > 0.1 * (EVERY_SCANS - 0.5)  # one frame per EVERY_SCANS scans
    monkeypatch.setattr("shutil.which", lambda name: None)  # no ffmpeg: a GIF
    path = write_video(frames, maps.occupancy, maps.corners.xy, tmp_path / "there", "amcl, there")
    assert path.suffix == ".gif"
    with Image.open(path) as gif:
        assert gif.n_frames == len(frames) and gif.size[0] > 300


def test_video_choice_picks_the_trials_asked_for():
    assert chosen_trials("best", 2, 2, 3) == [("best", 2)]
    assert chosen_trials("worst", 0, 2, 3) == [("worst", 2)]
    assert chosen_trials("all", 0, 2, 2) == [("trial00", 0), ("trial01", 1)]
    assert chosen_trials("best", None, 1, 2) == []
