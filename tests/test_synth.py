"""The scene renderer: determinism, ground truth against the pixels, conditions, bad options, CLI."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from sbplan.cli import main
from sbplan.errors import SceneError
from sbplan.synth import (AMBIGUOUS, CONDITIONS, FREE, OCCUPIED, PATTERNS, FloorSpec, GroundTruth, SceneSpec,
                          render_reference, render_scene)

SMALL = dict(width=320, height=240, cols=6, rows=4)
#: no lighting or camera effects: every pixel the obstacles do not touch equals the reference's
PLAIN = {"noise": 0.0, "blur": 0.0}


@pytest.fixture(scope="module")
def floor():
    return FloorSpec(**SMALL, floor_seed=3)


def test_reference_is_deterministic_per_seed(floor):
    a, b = render_reference(floor, seed=4), render_reference(floor, seed=4)
    assert a.dtype == np.uint8 and a.shape == (240, 320)
    assert np.array_equal(a, b)
    assert not np.array_equal(a, render_reference(floor, seed=5))


def test_scene_is_deterministic_per_seed(floor):
    scene = SceneSpec(n_obstacles=3, condition="shadows")
    img1, t1 = render_scene(floor, scene, seed=9)
    img2, t2 = render_scene(floor, scene, seed=9)
    assert np.array_equal(img1, img2)
    assert t1.to_json() == t2.to_json()
    img3, t3 = render_scene(floor, scene, seed=10)
    assert not np.array_equal(img1, img3)
    assert t1.to_json() != t3.to_json()


def test_floor_seed_changes_the_floor_texture():
    a = render_reference(FloorSpec(**SMALL, floor_seed=1), seed=0, effects=PLAIN)
    b = render_reference(FloorSpec(**SMALL, floor_seed=2), seed=0, effects=PLAIN)
    assert not np.array_equal(a, b)


def test_truth_round_trips_through_json(floor, tmp_path):
    _, truth = render_scene(floor, SceneSpec(n_obstacles=2), seed=3)
    again = GroundTruth.from_json(truth.to_json())
    assert np.array_equal(again.cells, truth.cells)
    assert np.allclose(again.centres_px, truth.centres_px, atol=1e-4)
    assert len(again.obstacles) == len(truth.obstacles) == 2
    assert again.params["seed"] == 3 and again.params["scene"]["n_obstacles"] == 2
    path = tmp_path / "t.json"
    path.write_text(truth.to_json())
    assert GroundTruth.from_json(path).counts == truth.counts


@pytest.mark.parametrize("seed", [1, 2, 3, 4])
def test_truth_matches_the_pixels(seed):
    """Occupied cells' symbols are really covered; free cells' symbols are untouched."""
    floor = FloorSpec(width=480, height=360, cols=8, rows=6, floor_seed=seed)
    ref = render_reference(floor, seed=0, effects=PLAIN).astype(int)
    img, truth = render_scene(floor, SceneSpec(n_obstacles=4, effects=PLAIN), seed=seed)
    img = img.astype(int)
    assert truth.counts["occupied"] > 0 and truth.counts["free"] > 0
    ink = ref < floor.background - floor.contrast / 2  # the printed symbols in the reference
    dx, dy = floor.pitch_px
    changed = img != ref
    # every pixel the printed symbols touch, antialiased rims included
    near_ink = PATTERNS["symbols"](floor)[0] > 0
    for r in range(floor.rows):
        for c in range(floor.cols):
            x, y = truth.centres_px[r, c]
            x0, x1 = int(round(x - dx / 2)), int(round(x + dx / 2))
            y0, y1 = int(round(y - dy / 2)), int(round(y + dy / 2))
            sym = ink[max(y0, 0):y1, max(x0, 0):x1]
            moved = changed[max(y0, 0):y1, max(x0, 0):x1]
            rim = near_ink[max(y0, 0):y1, max(x0, 0):x1]
            assert sym.sum() > 50
            hidden = float(moved[sym].mean())
            state = truth.cells[r, c]
            if state == FREE:
                # every pixel of the symbol and its rim is exactly as in the reference
                assert not moved[rim].any(), (r, c)
            elif state == OCCUPIED:
                assert hidden > truth.params["occupied_fraction"], (r, c, hidden)
                assert abs(hidden - truth.overlap[r, c]) < 0.12, (r, c, hidden, truth.overlap[r, c])
            else:
                assert state == AMBIGUOUS and truth.overlap[r, c] <= truth.params["occupied_fraction"]


def test_truth_rule_uses_the_stated_fraction(floor):
    _, lo = render_scene(floor, SceneSpec(n_obstacles=4, occupied_fraction=0.02), seed=21)
    _, hi = render_scene(floor, SceneSpec(n_obstacles=4, occupied_fraction=0.6), seed=21)
    assert np.array_equal(lo.overlap, hi.overlap)
    assert np.array_equal(lo.cells == OCCUPIED, lo.overlap > 0.02)
    assert np.array_equal(hi.cells == OCCUPIED, hi.overlap > 0.6)
    sliver = (hi.overlap > 0) & (hi.overlap <= 0.6)
    assert sliver.any() and (hi.cells[sliver] == AMBIGUOUS).all()
    assert (hi.overlap[hi.cells == AMBIGUOUS] <= 0.6).all()
    assert (hi.overlap[hi.cells == FREE] == 0).all()
    assert (hi.cells == AMBIGUOUS).sum() >= (lo.cells == AMBIGUOUS).sum()


def test_explicit_obstacles_cover_exactly_their_cells():
    floor = FloorSpec(width=400, height=300, cols=4, rows=3)
    x, y = floor.col_x[1], floor.row_y[1]
    dx, dy = floor.pitch_px
    square = np.array([[x - 0.4 * dx, y - 0.4 * dy], [x - 0.4 * dx, y + 0.4 * dy],
                       [x + 0.4 * dx, y + 0.4 * dy], [x + 0.4 * dx, y - 0.4 * dy]])
    _, truth = render_scene(floor, SceneSpec(obstacles=[square]), seed=0)
    want = np.zeros((3, 4), np.int8)
    want[1, 1] = OCCUPIED
    assert np.array_equal(truth.cells, want)
    assert truth.overlap[1, 1] == pytest.approx(1.0)
    assert np.allclose(truth.obstacles[0], square)


@pytest.mark.parametrize("name", sorted(CONDITIONS))
def test_every_condition_renders(name, floor):
    clean, clean_truth = render_scene(floor, SceneSpec(n_obstacles=2), seed=5)
    img, truth = render_scene(floor, SceneSpec(n_obstacles=2, condition=name), seed=5)
    ref = render_reference(floor, seed=0, condition=name)
    assert img.shape == ref.shape == (240, 320) and img.dtype == ref.dtype == np.uint8
    assert truth.cells.shape == (4, 6) and truth.params["scene"]["condition"] == name
    assert 20 < img.mean() < 250
    if name != "clean":
        assert not np.array_equal(img, clean)
    # the condition does not move the obstacles (independent seed streams)
    assert len(truth.obstacles_floor) == 2
    assert all(np.allclose(a, b) for a, b in zip(truth.obstacles_floor, clean_truth.obstacles_floor))


def test_conditions_do_what_they_say(floor):
    def mean(name):
        return render_scene(floor, SceneSpec(n_obstacles=0, condition=name), seed=2)[0].astype(float)
    clean = mean("clean")
    assert mean("bright").mean() > 1.2 * clean.mean()
    assert mean("dark").mean() < 0.7 * clean.mean()
    assert mean("low-light").mean() < 0.35 * clean.mean()
    assert np.abs(cv2.Laplacian(mean("blur"), cv2.CV_64F)).mean() < np.abs(cv2.Laplacian(clean, cv2.CV_64F)).mean()
    assert (mean("noise") - clean).std() > 4
    assert mean("highlights").max() >= clean.max()


def test_tilt_moves_the_true_centres():
    flat = FloorSpec(**SMALL)
    tilted = FloorSpec(**SMALL, tilt=(4.0, -3.0))
    _, t0 = render_scene(flat, SceneSpec(n_obstacles=1), seed=1)
    _, t1 = render_scene(tilted, SceneSpec(n_obstacles=1), seed=1)
    assert np.allclose(t0.centres_px, flat.centres())
    shift = np.linalg.norm(t1.centres_px - t0.centres_px, axis=-1)
    assert shift.max() > 2 and shift.max() < 40
    assert np.array_equal(t0.cells, t1.cells)  # occupancy is decided in the floor plane


@pytest.mark.parametrize("make, option", [
    (lambda: FloorSpec(width=-5, height=240), "width"),
    (lambda: FloorSpec(width=320, height=0), "height"),
    (lambda: FloorSpec(**{**SMALL, "cols": 0}), "cols"),
    (lambda: FloorSpec(**{**SMALL, "rows": -2}), "rows"),
    (lambda: FloorSpec(width=100, height=80, cols=40, rows=30), "cols/rows"),
    (lambda: FloorSpec(**SMALL, symbol_size=-3), "symbol_size"),
    (lambda: FloorSpec(**SMALL, symbol_size=200), "symbol_size"),
    (lambda: FloorSpec(**SMALL, pitch=-10), "pitch"),
    (lambda: FloorSpec(**SMALL, pitch=120), "pitch/margin"),
    (lambda: FloorSpec(**SMALL, symbol="no-such-symbol"), "symbol"),
    (lambda: FloorSpec(**SMALL, symbol=[(0, 0), (1, 1), (1, 0), (0, 1)]), "symbol"),
    (lambda: FloorSpec(**SMALL, tilt=(30, 0)), "tilt"),
    (lambda: SceneSpec(n_obstacles=-1), "n_obstacles"),
    (lambda: SceneSpec(condition="foggy"), "condition"),
    (lambda: SceneSpec(kinds=("sofa",)), "kinds"),
    (lambda: SceneSpec(size=(-1, 2)), "size"),
    (lambda: SceneSpec(effects={"gain": -1}), "effects.gain"),
    (lambda: SceneSpec(occupied_fraction=0), "occupied_fraction"),
    (lambda: render_scene(FloorSpec(**SMALL), seed=-1), "seed"),
])
def test_bad_options_raise_scene_error_naming_the_option(make, option):
    with pytest.raises(SceneError) as err:
        make()
    assert str(err.value).startswith(option + ":"), str(err.value)


def test_cli_writes_reference_scenes_and_truth(tmp_path, capsys):
    out = tmp_path / "floor"
    assert main(["synth", "-o", str(out), "--size", "320x240", "--grid", "6x4", "--scenes", "2",
                 "--obstacles", "2", "--condition", "gradient", "--seed", "3"]) == 0
    names = sorted(p.name for p in out.iterdir())
    assert names == ["reference.png", "scene-01.json", "scene-01.png", "scene-02.json", "scene-02.png"]
    img = cv2.imread(str(out / "scene-02.png"), cv2.IMREAD_UNCHANGED)
    assert img.shape == (240, 320)
    truth = json.loads((out / "scene-02.json").read_text())
    assert truth["params"]["seed"] == 5 and truth["params"]["scene"]["condition"] == "gradient"
    floor = FloorSpec.from_dict(truth["params"]["floor"])
    expect, _ = render_scene(floor, SceneSpec.from_dict(truth["params"]["scene"]), seed=5)
    assert np.array_equal(img, expect)  # the truth records every parameter needed to re-render
    assert "scene-02: " in capsys.readouterr().out


def test_cli_list_names_maps_and_conditions(capsys):
    assert main(["synth", "--list"]) == 0
    text = capsys.readouterr().out
    for name in ("paper-8x6", "large-16x12", "edge-clips", *CONDITIONS):
        assert name in text


@pytest.mark.parametrize("argv, option", [
    (["--grid", "40x30", "--size", "100x80"], "cols/rows"),
    (["--grid", "0x4"], "cols"),
    (["--size=-320x240"], "width"),
    (["--size", "big"], "--size"),
    (["--symbol", "nope"], "symbol"),
    (["--condition", "nope"], "condition"),
    (["--obstacles", "-2"], "n_obstacles"),
])
def test_cli_bad_options_print_one_line_and_fail(argv, option, tmp_path, capsys):
    code = main(["synth", "-o", str(tmp_path / "x"), *argv])
    err = capsys.readouterr().err
    assert code != 0
    assert err.count("\n") == 1 and err.startswith(f"sbplan: error: {option}:"), err
    assert not (tmp_path / "x" / "reference.png").exists()
