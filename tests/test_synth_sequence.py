"""Rendered streams (sbplan.synth.sequence): what they hold, read back through OpenCV."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from sbplan.cli import main
from sbplan.errors import SceneError
from sbplan.synth import FloorSpec, SceneSpec, render_scene
from sbplan.synth.sequence import SequenceSpec, Shade, Track, demo_sequence, read_truth, render_sequence

FLOOR = FloorSpec(width=320, height=240, cols=6, rows=4)


def test_synth_writes_a_video_stream_with_per_frame_truth(tmp_path, capsys):
    assert main(["synth", "-o", str(tmp_path), "--sequence", "avi", "--size", "320x240", "--grid", "6x4",
                 "--frames", "24", "--seed", "2"]) == 0
    assert "24 frames at 10 fps" in capsys.readouterr().out
    truth = read_truth(tmp_path)
    meta = json.loads((tmp_path / "sequence.json").read_text())
    assert len(truth) == 24 and meta["kind"] == "avi" and (tmp_path / "reference.png").is_file()
    dropped = [t["frame"] for t in truth if t["dropped"]]
    corrupt = [t["written"] for t in truth if t["corrupt"]]
    assert len(dropped) == 1 and len(corrupt) == 1
    cap = cv2.VideoCapture(str(tmp_path / "sequence.avi"), cv2.CAP_FFMPEG)
    assert cap.get(cv2.CAP_PROP_FRAME_COUNT) == 23 and cap.get(cv2.CAP_PROP_FPS) == 10
    decoded = []
    for index in range(23):
        ok, image = cap.read()
        decoded.append(ok)
        if ok:
            assert image.shape[:2] == (240, 320)
    assert [i for i, ok in enumerate(decoded) if not ok] == corrupt  # only the corrupt frame fails


def test_folder_stream_numbers_its_files_by_scene_frame(tmp_path):
    spec = demo_sequence(FLOOR, n_frames=24)
    main(["synth", "-o", str(tmp_path), "--sequence", "folder", "--size", "320x240", "--grid", "6x4",
          "--frames", "24"])
    names = sorted(p.name for p in (tmp_path / "frames").iterdir())
    assert len(names) == 23 and f"frame-{spec.dropped[0]:05d}.png" not in names
    assert cv2.imread(str(tmp_path / "frames" / f"frame-{spec.corrupt[0]:05d}.png")) is None
    assert cv2.imread(str(tmp_path / "frames" / "frame-00000.png")) is not None


def test_the_timeline_is_in_the_truth():
    spec = demo_sequence(FLOOR, n_frames=24, hysteresis=3)
    truth = {k: t for k, _, t in render_sequence(FLOOR, spec, seed=1)}
    assert [k for k, t in truth.items() if "1" in t["tracks"]] == [6]  # the blip: one frame
    slider = [tuple(map(tuple, truth[k]["tracks"]["2"])) for k in range(6, 19)]
    assert slider[0] == ((2, 1),) and slider[-1] == ((2, 2),)
    shaded = [k for k, t in truth.items() if t["shade"]]
    assert shaded == list(range(4, 9))
    # a shadow is not an obstacle: the cells it crosses stay free
    for k in shaded:
        cells = np.array(truth[k]["cells"])
        expected = np.zeros_like(cells)
        for track in truth[k]["tracks"].values():
            for r, c in track:
                expected[r, c] = 1
        assert ((cells == 1) == (expected == 1)).all()
    assert truth[11]["camera_motion"] is None and truth[12]["camera_motion"] == [4.0, -3.0, 0.3, 1.0]


def test_an_obstacle_looks_the_same_in_every_frame():
    box = np.array([[100.0, 80.0], [100.0, 140.0], [170.0, 140.0], [170.0, 80.0]])
    other = box + (120, 0)
    alone, _ = render_scene(FLOOR, SceneSpec(obstacles=[box], effects={"noise": 0}), seed=5, texture_seeds=[7])
    both, _ = render_scene(FLOOR, SceneSpec(obstacles=[other, box], effects={"noise": 0}), seed=5,
                           texture_seeds=[8, 7])
    assert np.array_equal(alone[85:135, 105:165], both[85:135, 105:165])
    a, _ = render_scene(FLOOR, SceneSpec(obstacles=[box]), seed=5, noise_seed=1, texture_seeds=[7])
    b, _ = render_scene(FLOOR, SceneSpec(obstacles=[box]), seed=5, noise_seed=2, texture_seeds=[7])
    assert not np.array_equal(a, b) and np.abs(a.astype(int) - b).mean() < 3  # new noise only


@pytest.mark.parametrize("bad, match", [
    (lambda: Track([[0, 0], [1, 1]], 0, 3), "outline"),
    (lambda: Track([[0, 0], [1, 0], [0, 1]], 5, 3), "first <= last"),
    (lambda: SequenceSpec(n_frames=0), "n_frames"),
    (lambda: SequenceSpec(n_frames=5, dropped=[2], corrupt=[2]), "cannot be both"),
    (lambda: SceneSpec(effects={"shade": (0.95, 2.0, ((0, 0), (1, 0), (0, 1)))}), "effects.shade"),
    (lambda: demo_sequence(FloorSpec(width=320, height=240, cols=3, rows=3)), "4 x 3 cells"),
    (lambda: render_scene(FLOOR, SceneSpec(n_obstacles=2), texture_seeds=[1, 2]), "texture_seeds"),
])
def test_bad_streams_are_refused(bad, match):
    with pytest.raises(SceneError, match=match):
        bad()


def test_a_shade_darkens_only_where_it_passes():
    shade = Shade(start=(0, 120), end=(320, 120), first=0, last=4, length=80, darkness=0.5, blur=2)
    ring = shade.at(2)[2]
    lit, _ = render_scene(FLOOR, SceneSpec(obstacles=[], effects={"noise": 0}), seed=1)
    dark, _ = render_scene(FLOOR, SceneSpec(obstacles=[], effects={"noise": 0, "shade": shade.at(2)}), seed=1)
    cx, cy = np.mean(ring, axis=0)
    assert dark[int(cy), int(cx)] < 0.7 * lit[int(cy), int(cx)]
    assert np.array_equal(dark[:40], lit[:40])  # far from it, nothing changes
    assert shade.at(5) is None
