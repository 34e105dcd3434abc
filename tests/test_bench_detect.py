"""ArUco floor layout, the detection baselines, and `sbplan bench detect` on one tiny scene."""

import json
import logging

import cv2
import numpy as np
import pytest

from sbplan.bench.baselines import AbsDiff, ArucoGrid, Mog2, footprints
from sbplan.cli import main
from sbplan.errors import InputError, SceneError
from sbplan.imageio import load_image
from sbplan.synth import FloorSpec, SceneSpec, render_reference, render_scene
from sbplan.synth.aruco import marker_dictionary

FLOOR = dict(width=480, height=360, cols=6, rows=4)


def _box_over(floor, row, col, half):
    x, y = floor.col_x[col], floor.row_y[row]
    return [(x - half, y - half), (x + half, y - half), (x + half, y + half), (x - half, y + half)]


@pytest.fixture(scope="module")
def floors():
    sym, aru = FloorSpec(**FLOOR), FloorSpec(**FLOOR, layout="aruco")
    # one obstacle hiding cell (1, 2) entirely, nothing near the others
    scene = SceneSpec(obstacles=[_box_over(sym, 1, 2, 0.4 * sym.pitch_px[1])])
    return {
        "sym": (sym, render_reference(sym, seed=0), *render_scene(sym, scene, seed=3)),
        "aru": (aru, render_reference(aru, seed=0), *render_scene(aru, scene, seed=3)),
    }


def test_aruco_floor_prints_each_cells_id_at_its_grid_point(floors):
    floor, ref, _, _ = floors["aru"]
    name, d = marker_dictionary(floor.rows * floor.cols)
    assert name == "DICT_4X4_50"
    corners, ids, _ = cv2.aruco.ArucoDetector(d, cv2.aruco.DetectorParameters()).detectMarkers(ref)
    assert ids is not None and sorted(ids.ravel().tolist()) == list(range(floor.rows * floor.cols))
    centres = floor.centres().reshape(-1, 2)
    for c, i in zip(corners, ids.ravel()):
        quad = c.reshape(4, 2)
        assert np.linalg.norm(quad.mean(axis=0) - centres[i]) < 1.5
        side = np.linalg.norm(quad - np.roll(quad, 1, axis=0), axis=1).mean()
        assert abs(side - floor.symbol_size) < 0.1 * floor.symbol_size


def test_aruco_scene_shares_obstacles_and_truth_rule(floors):
    sym_floor, _, sym_img, sym_truth = floors["sym"]
    aru_floor, _, aru_img, aru_truth = floors["aru"]
    assert aru_truth.cells[1, 2] == 1 and sym_truth.cells[1, 2] == 1
    assert (aru_truth.cells == 1).sum() == 1 and (sym_truth.cells == 1).sum() == 1
    # same obstacle pixels: the hidden area is identical in both images, only the print differs
    inside = np.zeros(sym_img.shape, np.uint8)
    cv2.fillPoly(inside, [np.round(np.array(_box_over(sym_floor, 1, 2, 0.4 * sym_floor.pitch_px[1]) )).astype(np.int32)], 1)
    inside = cv2.erode(inside, np.ones((5, 5), np.uint8)) > 0
    assert np.abs(sym_img[inside].astype(int) - aru_img[inside].astype(int)).mean() < 3
    assert "aruco" in aru_truth.params["floor"]["layout"]


def test_aruco_layout_rejects_markers_that_do_not_fit():
    # turned 45 degrees, the symbol still fits its 80 px pitch, the marker's square with its
    # one-module quiet zone (90.5 px across) does not
    floor = FloorSpec(**FLOOR, layout="aruco", symbol_size=48, symbol_angle=45)
    with pytest.raises(SceneError, match="symbol_size: 48 px ArUco markers with their quiet zone overlap"):
        render_reference(floor)
    with pytest.raises(SceneError, match="markers"):
        marker_dictionary(1001)


def test_baselines_find_the_hidden_cell_and_only_it(floors):
    floor, ref, img, truth = floors["sym"]
    _, aref, aimg, atruth = floors["aru"]
    centres = truth.centres_px
    methods = [
        (ArucoGrid(aref, rows=floor.rows, cols=floor.cols), aref, aimg),
        (AbsDiff(ref, centres, box=floor.symbol_size), ref, img),
        (Mog2(ref, centres, box=floor.symbol_size, seed=1), ref, img),
    ]
    for method, reference, scene in methods:
        assert not method(reference).any(), type(method).__name__
        assert method(scene).tolist() == (truth.cells == 1).tolist(), type(method).__name__


def test_aruco_grid_ignores_a_marker_seen_far_from_its_place(floors):
    floor, aref, _, _ = floors["aru"]
    grid = ArucoGrid(aref, rows=floor.rows, cols=floor.cols)
    # swap the images of cells (0, 0) and (0, 1): both ids are found, each in the wrong place
    moved = aref.copy()
    dx = int(round(floor.col_x[1] - floor.col_x[0]))
    half = int(floor.symbol_size)
    x0, y0 = int(round(floor.col_x[0])) - half // 2 - 4, int(round(floor.row_y[0])) - half // 2 - 4
    a = aref[y0:y0 + half + 8, x0:x0 + half + 8].copy()
    b = aref[y0:y0 + half + 8, x0 + dx:x0 + dx + half + 8].copy()
    moved[y0:y0 + half + 8, x0:x0 + half + 8] = b
    moved[y0:y0 + half + 8, x0 + dx:x0 + dx + half + 8] = a
    occ = grid(moved)
    assert occ[0, 0] and occ[0, 1] and occ.sum() == 2


def test_footprints_are_ink_inside_each_cells_box(floors):
    floor, ref, _, truth = floors["sym"]
    flat, cell, counts = footprints(ref, truth.centres_px, box=floor.symbol_size)
    assert counts.shape == (floor.rows * floor.cols,) and (counts > 50).all()
    assert (ref.ravel()[flat] < 150).mean() > 0.6  # mostly ink (plus a 2-pixel rim)
    # the symbol's area (ink) is about the footprint's size
    area = floor.symbol_size ** 2
    assert (counts < area).all()


def test_baselines_reject_bad_input(floors):
    floor, ref, _, truth = floors["sym"]
    with pytest.raises(InputError, match="threshold"):
        AbsDiff(ref, truth.centres_px, box=floor.symbol_size, threshold=300)
    with pytest.raises(InputError, match="fraction"):
        AbsDiff(ref, truth.centres_px, box=floor.symbol_size, fraction=1.5)
    with pytest.raises(InputError, match="centres"):
        Mog2(ref, truth.centres_px[0], box=floor.symbol_size)
    with pytest.raises(InputError, match="image"):
        AbsDiff(ref, truth.centres_px, box=floor.symbol_size)(ref.astype(float))
    with pytest.raises(InputError, match="reference"):
        ArucoGrid(ref, rows=floor.rows, cols=floor.cols)  # the symbol floor has no markers
    with pytest.raises(InputError, match="max_offset"):
        ArucoGrid(floors["aru"][1], rows=floor.rows, cols=floor.cols, max_offset=2)


def test_bench_detect_runs_on_one_tiny_scene(tmp_path, capsys):
    png = tmp_path / "detect.png"
    args = ["bench", "detect", "--conditions", "clean", "--scenes", "1", "--size", "480x360", "--grid", "6x4",
            "--repeat", "1", "--slow-scenes", "0", "--plot", str(png)]
    assert main(args + ["--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    methods = {r["method"] for r in result["rows"]}
    assert {"sbplan default", "aruco-grid", "absdiff", "mog2", "sbplan matcher=hu-moments"} <= methods
    for r in result["rows"]:
        if r["method"] == "sbplan approximator=kka":
            assert r["frames"] == 0  # --slow-scenes 0 skips it
            continue
        assert r["frames"] == 1 and 0 <= r["f1"] <= 1 and r["median_ms"] > 0
        assert r["tp"] + r["fp"] + r["fn"] + r["tn"] > 0
    assert [c["condition"] for c in result["checks"]] == ["clean"]
    assert {"binarize", "extract", "match", "total"} <= set(result["stage_ms"])
    plot = load_image(png)
    assert plot.shape[:2] == (1000, 1600) and plot.std() > 10
    assert main(args[:-2] + ["--variants", "default"]) == 0
    out = capsys.readouterr().out
    assert "F1 (cells" in out and "aruco-grid" in out and "hu-moments" not in out


def test_bench_detect_bad_options(capsys):
    assert main(["bench", "detect", "--conditions", "fog"]) != 0
    assert "sbplan: error: --conditions" in capsys.readouterr().err
    assert main(["bench", "detect", "--conditions", "clean", "--scenes", "0"]) != 0
    assert "--scenes" in capsys.readouterr().err


def test_bench_detect_keeps_the_camera_warnings_out_of_its_output(capsys):
    # the camera conditions move the camera on purpose; the tables say by how much
    args = ["bench", "detect", "--conditions", "shift-8", "--scenes", "1", "--size", "480x360", "--grid", "6x4",
            "--repeat", "1", "--variants", "default"]
    assert main(args) == 0
    captured = capsys.readouterr()
    assert "camera moved" not in captured.err and "shift-8" in captured.out
    # ... and leaves the detector's logger as it found it
    assert not logging.getLogger("sbplan.detection.detector").filters


def test_the_movement_error_compares_the_movement_at_the_centre_on_both_sides():
    # A sagged camera's tilt shifts and turns the image's centre beyond the vibration's own
    # numbers; the truth's movement at the centre comes from its matrix, as the detection's does
    # (the sag condition read 0.0205 deg off while the registration was 0.0008 deg off).
    from sbplan.bench.detect import _motion_error
    from sbplan.bench.evaluation import condition_scenes
    from sbplan.detection import Detector
    from sbplan.detection.calibration import calibrate

    scenes = list(condition_scenes("sag", scenes=2, seed=0))
    detector = Detector(calibrate(scenes[0][0]))
    for _, image, truth in scenes:
        assert truth.params["camera"]["motion"]["sag_deg"]
        err_px, err_deg = _motion_error(detector.find_cells(image).camera, truth)
        assert err_px < 0.1 and err_deg < 0.005


def test_bench_detect_runs_on_another_symbol(capsys):
    args = ["bench", "detect", "--conditions", "clean", "--scenes", "1", "--size", "480x360", "--grid", "6x4",
            "--repeat", "1", "--variants", "default", "--symbol", "letter-p"]
    assert main(args + ["--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["setup"]["symbol"] == "letter-p"
    default = next(r for r in result["rows"] if r["method"] == "sbplan default")
    assert default["frames"] == 1 and default["error"] is None and default["tp"] + default["tn"] > 0
    assert main(args) == 0
    assert "rows of letter-p" in capsys.readouterr().out
    assert main(args[:-1] + ["letter-q"]) != 0
    err = capsys.readouterr().err
    assert "--symbol: unknown symbol 'letter-q'" in err and "letter-p" in err
