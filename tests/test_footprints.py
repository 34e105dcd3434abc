"""Obstacle footprints and obstacle models (issue 15), on the real renderer: two obstacles touching
at a corner can be planned around with every interface's default, the route keeps off the true
obstacles, every output shows the polygons the planner used, shadows and light do not grow
footprints, and old calibrations fall back to the cells."""

from __future__ import annotations

import json
import subprocess
import sys

import cv2
import numpy as np
import pytest
import shapely
import shapely.affinity
from shapely.geometry import LineString, Point, Polygon

import sbplan
from sbplan.bench.evaluation import FootprintScores, score_footprints
from sbplan.detection import Detector, exports
from sbplan.detection.calibration import Calibration, calibrate
from sbplan.detection.footprints import cell_outlines
from sbplan.detection.obstacles import DEFAULT_OBSTACLE_MODEL, OBSTACLE_MODELS, PARTS_RATIO, split_parts
from sbplan.errors import InputError, MapFormatError, StartInObstacleError
from sbplan.imageio import write_json
from sbplan.planning import PlanningMap, load_obstacles
from sbplan.synth import FloorSpec, SceneSpec, render_reference, render_scene
from sbplan.workspace import Workspace

FLOOR = FloorSpec(width=640, height=480, cols=8, rows=6)
RADIUS = 0.1  # metres; the pitch is 0.5 m = 80 px


@pytest.fixture(scope="module")
def calibration() -> Calibration:
    return calibrate(render_reference(FLOOR, seed=0), workspace=Workspace(pitch_m=(0.5, 0.5), robot_radius_m=RADIUS))


@pytest.fixture(scope="module")
def corner(calibration):
    """Two 1.5-pitch squares touching at one corner (a labelled box and a striped one), and a start
    and a goal in the free floor of the two notches beside them."""
    side = 1.5 * FLOOR.pitch_px[0]
    x0, y0 = FLOOR.col_x[1] - 0.3 * side / 1.5, FLOOR.row_y[1] - 0.3 * side / 1.5
    a = np.array([[x0, y0], [x0 + side, y0], [x0 + side, y0 + side], [x0, y0 + side]])
    image, truth = render_scene(FLOOR, SceneSpec(obstacles=[a, a + side]), seed=4)
    start_px = np.array([x0 + 1.5 * side, y0 + 0.5 * side])
    goal_px = np.array([x0 + 0.5 * side, y0 + 1.5 * side])
    start, goal = calibration.pixels_to_world(np.stack([start_px, goal_px]))
    return image, truth, Detector(calibration)(image), tuple(start), tuple(goal)


def _keeps_off(route_m, truth, calibration) -> float:
    """The route's least distance (pixels) to the true obstacles' outlines, 0 when it enters one."""
    line = LineString(calibration.world_to_pixels(np.asarray(route_m)))
    return min(line.distance(Polygon(p)) for p in truth.obstacles)


def test_the_default_model_is_parts_everywhere():
    import argparse

    from sbplan.commands import demo, detect, plan

    assert DEFAULT_OBSTACLE_MODEL == "parts" and OBSTACLE_MODELS == ("mar", "parts", "outline")
    for command in (detect, plan, demo):
        parser = argparse.ArgumentParser()
        command.add_arguments(parser)
        known = {a.dest: a for a in parser._actions}
        assert known["obstacle_model"].default == "parts" and tuple(known["obstacle_model"].choices) == OBSTACLE_MODELS


def test_touching_obstacles_are_planned_around_with_the_defaults(corner, calibration, tmp_path):
    image, truth, detection, start, goal = corner
    # one footprint for both squares (they touch), cut into parts that leave the notches free
    assert len(detection.obstacles) == 1 and len(detection.obstacles[0].parts_m) >= 2
    radius_px = RADIUS * FLOOR.pitch_px[0] / 0.5
    # the API's default
    route = sbplan.plan(detection, start, goal, robot_radius=RADIUS)
    assert route.status == "exact"
    assert _keeps_off(route.waypoints, truth, calibration) > 0.75 * radius_px
    # ... and the outline model's
    outline = sbplan.plan(detection, start, goal, robot_radius=RADIUS, obstacle_model="outline")
    assert _keeps_off(outline.waypoints, truth, calibration) > 0.75 * radius_px
    # the paper's MAR of the two squares covers the notches: what the parts model is for
    with pytest.raises(StartInObstacleError):
        sbplan.plan(detection, start, goal, robot_radius=RADIUS, obstacle_model="mar")
    # the CLI's default, from the result file
    write_json(tmp_path / "result.json", detection.to_json())
    out = subprocess.run([sys.executable, "-m", "sbplan", "plan", "--obstacles", str(tmp_path / "result.json"),
                          "--start", "{},{}".format(*start), "--goal", "{},{}".format(*goal),
                          "--radius", str(RADIUS), "--json"], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    cli = json.loads(out.stdout)
    assert cli["length"] == pytest.approx(route.length, abs=1e-5)
    assert _keeps_off(cli["waypoints"], truth, calibration) > 0.75 * radius_px
    # the TUI's default (its session plans what the route screen shows)
    from sbplan.tui.session import Session

    session = Session(calibration=calibration, detection=detection, start=start, goal=goal)
    assert session.obstacle_model == "parts"
    assert session.plan().length == pytest.approx(route.length, abs=1e-9)


def test_outputs_show_the_polygons_the_planner_used(corner, calibration, tmp_path):
    image, truth, detection, start, goal = corner
    for model in OBSTACLE_MODELS:
        planned = [Polygon(p) for p in detection.planner_obstacles(model)]
        pmap = PlanningMap(planned, robot_radius=RADIUS, bounds=calibration.world_bounds())
        want = shapely.union_all(pmap.obstacles)
        # GeoJSON: the same polygons, read back as the planner reads them
        exports.write_geojson(tmp_path / f"{model}.geojson", detection, model)
        got = load_obstacles(tmp_path / f"{model}.geojson").polygons
        assert len(got) == len(planned)
        assert shapely.union_all(got).symmetric_difference(want).area < 1e-5  # the file rounds to 1e-6 m
        # nav2: every map pixel they reach into is occupied, and no other
        exports.write_nav2(tmp_path / model, detection, model=model)
        nav2 = load_obstacles(tmp_path / model / "map.yaml")
        assert want.difference(shapely.union_all(nav2.polygons)).area < 1e-9
        pgm = cv2.imread(str(tmp_path / model / "map.pgm"), cv2.IMREAD_UNCHANGED)
        res = min(calibration.workspace.pitch_m) / 10
        rows, cols = np.nonzero(pgm == 0)
        x0, y0 = nav2.bounds[0] + cols * res, nav2.bounds[1] + (pgm.shape[0] - 1 - rows) * res
        pixels = shapely.box(x0, y0, x0 + res, y0 + res)
        assert len(pixels) and (shapely.area(shapely.intersection(pixels, want)) > 1e-6 * res * res).all()
        # overlay: the planner's polygons and clearance, drawn through the grid
        rings, clearance = exports.overlay_polygons(detection, model)
        assert len(rings) == len(pmap.obstacles)
        cam = detection.camera  # the overlay draws in the frame: back to the calibration's pixels, then metres
        for ring, poly in zip(rings, pmap.obstacles):
            back = Polygon(calibration.pixels_to_world(cam.to_calibration(ring)))
            assert back.symmetric_difference(poly).area < 1e-9
        zone = shapely.union_all([Polygon(calibration.pixels_to_world(cam.to_calibration(r))) for r in clearance])
        floor = shapely.box(*calibration.world_bounds())
        assert zone.symmetric_difference(shapely.union_all(pmap.enlarged).intersection(floor)).area < 1e-9
        picture = exports.overlay_image(image, detection, model, caption=False)  # the frame's pixels only
        yellow = cv2.inRange(picture, (0, 200, 235), (40, 240, 255)) > 0
        for ring in rings:  # the yellow line runs along every polygon's edges
            edge = np.concatenate([np.linspace(p, q, 20) for p, q in zip(ring, np.roll(ring, -1, axis=0))])
            ij = np.clip(np.rint(edge).astype(int), 0, [FLOOR.width - 1, FLOOR.height - 1])
            near = cv2.dilate(yellow.astype(np.uint8), np.ones((3, 3), np.uint8)) > 0
            assert near[ij[:, 1], ij[:, 0]].mean() > 0.9


def test_a_detection_is_planned_on_only_with_a_model_name(corner):
    _, _, detection, start, goal = corner
    with pytest.raises(InputError, match="obstacle_model"):
        detection.planner_obstacles("hull")
    with pytest.raises(InputError, match="only a Detection"):
        sbplan.plan([np.zeros((3, 2)) + [[0, 0], [1, 0], [0, 1]]], (2, 2), (3, 3), robot_radius=0.1,
                     obstacle_model="mar")


def test_shadows_and_light_do_not_grow_footprints(calibration):
    """The same obstacles (same seeds) under base light, cast shadows and a light gradient: the
    footprints' area outside the true obstacles stays what it is under base light."""
    floor = FloorSpec(width=800, height=600, cols=8, rows=5)
    cal = calibrate(render_reference(floor, seed=0))
    detector = Detector(cal)
    extra = {}
    for condition in ("clean", "shadows", "gradient"):
        total = FootprintScores()
        for seed in range(1, 7):
            image, truth = render_scene(floor, SceneSpec(n_obstacles=3, condition=condition), seed=seed)
            total = total + score_footprints(detector(image), truth)
        extra[condition] = (total.reported_px - total.found_px) / total.true_px
        assert total.recall > 0.95, condition
    assert extra["clean"] < 0.3
    assert extra["shadows"] <= extra["clean"] + 0.03, extra
    assert extra["gradient"] <= extra["clean"] + 0.03, extra


def test_footprints_are_tighter_than_cells(corner, calibration):
    image, truth, detection, _, _ = corner
    cells = Detector(calibration, footprint="cells")(image)
    pixels = score_footprints(detection, truth)
    paper = score_footprints(cells, truth)
    assert pixels.recall > 0.98 and pixels.recall >= paper.recall
    assert pixels.area_ratio < 1.3 < paper.area_ratio
    assert pixels.swallowed["parts"] == 0 < paper.swallowed["mar"]


def test_the_nav2_map_marks_exactly_the_pixels_an_obstacle_reaches_into():
    """nav2_pixels against the plain definition (every pixel square's overlap, one by one): a
    rectangle on pixel edges, a rotated one, a concave outline and one past the map's border."""
    res, shape, origin = 0.05, (40, 60), (-0.5, 1.0)
    rng = np.random.default_rng(3)
    star = [(np.cos(t) * r, np.sin(t) * r) for t, r in zip(np.linspace(0, 2 * np.pi, 14, endpoint=False),
                                                            rng.uniform(0.2, 0.6, 14))]
    polygons = [np.array([[0.0, 1.5], [0.5, 1.5], [0.5, 2.0], [0.0, 2.0]]),
                np.asarray(shapely.affinity.rotate(shapely.box(1.0, 1.3, 1.73, 1.61), 27).exterior.coords)[:-1],
                np.array(star) + (1.4, 2.4), np.array([[2.2, 2.6], [2.8, 2.9], [2.3, 3.3]])]
    rows, cols = np.mgrid[:shape[0], :shape[1]]
    x0, y0 = origin[0] + cols * res, origin[1] + (shape[0] - 1 - rows) * res
    squares = shapely.box(x0, y0, x0 + res, y0 + res)
    for p in polygons:
        got = exports.nav2_pixels([p], shape=shape, resolution=res, origin=origin)
        want = shapely.area(shapely.intersection(squares, Polygon(p))) > 1e-6 * res * res
        assert got.any() and (got == want).all()
    # the one on pixel edges: its 10 x 10 pixels, not one more
    assert exports.nav2_pixels(polygons[:1], shape=shape, resolution=res, origin=origin).sum() == 100


def test_old_calibrations_fall_back_to_the_cells(corner, calibration):
    image = corner[0]
    data = calibration.to_json()
    del data["symbol"]["reference_thumbnail_png"]
    del data["stages"]["footprint"]  # written before the footprint stage existed
    old = Calibration.from_json(data)
    detector = Detector(old)
    assert detector.stage_names["footprint"] == "cells"
    result = detector(image)
    cells = Detector(calibration, footprint="cells")(image)
    assert [o.outline_px.tolist() for o in result.obstacles] == [o.outline_px.tolist() for o in cells.obstacles]
    assert result.to_json()["stages"]["footprint"] == "cells"


def test_every_occupied_cell_keeps_an_obstacle(calibration):
    """A footprint stage that finds nothing: detection still reports every occupied cell."""
    from sbplan.contracts import FootprintRefiner

    class Nothing(FootprintRefiner):
        name = "test-nothing"
        description = "finds no outline at all"

        def outlines(self, gray, occupied, occupancy, calibration, camera, prepared):
            return []

    image, _ = render_scene(FLOOR, SceneSpec(n_obstacles=2), seed=2)
    result = Detector(calibration, footprint=Nothing())(image)
    assert sorted(c for o in result.obstacles for c in o.cells) == result.occupied_cells
    want = shapely.union_all([Polygon(o) for o in cell_outlines(result.occupancy)])
    got = shapely.union_all([Polygon(o.outline_px) for o in result.obstacles])
    assert got.symmetric_difference(want).area < 0.02 * want.area


def test_parts_cover_the_outline_within_the_ratio():
    square = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
    # a traced outline of two squares touching at a corner passes the corner twice
    corner_touch = np.array([[0, 0], [1, 0], [1, 1], [2, 1], [2, 2], [1, 2], [1, 1], [0, 1]], float)
    ell = np.array([[0, 0], [3, 0], [3, 1], [1, 1], [1, 3], [0, 3]], float)
    t = np.linspace(0, 2 * np.pi, 90, endpoint=False)
    ring = Polygon(np.c_[2 * np.cos(t), 2 * np.sin(t)], [np.c_[np.cos(t), np.sin(t)][::-1]])
    for shape, most in ((corner_touch, 2), (ell, 3), (square, 1),
                        (np.c_[np.cos(t), np.sin(t)], 1)):
        outline = shapely.make_valid(Polygon(shape))
        parts = split_parts(shape)
        assert 1 <= len(parts) <= most
        covered = shapely.union_all([Polygon(p) for p in parts])
        # (OpenCV fits the rectangles in float32: they hold the outline to 1e-7 of its size)
        assert outline.difference(covered).area < 1e-6 * outline.area
        assert sum(Polygon(p).area for p in parts) <= PARTS_RATIO * outline.area
    # a ring's outline is its outer circle: planning treats the hole as inside
    assert len(split_parts(np.asarray(ring.exterior.coords)[:-1])) == 1


def test_json_results_without_parts_are_cut_on_reading(corner, tmp_path):
    _, _, detection, _, _ = corner
    data = detection.to_json()
    for ob in data["obstacles"]:
        del ob["parts_m"]
    write_json(tmp_path / "old.json", data)
    got = load_obstacles(tmp_path / "old.json").polygons
    want = [Polygon(p) for p in detection.planner_obstacles("parts")]
    # cut again from the outline rounded to a micrometre: the cuts may move by as much
    assert shapely.union_all(got).symmetric_difference(shapely.union_all(want)).area < 1e-3 * shapely.union_all(want).area
    with pytest.raises(MapFormatError, match="obstacle_model"):
        load_obstacles(tmp_path / "old.json", obstacle_model="hull")


def test_a_moved_camera_keeps_its_footprints():
    """The same obstacles with the camera unmoved and moved by a fraction of a pixel and a small
    turn: the footprints hold as much of the obstacles (the frame is read in the calibration's
    geometry at its full resolution, not from blocks interpolated into it)."""
    floor = FloorSpec(width=800, height=600, cols=8, rows=5)
    cal = calibrate(render_reference(floor, seed=0))
    recall = {}
    for motion in (None, (0.7, -0.7, 0.0, 1.0), (0.0, 0.0, 0.5, 1.0)):
        detector, total = Detector(cal), FootprintScores()
        for seed in range(1, 5):
            effects = {} if motion is None else {"motion": motion}
            image, truth = render_scene(floor, SceneSpec(n_obstacles=3, effects=effects), seed=seed)
            total = total + score_footprints(detector(image), truth)
        recall[motion] = total.recall
    still = recall.pop(None)
    assert all(r >= still - 0.002 for r in recall.values()), (still, recall)


def test_the_moved_frame_is_read_as_its_full_resolution_warp():
    """The moved frame's blocks (box means sampled where the blocks moved) are the block means of
    the frame warped at its full resolution: exactly under a translation, within a grey level
    under the camera's small turns and zooms."""
    from sbplan.detection.footprints import _in_calibration
    from sbplan.detection.registration import CameraMotion

    rng = np.random.default_rng(3)
    gray = cv2.GaussianBlur((rng.random((240, 320)) * 255).astype(np.uint8), (0, 0), 1.5)
    gray = cv2.normalize(gray, None, 0, 255, cv2.NORM_MINMAX)
    box = (3, 4, 70, 52)  # small pixels: x0, y0, x1, y1
    for angle, scale, tol in ((0.0, 1.0, 1e-3), (0.5, 1.01, 1.0)):
        m = cv2.getRotationMatrix2D((160.0, 120.0), angle, scale)
        m[:, 2] += (0.7, -0.4)
        camera = CameraMotion(np.vstack([m, (0, 0, 1)]), (0.7, -0.4), angle, scale, 0.0, 0, 1.0, "similarity")
        x0, y0, x1, y1 = box
        shift = np.array([[1.0, 0, 4 * x0], [0, 1.0, 4 * y0], [0, 0, 1.0]])
        full = cv2.warpAffine(gray.astype(np.float32), (camera.matrix @ shift)[:2], (4 * (x1 - x0), 4 * (y1 - y0)),
                              flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP, borderMode=cv2.BORDER_REPLICATE)
        blocks = full.reshape(y1 - y0, 4, x1 - x0, 4).mean(axis=(1, 3))
        got = _in_calibration(gray, camera, 4, box)
        assert got.shape == blocks.shape
        assert np.abs(got - blocks).max() < tol, (angle, np.abs(got - blocks).max())


def _supported_by_box_filters(region, occ, floor, frame, log_reference, texture, share):
    """The support test as first written: the light box-filtered over the whole box around the
    pieces (the pieces' pixels only are now summed, from integral images)."""
    from sbplan.detection.footprints import CHANGE_LEVEL, TEXTURE_SEED

    outside = region & ~occ
    bx, by, bw, bh = cv2.boundingRect(outside.view(np.uint8))
    h, w = region.shape
    y0, y1, x0, x1 = max(by - 15, 0), min(by + bh + 15, h), max(bx - 15, 0), min(bx + bw + 15, w)
    box = (slice(y0, y1), slice(x0, x1))
    ratio = cv2.log(np.maximum(frame[box], np.float32(1))) - log_reference[box]
    weight = floor[box].astype(np.float32)
    light = cv2.blur(ratio * weight, (31, 31), borderType=cv2.BORDER_CONSTANT) \
        / np.maximum(cv2.blur(weight, (31, 31), borderType=cv2.BORDER_CONSTANT), np.float32(1e-3))
    changed = (np.abs(ratio - light) > CHANGE_LEVEL) | (texture[box] > TEXTURE_SEED)
    n, labels = cv2.connectedComponents(outside[box].astype(np.uint8), connectivity=8)
    drop = np.bincount(labels[changed], minlength=n) < share * np.bincount(labels.ravel(), minlength=n)
    drop[0] = False
    out = region.copy()
    out[box] &= ~drop[labels]
    return out


def test_the_support_test_keeps_the_pieces_that_changed():
    """Pieces outside the occupied cells stay when a quarter of them changed from the reference
    (against the light the floor seeds around show), whatever the light's level: the same pieces
    as box filters over the whole box give, on pieces near the decision (the pieces' pixels only
    are summed now, from integral images)."""
    from sbplan.detection.footprints import SUPPORT, _supported

    rng = np.random.default_rng(5)
    h, w = 120, 160
    log_reference = cv2.GaussianBlur(rng.normal(5.0, 0.05, (h, w)).astype(np.float32), (0, 0), 3)
    light = np.linspace(-0.3, 0.2, w, dtype=np.float32)[None, :]  # a lighting gradient
    # near CHANGE_LEVEL off the light here and there: a piece's fate hangs on its light
    ratio = (light + rng.normal(0, 0.08, (h, w))).astype(np.float32)
    occ = np.zeros((h, w), bool)
    occ[45:75, 60:100] = True
    region = occ.copy()
    for k in range(28):  # arms out of the occupied cells, some darker than their light
        r0 = 46 + k
        side = slice(100, 110 + 2 * k) if k % 2 else slice(50 - 2 * k, 60)
        region[r0, side] = True
        ratio[r0, side] -= 0.01 * (k % 5)
    frame = np.exp(log_reference + ratio).astype(np.float32)
    away = cv2.distanceTransform((~region).astype(np.uint8), cv2.DIST_L2, 5)
    floor = (away >= 3) & (rng.random((h, w)) < 0.3)
    texture = np.zeros((h, w), np.float32)
    got = _supported(region, occ, floor, frame, log_reference, texture, SUPPORT)
    want = _supported_by_box_filters(region, occ, floor, frame, log_reference, texture, SUPPORT)
    assert np.array_equal(got, want)
    kept = [got[46 + k, 104 if k % 2 else 56] for k in range(28)]
    assert any(kept) and not all(kept), kept


def test_the_cut_search_finds_the_parts_the_plain_search_finds(monkeypatch):
    # the cut search clips an outline at its 15 positions in one call to shapely's ufunc; with
    # the scalar wrapper one position at a time (where the ufunc is not there) the parts are the
    # same, point for point
    from sbplan.detection import obstacles

    rng = np.random.default_rng(3)
    outlines = [np.array([[0, 0], [10, 0], [10, 2], [2, 2], [2, 9], [0, 9]], float),  # an L
                np.array([[0, 0], [4, 0], [4, 4], [8, 4], [8, 8], [4, 8], [4, 4], [0, 4]], float)]  # corners touching
    for _ in range(6):  # star-shaped blobs
        t = np.sort(rng.uniform(0, 2 * np.pi, 12))
        r = rng.uniform(1.0, 4.0, 12)
        outlines.append(np.c_[r * np.cos(t), r * np.sin(t)])
    fast = [split_parts(o) for o in outlines]
    assert any(len(p) > 1 for p in fast)
    monkeypatch.setattr(obstacles, "_CLIP_UFUNC", None)
    slow = [split_parts(o) for o in outlines]
    # ... and both are the plain search: one clip, one list of pieces and one MAR at a time
    monkeypatch.setattr(obstacles, "_best_cut", _best_cut_one_at_a_time)
    plain = [split_parts(o) for o in outlines]
    for a, b, c in zip(fast, slow, plain):
        assert len(a) == len(b) == len(c)
        assert all(np.array_equal(x, y) and np.array_equal(x, z) for x, y, z in zip(a, b, c))


def _best_cut_one_at_a_time(p, rect):
    from sbplan.detection import obstacles as o

    e = rect[1] - rect[0]
    side = float(np.degrees(np.arctan2(e[1], e[0]))) % 90.0
    best, best_cost, best_angle = None, o._area(rect), 0.0
    for angle in dict.fromkeys((side, 0.0)):
        for turn in (angle, angle + 90.0):
            q = shapely.affinity.rotate(p, -turn, origin=(0, 0))
            x0, y0, x1, y1 = q.bounds
            pad = 1.0 + (x1 - x0) + (y1 - y0)
            for t in np.linspace(x0, x1, o.PARTS_CUTS + 2)[1:-1]:
                left = shapely.clip_by_rect(q, x0 - pad, y0 - pad, t, y1 + pad)
                right = shapely.clip_by_rect(q, t, y0 - pad, x1 + pad, y1 + pad)
                pieces = [g for g in o._polygons(left) + o._polygons(right) if g.area > 0]
                if len(pieces) < 2:
                    continue
                cost = sum(o._area(o.mar_opencv(shapely.get_coordinates(g.exterior)[:-1])) for g in pieces)
                if cost < best_cost * (1 - 1e-9):
                    best, best_cost, best_angle = pieces, cost, turn
        if best is not None and best_cost <= o.PARTS_RATIO * p.area:
            break
    if best is None:
        return None
    return [shapely.affinity.rotate(g, best_angle, origin=(0, 0)) for g in best]
