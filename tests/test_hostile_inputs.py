"""Garbage in gets a clear refusal, never a confident answer or a traceback (issue 21, items 4-11;
issue 18, item 6: one exit-code scheme, ``-v`` after the command).

Every CLI case runs in-process through ``sbplan.cli.main`` (a traceback would fail the test as
the exception it is) and writes only inside the test's folder.
"""

from __future__ import annotations

import base64
import json
import math
import struct
import zlib
from dataclasses import dataclass, replace

import cv2
import numpy as np
import pytest

from sbplan import registry
from sbplan.cli import main
from sbplan.contracts import Binarizer, DescriptorMatcher, OccupancyMapper, Planner
from sbplan.detection import Detector, exports
from sbplan.detection.calibration import calibrate, load_calibration
from sbplan.errors import (EXIT_CODES, CalibrationFileError, CameraMotionError, DetectionError, ImageError, InputError,
                           LimitError, MapFormatError, NoFloorError, StageError)
from sbplan.imageio import load_image, write_image
from sbplan.planning import load_obstacles, plan
from sbplan.synth import FloorSpec, SceneSpec, render_scene

from _small_floor import FLOOR, calibrated_floor


@pytest.fixture(scope="module")
def site(tmp_path_factory):
    """A calibrated floor on disk: reference, a scene with obstacles, calibration, result, nav2 map."""
    folder = tmp_path_factory.mktemp("site")
    cal = calibrated_floor(folder)
    image, truth = render_scene(FLOOR, SceneSpec(n_obstacles=2), seed=3)
    write_image(folder / "scene.png", image)
    detection = Detector(cal)(image)
    (folder / "result.json").write_text(json.dumps(detection.to_json()))
    exports.write_nav2(folder / "nav2", detection)
    return folder, cal, image, detection


def _run(capsys, *argv) -> tuple[int, str, str]:
    """``sbplan ARGV`` in this process: (exit code, stdout, stderr). argparse's own errors exit 2."""
    try:
        code = main([str(a) for a in argv])
    except SystemExit as exc:
        code = exc.code
    out = capsys.readouterr()
    return code, out.out, out.err


def _one_line_error(code: int, err: str, expected: int | None = None) -> None:
    assert code in EXIT_CODES and code not in (0, 1), (code, err)
    if expected is not None:
        assert code == expected, (code, err)
    assert "Traceback" not in err
    if code == 2 and err.startswith("usage:"):
        return  # argparse: usage, then one error line
    assert err.startswith("sbplan: error:") and err.count("\n") == 1, err


# -- item 4: the matcher decides -------------------------------------------------------------------
def test_a_calibration_threshold_that_matches_nothing_is_refused(site):
    _, cal, image, _ = site
    with pytest.raises(CameraMotionError, match="0 symbols found"):
        Detector(replace(cal, threshold=-1.0))(image)


@dataclass(kw_only=True, frozen=True)
class NanMatcher(DescriptorMatcher):
    name = "nan-matcher"

    def describe(self, points):
        return np.zeros(4)

    def distance_matrix(self, a, b):
        return np.full((len(a), len(b)), np.nan)


@dataclass(kw_only=True, frozen=True)
class RejectAll(DescriptorMatcher):
    """A matcher that rejects everything: every outline is equally far from the symbol."""

    name = "reject-all"

    def describe(self, points):
        return np.array([float(len(points)), 1.0])

    def distance_matrix(self, a, b):
        return np.full((len(a), len(b)), 1e3)


def test_a_matcher_returning_nan_is_named(site):
    _, cal, image, _ = site
    with pytest.raises(StageError, match=r"matcher 'nan-matcher' \(from .*test_hostile_inputs\).*NaN"):
        Detector(cal, matcher=NanMatcher())(image)


def test_a_registered_matcher_that_rejects_everything_is_seen(site):
    _, cal, image, _ = site
    reg = registry.registry()
    reg.add(RejectAll, origin="tests")
    try:
        with pytest.raises(CameraMotionError, match="0 symbols found"):
            Detector(cal, matcher="reject-all")(image)
    finally:
        reg.remove("matcher", "reject-all")


def test_symbols_found_counts_matches_only_and_the_edge_check_does_not_decide_alone(site):
    _, cal, image, detection = site
    free = int((~detection.occupied).sum())
    assert detection.symbols_found + detection.symbols_rescued == free
    data = detection.to_json()
    assert data["symbols_found"] == detection.symbols_found and data["symbols_rescued"] == detection.symbols_rescued
    fourier = type(cal.stage("matcher"))

    @dataclass(kw_only=True, frozen=True)
    class MostlyBlind(fourier):
        """The calibrated matcher (same name and options), blind to three symbols in four."""

        def distance_matrix(self, a, b):
            d = super().distance_matrix(a, b)
            d[np.arange(len(d)) % 4 != 0] += 10.0
            return d

    with pytest.raises(DetectionError, match="edge check would call"):
        Detector(cal, matcher=MostlyBlind(**cal.stage("matcher").config()))(image)


# -- item 5: wrong calibration, dead camera ---------------------------------------------------------
@pytest.mark.parametrize("frame, says", [
    ("white", "uniform"), ("black", "black"), ("noise", "noise"), ("dark", "very dark"), ("grey", "uniform")])
def test_frames_without_a_floor_are_refused_with_what_to_check(site, frame, says):
    _, cal, image, _ = site
    h, w = cal.image_shape
    frames = {"white": np.full((h, w), 255, np.uint8), "black": np.zeros((h, w), np.uint8),
              "noise": np.random.default_rng(0).integers(0, 256, (h, w)).astype(np.uint8),
              "dark": (image.astype(np.uint16) * 12 // 255).astype(np.uint8),
              "grey": np.full((h, w), 128, np.uint8)}
    with pytest.raises(NoFloorError, match=f"no floor in view.*{says}.*check"):
        Detector(cal)(frames[frame])


@pytest.mark.parametrize("other", [dict(cols=5, rows=3), dict(cols=7, rows=5), dict(symbol="letter-f")])
def test_another_floors_calibration_is_refused(site, other):
    _, cal, _, _ = site
    image, _ = render_scene(FloorSpec(width=480, height=360, **{"cols": 6, "rows": 4, **other}),
                            SceneSpec(n_obstacles=2), seed=3)
    with pytest.raises(CameraMotionError, match="another"):
        Detector(cal)(image)


def test_the_cli_refuses_a_dead_frame_with_exit_6(site, tmp_path, capsys):
    folder = site[0]
    write_image(tmp_path / "black.png", np.zeros((360, 480), np.uint8))
    code, out, err = _run(capsys, "detect", tmp_path / "black.png", "-c", folder / "cal.json")
    _one_line_error(code, err, 6)
    assert out == "" and "no floor in view" in err


# -- item 6: every calibration field is checked on load ----------------------------------------------
def _edit(data: dict, path: str, value) -> dict:
    data = json.loads(json.dumps(data))
    *parents, last = path.split(".")
    d = data
    for key in parents:
        d = d[int(key)] if isinstance(d, list) else d[key]
    if value is _DELETE:
        del d[last]
    elif isinstance(d, list):
        d[int(last)] = value
    else:
        d[last] = value
    return data


_DELETE = object()
_TINY_PNG = base64.b64encode(cv2.imencode(".png", np.zeros((3, 3), np.uint8))[1].tobytes()).decode()


@pytest.mark.parametrize("path, value, field", [
    ("symbol.threshold", float("nan"), "symbol.threshold"),
    ("symbol.threshold", float("inf"), "symbol.threshold"),
    ("symbol.threshold", -1.0, "symbol.threshold"),
    ("symbol.threshold", "0.1", "symbol.threshold"),
    ("symbol.outline_tolerance_px", float("inf"), "symbol.outline_tolerance_px"),
    ("symbol.area_px", 0, "symbol.area_px"),
    ("symbol.margin", float("nan"), "symbol.margin"),
    ("symbol.points_range", [50, 10], "symbol.points_range"),
    ("symbol.points_range", [1.5, 10], "symbol.points_range"),
    ("symbol.descriptor", [], "symbol.descriptor"),
    ("symbol.polygons", [[[0, 0], [1, 1]]], "symbol.polygons"),
    ("symbol.polygons.0.0", [float("nan"), 1.0], "symbol.polygons[0]"),
    ("symbol.holes", [[]], "symbol.holes"),
    ("symbol.holes", "none", "symbol.holes"),
    ("symbol.holes.0", [[[0, 0], [1, 1]]], "symbol.holes[0]"),
    ("symbol.inner_tolerance_px", [[1.0]], "symbol.inner_tolerance_px"),
    ("symbol.edge_contrast.0.0", float("nan"), "symbol.edge_contrast"),
    ("symbol.registration_centres_px", [[1.0, 2.0]], "symbol.registration_centres_px"),
    ("symbol.registration_centres_px.0.0.0", float("nan"), "symbol.registration_centres_px"),
    ("symbol.reference_thumbnail_png", "not base64 !", "symbol.reference_thumbnail_png"),
    ("symbol.reference_thumbnail_png", base64.b64encode(b"GIF89a....").decode(), "symbol.reference_thumbnail_png"),
    ("symbol.reference_thumbnail_png", _TINY_PNG, "symbol.reference_thumbnail_png"),
    ("grid.centres_px.0.0.0", float("nan"), "grid.centres_px"),
    ("grid.centres_px", [[1, 2]], "grid.centres_px"),
    ("grid.homography", [[0, 0, 0], [0, 0, 0], [0, 0, 1]], "grid.homography"),
    ("grid.tolerance_px", -3, "grid.tolerance_px"),
    ("grid.rows", 0, "grid.rows"),
    ("grid", [], "grid"),
    ("image_shape", [360, "x"], "image_shape"),
    ("image_shape", [0, 480], "image_shape"),
    ("stages.binarizer.options.window", -5, "stages.binarizer.options"),
    ("stages.matcher.name", 3, "stages.matcher.name"),
    ("stages.mapper", _DELETE, "stages.mapper"),
    ("workspace.robot_radius_m", float("nan"), "workspace"),
    ("workspace.pitch_m", [0.5, float("inf")], "workspace"),
    ("workspace.pitch_m", [1e308, 1e308], "workspace"),  # finite, but every world coordinate overflows
    ("workspace.origin_m", [-1e300, 0.0], "workspace"),
    ("other_polygons", {"a": 1}, "other_polygons"),
])
def test_every_calibration_field_is_checked_on_load(site, tmp_path, path, value, field):
    good = json.loads((site[0] / "cal.json").read_text())
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(_edit(good, path, value)))
    with pytest.raises(CalibrationFileError) as info:
        load_calibration(bad)
    message = str(info.value)
    assert message.startswith(f"{bad}: {field}"), message
    assert "\n" not in message


def test_calibration_files_that_are_not_calibrations(site, tmp_path, capsys):
    deep = tmp_path / "deep.json"
    deep.write_text("[" * 100_000 + "]" * 100_000)
    with pytest.raises(CalibrationFileError, match="deep.json: .*nested too deeply"):
        load_calibration(deep)
    huge = _edit(json.loads((site[0] / "cal.json").read_text()), "image_shape", [100000, 100000])
    (tmp_path / "huge.json").write_text(json.dumps(huge))
    with pytest.raises(LimitError, match="huge.json: image_shape 100000 x 100000"):
        load_calibration(tmp_path / "huge.json")
    listed = tmp_path / "list.json"
    listed.write_text("[1, 2]")
    with pytest.raises(CalibrationFileError, match="list.json: not an sbplan calibration"):
        load_calibration(listed)
    code, _, err = _run(capsys, "detect", site[0] / "scene.png", "-c", deep)
    _one_line_error(code, err, 3)


def test_automatic_stage_options_in_a_calibration_are_fitted_not_left_at_a_guess(site):
    # window 0 means "from the symbol size": the detector fits it as calibration does
    _, cal, image, detection = site
    stages = json.loads(json.dumps(cal.stages))
    stages["binarizer"]["options"]["window"] = 0
    auto = replace(cal, stages=stages)
    assert auto.stage("binarizer") == cal.stage("binarizer")
    np.testing.assert_array_equal(Detector(auto)(image).occupied, detection.occupied)


# -- item 7: no route through overflowed geometry ----------------------------------------------------
@pytest.mark.parametrize("big", [1e308, 1e200, 1e13])
def test_obstacles_beyond_the_planners_arithmetic_are_refused(big):
    ob = np.array([[1.0, 1.0], [2.0, 1.0], [big, 2.0], [1.0, 2.0]])
    for bounds in ((-1.0, -1.0, 5.0, 5.0), None):
        with pytest.raises(InputError, match="beyond"):
            plan([ob], (0.0, 0.0), (3.0, 3.0), robot_radius=0.1, bounds=bounds)


def test_slivers_too_thin_for_the_arithmetic_are_no_obstacles_and_thin_ones_are_kept():
    from sbplan.planning.geometry import as_polygons, enlarge

    import shapely

    kept = as_polygons([[[0.0, 0.0], [1.0, 0.0], [0.0, t]] for t in (1e-30, 1e-200, 1e-320)])
    assert len(kept) == 1  # GEOS's buffer of the thinner ones missed points within the radius
    with np.errstate(all="ignore"):  # GEOS divides by the sliver's thickness, and gets it right
        grown = enlarge(kept, 0.1)[0]
    assert all(grown.contains(shapely.Point(x, y)) for x in np.linspace(0, 1, 11) for y in (-0.099, 0.099))


def test_obstacles_far_beyond_small_bounds_are_refused_and_near_ones_planned():
    far = np.array([[1.0, 1.0], [2.0, 1.0], [1e11, 2.0], [1.0, 2.0]])
    with pytest.raises(InputError, match="double precision"):
        plan([far], (0.0, 0.0), (3.0, 3.0), robot_radius=0.1, bounds=(-1.0, -1.0, 5.0, 5.0))
    near = np.array([[1.0, 1.0], [2.0, 1.0], [1e6, 2.0], [1.0, 2.0]])
    route = plan([near], (0.0, 0.0), (3.0, 3.0), robot_radius=0.1, bounds=(-1.0, -1.0, 5.0, 5.0))
    import shapely

    assert route.status == "exact" and math.isfinite(route.length)
    assert not shapely.LineString(route.waypoints).intersects(shapely.Polygon(near).buffer(0.099))


# -- item 8: simple mistakes, one line each ------------------------------------------------------------
def test_simple_mistakes_give_one_line(site, tmp_path, capsys):
    folder = site[0]
    scene, cal = folder / "scene.png", folder / "cal.json"
    (tmp_path / "inf.yaml").write_text("image: map.pgm\nresolution: .inf\norigin: [0, 0, 0]\n")
    (tmp_path / "map.pgm").write_bytes((folder / "nav2" / "map.pgm").read_bytes())
    cases = [
        (["detect", scene, "-c", cal, "--nav2-resolution", "-1", "--nav2", tmp_path / "n"], 2),
        (["detect", scene, "-c", cal, "--nav2-resolution", "nan", "--nav2", tmp_path / "n"], 2),
        (["detect", scene, "-c", cal, "--nav2", folder / "result.json"], 4),
        (["detect", scene, "-c", cal, "-o", tmp_path], 4),
        (["plan", "--obstacles", folder / "result.json", "--start", "0.3,0.3", "--goal", "2.7,1.7", "--radius",
          "0.1", "--plot", tmp_path], 4),
        (["detect", scene, "-c", cal, "--overlay", tmp_path / "x.xyz"], 4),
        (["plan", "--obstacles", tmp_path / "inf.yaml", "--start", "0,0", "--goal", "1,1", "--radius", "0"], 3),
    ]
    for argv, expected in cases:
        code, _, err = _run(capsys, *argv)
        _one_line_error(code, err, expected)
    assert not (tmp_path / "n").exists()


# -- item 9: sizes are checked before the work, with limits that can be raised --------------------------
def _png_claiming(width: int, height: int) -> bytes:
    """A small PNG whose header says width x height (its data is one row): what a decompression
    bomb's header says, without the bomb."""
    ihdr = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    chunk = lambda kind, data: (struct.pack(">I", len(data)) + kind + data
                                + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF))
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(b"\0" * (width + 1)))
            + chunk(b"IEND", b""))


def test_huge_images_are_refused_from_their_header(tmp_path, capsys, monkeypatch):
    bomb = tmp_path / "bomb.png"
    bomb.write_bytes(_png_claiming(30000, 30000))
    with pytest.raises(LimitError, match="30000 x 30000 pixels.*SBPLAN_MAX_IMAGE_PIXELS"):
        load_image(bomb)
    code, _, err = _run(capsys, "calibrate", bomb, "-o", tmp_path / "c.json")
    _one_line_error(code, err, 9)
    # the limit is documented and can be lowered (or raised)
    small = tmp_path / "small.png"
    write_image(small, np.zeros((40, 50), np.uint8))
    monkeypatch.setenv("SBPLAN_MAX_IMAGE_PIXELS", "1000")
    with pytest.raises(LimitError, match="50 x 40"):
        load_image(small)
    with pytest.raises(LimitError):
        calibrate(np.zeros((40, 50), np.uint8))
    monkeypatch.setenv("SBPLAN_MAX_IMAGE_PIXELS", "lots")
    with pytest.raises(InputError, match="SBPLAN_MAX_IMAGE_PIXELS"):
        load_image(small)



def _bigtiff(image: np.ndarray) -> bytes:
    """An uncompressed 8-bit grey BigTIFF (OpenCV writes none): header, one IFD, one strip."""
    h, w = image.shape
    entries = [(256, 4, w), (257, 4, h), (258, 3, 8), (259, 3, 1), (262, 3, 1), (273, 16, 0), (277, 3, 1),
               (278, 4, h), (279, 16, h * w)]
    data_at = 16 + 8 + 20 * len(entries) + 8
    ifd = struct.pack("<Q", len(entries)) + b"".join(
        struct.pack("<HHQQ", tag, typ, 1, data_at if tag == 273 else value) for tag, typ, value in entries)
    return b"II+\x00" + struct.pack("<HHQ", 8, 0, 16) + ifd + struct.pack("<Q", 0) + image.tobytes()


def test_every_format_opencv_decodes_is_sized_from_its_header_before_decoding(tmp_path, monkeypatch):
    from sbplan.imageio import image_size

    grey = np.zeros((37, 53), np.uint8)
    grey[5:30, 7:40] = 200
    files = {"bigtiff.tif": _bigtiff(grey)}
    for ext in (".png", ".jpg", ".jp2", ".bmp", ".pbm", ".pgm", ".ppm", ".pam", ".pfm", ".sr", ".tif", ".webp",
                ".hdr", ".avif", ".gif"):
        image = cv2.merge([grey] * 3) if ext in (".ppm", ".gif", ".sr") else grey
        if ext in (".pfm", ".hdr"):
            image = cv2.merge([grey.astype(np.float32) / 255] * 3)
        try:
            ok, buf = cv2.imencode(ext, image)
        except cv2.error:
            continue  # no encoder in this OpenCV build: nothing of that format to test with
        if ok:
            files["image" + ext] = buf.tobytes()
    assert len(files) >= 12, sorted(files)
    for name, data in files.items():
        (tmp_path / name).write_bytes(data)
        assert image_size(data) == (53, 37), name
        assert load_image(tmp_path / name).shape == (37, 53), name
    # below the limit: refused from the header ("W x H pixels"), not after decoding ("decoded to")
    monkeypatch.setenv("SBPLAN_MAX_IMAGE_PIXELS", "1000")
    for name in files:
        with pytest.raises(LimitError, match=rf"{name}: 53 x 37 pixels"):
            load_image(tmp_path / name)
    monkeypatch.delenv("SBPLAN_MAX_IMAGE_PIXELS")
    # a GIF whose screen says 30000 x 30000 (a 1-pixel picture): refused before its 900 M pixels
    gif = bytearray(files["image.gif"])
    gif[6:10] = struct.pack("<HH", 30000, 30000)
    (tmp_path / "bomb.gif").write_bytes(bytes(gif))
    with pytest.raises(LimitError, match="bomb.gif: 30000 x 30000 pixels"):
        load_image(tmp_path / "bomb.gif")
    # a format whose size no header gives is not decoded at all (OpenEXR, unknown bytes)
    (tmp_path / "unknown.img").write_bytes(b"\x76\x2f\x31\x01" + bytes(60))
    with pytest.raises(ImageError, match="cannot read before decoding"):
        load_image(tmp_path / "unknown.img")

def test_a_huge_nav2_map_is_refused_before_it_is_made(site, tmp_path, capsys, monkeypatch):
    folder, _, _, detection = site
    with pytest.raises(LimitError, match="nav2 map of 300000 x 200000 pixels"):
        exports.nav2_map(detection, resolution=0.00001)
    code, _, err = _run(capsys, "detect", folder / "scene.png", "-c", folder / "cal.json", "--nav2",
                        tmp_path / "n", "--nav2-resolution", "0.00001")
    _one_line_error(code, err, 9)
    assert exports.nav2_map(detection)[0].shape == (40, 60)
    monkeypatch.setenv("SBPLAN_MAX_MAP_PIXELS", "100")  # the limit is the user's to set
    with pytest.raises(LimitError, match="SBPLAN_MAX_MAP_PIXELS"):
        exports.nav2_map(detection)


def test_a_noisy_occupancy_image_is_refused_not_merged_for_minutes(tmp_path, capsys, monkeypatch):
    noisy = tmp_path / "noisy.png"
    write_image(noisy, np.where(np.random.default_rng(1).random((120, 120)) < 0.3, 0, 255).astype(np.uint8))
    monkeypatch.setenv("SBPLAN_MAX_OBSTACLE_VERTICES", "2000")
    with pytest.raises(LimitError, match="runs of occupied pixels.*noisy"):
        load_obstacles(noisy)
    code, _, err = _run(capsys, "plan", "--obstacles", noisy, "--start", "1,1", "--goal", "100,100", "--radius", "1",
                        "--time-limit", "2")
    _one_line_error(code, err, 9)
    many = [np.array([[x, y], [x + 0.5, y], [x + 0.5, y + 0.5], [x, y + 0.5]]) for x in range(30) for y in range(30)]
    with pytest.raises(LimitError, match="4,500 vertices"):
        plan(many, (-1.0, -1.0), (31.0, 31.0), robot_radius=0.1)


# -- item 10: plugin stages that fail at run time are named ---------------------------------------------
@dataclass(kw_only=True, frozen=True)
class ExplodingBinarizer(Binarizer):
    name = "exploding"

    def binarize(self, gray):
        raise RuntimeError("out of film")


@dataclass(kw_only=True, frozen=True)
class NoneMatcher(DescriptorMatcher):
    name = "none-matcher"

    def describe(self, points):
        return np.zeros(4)

    def describe_many(self, outlines):
        return None

    def distance_matrix(self, a, b):
        return None


@dataclass(kw_only=True, frozen=True)
class StringMapper(OccupancyMapper):
    name = "string-mapper"

    def occupancy_image(self, grid, occupied, shape):
        return "occupied"


@dataclass(kw_only=True, frozen=True)
class EmptyBandsBinarizer(Binarizer):
    name = "empty-bands"

    def binarize(self, gray):
        return gray < 128

    def binarize_bands(self, gray, bands):
        return np.zeros(())


@dataclass(kw_only=True, frozen=True)
class NonePlanner(Planner):
    name = "none-planner"

    def solve(self, problem, *, time_limit=1.0):
        return None


@pytest.mark.parametrize("kind, stage, says", [
    ("binarizer", ExplodingBinarizer(), "failed in binarize.*RuntimeError: out of film"),
    ("binarizer", EmptyBandsBinarizer(), r"binarize_bands\(\) returned an array of shape \(\)"),
    ("matcher", NoneMatcher(), r"describe_many\(\) returned None"),
    ("mapper", StringMapper(), r"occupancy_image\(\) returned a str"),
])
def test_detection_stages_that_fail_are_named(site, kind, stage, says):
    _, cal, image, _ = site
    with pytest.raises(StageError, match=f"{kind} '{stage.name}' \\(from .*\\).*{says}"):
        Detector(cal, **{kind: stage})(image)


def test_a_planner_returning_none_and_a_registered_stage_name_their_plugin(site, tmp_path, capsys):
    with pytest.raises(StageError, match=r"planner 'none-planner' .*solve\(\) returned None, expected a Route"):
        plan([], (0.0, 0.0), (1.0, 1.0), robot_radius=0.1, bounds=(0, 0, 2, 2), planner=NonePlanner())
    folder = site[0]
    reg = registry.registry()
    reg.add(ExplodingBinarizer, origin="film-plugin")
    try:
        code, _, err = _run(capsys, "detect", folder / "scene.png", "-c", folder / "cal.json",
                            "--binarizer", "exploding")
        _one_line_error(code, err, 8)
        assert "binarizer 'exploding' (from film-plugin) failed in binarize" in err
        code, _, err = _run(capsys, "calibrate", folder / "reference.png", "-o", tmp_path / "c.json",
                            "--binarizer", "exploding")
        _one_line_error(code, err, 8)
        assert "(from film-plugin)" in err
    finally:
        reg.remove("binarizer", "exploding")


# -- item 11: smaller ones ----------------------------------------------------------------------------
def test_nav2_images_stay_in_their_folder_and_values_are_checked(site, tmp_path, capsys):
    pgm = (site[0] / "nav2" / "map.pgm").read_bytes()
    (tmp_path / "outside.pgm").write_bytes(pgm)
    maps = tmp_path / "maps"
    maps.mkdir()
    (maps / "map.pgm").write_bytes(pgm)
    head = "resolution: 0.05\norigin: [0, 0, 0]\n"
    cases = {
        "image: ../outside.pgm\n" + head: "outside the map's folder",
        f"image: {tmp_path / 'outside.pgm'}\n" + head: "outside the map's folder",
        "image: map.pgm\n" + head + "negate: 2\n": "negate must be 0 or 1",
        "image: map.pgm\n" + head + "occupied_thresh: .nan\n": "occupied_thresh must be a finite number",
        "image: map.pgm\n" + head + "free_thresh: 0.9\n": "free_thresh < occupied_thresh",
        "image: map.pgm\n" + head + "mode: weird\n": "mode must be trinary, scale or raw",
        "image: map.pgm\nresolution: 0.05\norigin: [0, .inf, 0]\n": "origin must be a finite number",
        "{{{: [\n": "not valid YAML",
        "just some words\n": "not a nav2 map.yaml",
        "colour: blue\n": "not a nav2 map.yaml",
    }
    for text, says in cases.items():
        (maps / "map.yaml").write_text(text)
        with pytest.raises(MapFormatError, match=says):
            load_obstacles(maps / "map.yaml")
    (maps / "map.yaml").write_text("image: ../outside.pgm\n" + head)
    assert load_obstacles(maps / "map.yaml", image_anywhere=True).bounds is not None
    code, _, err = _run(capsys, "plan", "--obstacles", maps / "map.yaml", "--start", "0.1,0.1", "--goal", "0.2,0.2",
                        "--radius", "0")
    _one_line_error(code, err, 3)


def test_negative_coordinates_a_map_file_for_the_tui_and_plan_on_loaded_obstacles(site, capsys):
    folder = site[0]
    code, out, err = _run(capsys, "plan", "--obstacles", folder / "result.json", "--start", "-5,-5", "--goal",
                          "1,1", "--radius", "0.1")
    _one_line_error(code, err, 7)
    assert "start (-5, -5) is outside the workspace" in err
    code, _, err = _run(capsys, "tui", folder / "cal.json")
    _one_line_error(code, err, 3)
    assert "is a file; 'sbplan tui' takes a map folder" in err
    obstacles = load_obstacles(folder / "result.json")
    route = plan(obstacles, (1.8, 0.2), (2.8, 1.8), robot_radius=0.05)
    assert route.status == "exact" and route.map.bounds == obstacles.bounds
    with pytest.raises(InputError, match="obstacles: expected a list of polygons"):
        plan(3, (1.8, 0.2), (2.8, 1.8), robot_radius=0.05)


# -- issue 18, item 6: one exit-code scheme; -v after the command -------------------------------------
def test_exit_codes_follow_one_scheme(site, tmp_path, capsys):
    folder = site[0]
    scene, cal = folder / "scene.png", folder / "cal.json"
    cases = [
        (["detect", tmp_path / "missing.png", "-c", cal], 3),
        (["detect", scene, "-c", tmp_path / "missing.json"], 3),
        (["detect", scene, "-c", cal, "--matcher", "nope"], 8),
        (["detect", scene, "-c", cal, "-o", tmp_path], 4),
        (["calibrate", tmp_path / "blank.png", "-o", tmp_path / "c.json"], 5),
        (["plan", "--obstacles", folder / "result.json", "--start", "0.75,1.0", "--goal", "2.8,1.8",
          "--radius", "0.1"], 7),
        (["plan", "--obstacles", folder / "result.json", "--start", "0.2,0.2", "--goal", "0.3,0.3",
          "--radius", "nan"], 2),
        (["detect", scene], 2),
    ]
    write_image(tmp_path / "blank.png", np.full((120, 160), 200, np.uint8))
    for argv, expected in cases:
        code, _, err = _run(capsys, *argv)
        _one_line_error(code, err, expected)


def test_verbose_after_the_command_shows_the_traceback(site, tmp_path, capsys):
    scene = site[0] / "scene.png"
    for argv in (["-v", "detect", scene, "-c", tmp_path / "missing.json"],
                 ["detect", "-v", scene, "-c", tmp_path / "missing.json"],
                 ["detect", scene, "-c", tmp_path / "missing.json", "-v"]):
        code, _, err = _run(capsys, *argv)
        assert code == 3 and "Traceback" in err and err.rstrip().endswith("no such calibration file"), argv
    code, _, err = _run(capsys, "symbols", "show", "nope", "-v")
    assert code != 0 and "Traceback" in err


# -- bad-input lists: 0 tracebacks ---------------------------------------------------------------------
def test_bad_input_lists_for_calibrate_detect_and_plan(site, tmp_path, capfd):
    # capfd, not capsys: what native libraries print on descriptor 2 (libpng) counts as a line too
    capsys = capfd
    folder = site[0]
    scene, cal, result, ref = folder / "scene.png", folder / "cal.json", folder / "result.json", folder / "reference.png"
    junk = tmp_path / "junk.png"
    junk.write_bytes(b"\x89PNG\r\n\x1a\n not really")
    damaged = tmp_path / "damaged.png"  # a true header, then a broken zlib stream: libpng speaks
    damaged.write_bytes(_png_claiming(48, 36)[:33] + struct.pack(">I", 7) + b"IDATgarbage" + bytes(4))
    empty = tmp_path / "empty.json"
    empty.write_text("")
    small = tmp_path / "small.png"
    write_image(small, np.zeros((36, 48), np.uint8))
    toml = tmp_path / "workspace.toml"
    toml.write_text("[grid]\npitch_m = 'wide'\n")
    bad_ws = tmp_path / "ws.toml"
    bad_ws.write_text("[robot]\nradius_m = 'x'\n[grid]\npitch_m = 1\n")
    lists = {
        "calibrate": [
            [ref], [ref, "-o", tmp_path / "c.json", "--cell-size", "-1"], [ref, "-o", tmp_path / "c.json", "--cell-size", "nan"],
            [ref, "-o", tmp_path / "c.json", "--cell-size", "1e308"],
            [junk, "-o", tmp_path / "c.json"], [tmp_path, "-o", tmp_path / "c.json"], [small, "-o", tmp_path / "c.json"],
            [ref, "-o", tmp_path / "c.json", "--workspace", toml], [ref, "-o", tmp_path / "c.json", "--workspace", bad_ws],
            [ref, "-o", tmp_path / "c.json", "--symbol", junk], [ref, "-o", tmp_path / "c.json", "--matcher", "x"],
            ["--update", empty, scene], ["--update", cal, small], ["--update", cal, scene, "--cell-size", "1"],
        ],
        "detect": [
            [scene, "-c", empty], [scene, "-c", junk], [junk, "-c", cal], [damaged, "-c", cal], [small, "-c", cal], [scene, "-c", tmp_path],
            [scene, "-c", cal, "--nav2-resolution", "inf", "--nav2", tmp_path / "n"],
            [scene, "-c", cal, "--nav2-resolution", "0", "--nav2", tmp_path / "n"],
            [scene, "-c", cal, "--geojson", tmp_path], [scene, "-c", cal, "--binarizer", "nope"],
            [scene, "-c", cal, "--nav2-resolution", "x"],
        ],
        "plan": [
            ["--obstacles", empty, "--start", "0,0", "--goal", "1,1", "--radius", "0"],
            ["--obstacles", junk, "--start", "0,0", "--goal", "1,1", "--radius", "0"],
            ["--obstacles", result, "--start", "0,0", "--goal", "1,1", "--radius", "-1"],
            ["--obstacles", result, "--start", "0,0", "--goal", "1,1", "--radius", "0", "--time-limit", "-1"],
            ["--obstacles", result, "--start", "0,0", "--goal", "1,1", "--radius", "0", "--margin", "inf"],
            ["--obstacles", result, "--start", "0", "--goal", "1,1", "--radius", "0"],
            ["--obstacles", result, "--start", "nan,0", "--goal", "1,1", "--radius", "0"],
            ["--obstacles", result, "--start", "1e308,0", "--goal", "1,1", "--radius", "0"],
            ["--obstacles", result, "--start", "0.1,0.1", "--goal", "1,1", "--radius", "0", "--planner", "x"],
            ["--obstacles", result, "--start", "0.1,0.1", "--goal", "1,1", "--radius", "0", "--use", "x"],
            ["--obstacles", small, "--start", "0,0", "--goal", "1,1", "--radius", "0", "--resolution", "-2"],
            ["--obstacles", result, "--start", "0,0", "--goal", "1,1", "--radius", "0", "--resolution", "nan"],
            ["--obstacles", result, "--start", "0.1,0.1", "--goal", "1,1", "--radius", "1e308"],
            ["--obstacles", result, "--start", "0.1,0.1", "--goal", "1,1", "--radius", "0", "--margin", "1e308"],
            ["--obstacles", tmp_path / "none.geojson", "--start", "0,0", "--goal", "1,1", "--radius", "0"],
        ],
    }
    for command, argvs in lists.items():
        for argv in argvs:
            code, _, err = _run(capsys, command, *argv)
            _one_line_error(code, err)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["damaged.png", "empty.json", "junk.png", "small.png",
                                                          "workspace.toml", "ws.toml"]


# -- the service: the same garbage over HTTP gets a 4xx with a code, never a 500 ----------------------
def test_bad_input_list_for_the_service():
    pytest.importorskip("fastapi")
    pytest.importorskip("httpx")
    from _service import MAP, SCENE_PNG, START, GOAL, client, png, running

    from sbplan.detection import calibrate as calibrate_map

    cal = calibrate_map(str(MAP / "reference.png"), workspace=str(MAP))
    h, w = cal.image_shape
    frames = {"black": np.zeros((h, w), np.uint8), "white": np.full((h, w), 255, np.uint8),
              "noise": np.random.default_rng(0).integers(0, 256, (h, w)).astype(np.uint8)}
    with running(cal) as (url, _), client(url) as http:
        for name, frame in frames.items():
            r = http.post("/detect", content=png(frame))
            assert r.status_code == 422 and r.json()["code"] == "no-floor", (name, r.text)
            assert "no floor in view" in r.json()["message"]
        assert http.post("/detect", content=SCENE_PNG).status_code == 200
        requests = [
            {"start": [1e308, 0.0], "goal": GOAL},
            {"start": START, "goal": GOAL, "robot_radius": 1e308},
            {"start": START, "goal": GOAL, "margin": 1e300},
            {"start": START, "goal": GOAL, "robot_radius": 1e-320},
        ]
        for body in requests:
            r = http.post("/routes", json=body)
            assert r.status_code < 500 and "\n" not in r.json().get("message", r.text), (body, r.text)
        route = http.post("/routes", json={"start": START, "goal": GOAL}).json()
        for obstacle in ([[0, 0], [1e308, 0], [0, 1]], [[0, 0], [1e200, 1], [1, 1e200]], [[0, 0], [1, 0], [0, 1e-320]]):
            r = http.post(f"/routes/{route['id']}/replan", json={"position": START, "obstacle": obstacle})
            assert r.status_code < 500, (obstacle, r.text)
        assert http.get("/state").json()["frame"] == 1
