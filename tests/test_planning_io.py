"""Obstacle loaders on real files (sbplan.detection.exports outputs of a detection, the OMPL maze images) and
the ``sbplan plan`` command (subprocess: exit codes, one-line errors, no OMPL log without -v)."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest
import shapely
import shapely.affinity
from shapely.geometry import LineString, box

from sbplan.detection import exports as export
from sbplan.errors import InputError, MapFormatError
from sbplan.planning import PlanningMap, detection_obstacles, load_obstacles
from sbplan.planning.loaders import occupancy_rectangles

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "maps" / "paper-8x6"
MAZES = ROOT / "maps" / "ompl-mazes"


@pytest.fixture(scope="module")
def detection_files(tmp_path_factory):
    from sbplan.detection.calibration import calibrate
    from sbplan.detection import Detector
    from sbplan.imageio import load_image, write_json
    from sbplan.workspace import load_workspace

    out = tmp_path_factory.mktemp("paper")
    cal = calibrate(PAPER / "reference.png", workspace=load_workspace(PAPER))
    det = Detector(cal)(load_image(PAPER / "scene-01.png"))
    write_json(out / "result.json", det.to_json())
    export.write_geojson(out / "obstacles.geojson", det)
    export.write_nav2(out / "nav2", det)
    return out, det


def test_detection_json_and_geojson_give_the_planners_polygons_and_the_bounds(detection_files):
    out, det = detection_files
    assert len(det.obstacles) == 3
    for model in ("parts", "mar"):
        want = [shapely.Polygon(p) for p in det.planner_obstacles(model)]
        for name in ("result.json", "obstacles.geojson"):
            if name.endswith("geojson") and model != "parts":
                continue  # the GeoJSON holds the model it was written with
            got = load_obstacles(out / name, obstacle_model=model) if name == "result.json" else load_obstacles(out / name)
            assert got.bounds == pytest.approx(det.calibration.world_bounds(), abs=1e-6)
            assert len(got.polygons) == len(want) >= 3
            for p in got.polygons:
                # The files round coordinates to 1e-6 m.
                assert min(p.hausdorff_distance(q) for q in want) < 2e-6
    mars = shapely.union_all([shapely.Polygon(ob.mar_m) for ob in det.obstacles])
    outlines = load_obstacles(out / "result.json", use="outline").polygons
    assert shapely.union_all(outlines).area < mars.area


def test_a_detection_and_its_json_give_the_same_obstacles(detection_files):
    out, det = detection_files
    for use, key in (("mar", "mar_m"), ("parts", "parts_m"), ("outline", "outline_m")):
        live = detection_obstacles(det, use=use)
        assert [np.asarray(p.exterior.coords)[:-1].tolist() for p in live.polygons] == \
            [np.asarray(q).tolist() for ob in det.obstacles for q in ob.polygons_m(use)]
        assert live.bounds == det.calibration.world_bounds()
        stored = detection_obstacles(json.loads((out / "result.json").read_text()), use=use, source="result.json")
        assert stored.bounds == pytest.approx(live.bounds, abs=1e-6) and stored.source == "result.json"
        assert len(stored.polygons) == len(live.polygons)
        for a, b in zip(stored.polygons, live.polygons):
            assert a.hausdorff_distance(b) < 2e-6  # the JSON rounds to 1e-6 m
        file = load_obstacles(out / "result.json", use=use)
        assert [p.wkb for p in file.polygons] == [p.wkb for p in stored.polygons] and file.bounds == stored.bounds
    with pytest.raises(MapFormatError, match="use"):
        detection_obstacles(det, use="hull")
    with pytest.raises(InputError, match="detection"):
        detection_obstacles([np.zeros((4, 2))])


def test_nav2_map_holds_the_planners_polygons_to_a_pixel(detection_files):
    out, det = detection_files
    got = load_obstacles(out / "nav2" / "map.yaml")
    assert got.bounds == pytest.approx(det.calibration.world_bounds(), abs=1e-6)
    union = shapely.union_all(got.polygons)
    want = shapely.union_all([shapely.Polygon(p) for p in det.planner_obstacles()])
    res = min(det.calibration.workspace.pitch_m) / 10
    assert want.difference(union).area < 1e-9  # every pixel a polygon touches is occupied
    assert union.difference(want.buffer(2 * res, join_style="mitre")).area < 1e-9
    # A route between the map's start and goal on the nav2 obstacles keeps the radius.
    ws = det.calibration.workspace
    pm = PlanningMap(got.polygons, robot_radius=ws.robot_radius_m, bounds=got.bounds)
    route = pm.solve(ws.start_m, ws.goal_m)
    assert LineString(route.waypoints).distance(union) >= ws.robot_radius_m - 1e-6


@pytest.mark.parametrize("name", ["ompl-maze-normal.png", "ompl-maze-thin.png"])
def test_maze_images_become_exact_polygons_not_one_mar(name):
    img = cv2.imread(str(MAZES / name), cv2.IMREAD_GRAYSCALE)
    got = load_obstacles(MAZES / name)
    assert got.bounds == (0.0, 0.0, 450.0, 450.0)
    union = shapely.union_all(got.polygons)
    assert union.area == pytest.approx(float((img < 128).sum()))
    assert sum(p.area for p in got.polygons) == pytest.approx(union.area)  # disjoint
    # Exact polygons: axis-parallel edges, and not one rectangle around the connected walls.
    for p in got.polygons:
        for ring in (p.exterior, *p.interiors):
            d = np.diff(np.asarray(ring.coords), axis=0)
            assert (np.min(np.abs(d), axis=1) == 0).all()
    assert union.area < 0.8 * 450 * 450  # the walls' MAR would be the whole image
    # Frame: origin bottom-left, y up; pixel (row, col) is free iff its centre is outside the union.
    rng = np.random.default_rng(0)
    rc = rng.integers(0, 450, (300, 2))
    centres = np.c_[rc[:, 1] + 0.5, 450 - rc[:, 0] - 0.5]
    inside = shapely.contains_xy(union, centres[:, 0], centres[:, 1])
    np.testing.assert_array_equal(inside, img[rc[:, 0], rc[:, 1]] < 128)
    # Entrance (top) to exit (bottom right) through the corridors, never through a wall.
    route = PlanningMap(got.polygons, robot_radius=2.0, bounds=got.bounds).solve((205, 445), (445, 55))
    assert route.status == "exact" and len(route.waypoints) > 5
    assert LineString(route.waypoints).distance(union) >= 2.0 - 1e-3


def test_occupancy_rectangles_with_resolution_and_origin():
    occ = np.zeros((4, 6), bool)
    occ[0:2, 1:3] = True  # top-left block
    occ[3, 5] = True
    rects = occupancy_rectangles(occ, resolution=0.5, origin=(10.0, 20.0))
    union = shapely.union_all(rects)
    assert union.symmetric_difference(shapely.union_all([box(10.5, 21.0, 11.5, 22.0), box(12.5, 20.0, 13.0, 20.5)])).area < 1e-12


@pytest.mark.parametrize("content, fragment", [
    ("", "not valid JSON"),
    ("{\"type\": \"FeatureCollection\", \"features\": [{\"type\": \"Feature\", \"geometry\": "
     "{\"type\": \"Point\", \"coordinates\": [1, 2]}}]}", "expected Polygon"),
    ("{\"format\": \"sbplan.detection/1\", \"obstacles\": [{\"id\": 1}]}", "parts_m"),
    ("[1, 2]", "neither a GeoJSON"),
])
def test_bad_obstacle_files_raise_map_format_errors(tmp_path, content, fragment):
    p = tmp_path / "bad.json"
    p.write_text(content)
    with pytest.raises(MapFormatError, match=fragment):
        load_obstacles(p)


# -- the CLI ---------------------------------------------------------------------------------------
def sbplan(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "sbplan", *map(str, args)], capture_output=True, text=True, cwd=cwd)


MAZE_ARGS = ("plan", "--obstacles", MAZES / "ompl-maze-normal.png", "--start", "205,445", "--goal", "445,55",
             "--radius", "2")


def test_cli_json_and_plot(tmp_path):
    png = tmp_path / "route.png"
    r = sbplan(*MAZE_ARGS, "--json", "--plot", png)
    assert r.returncode == 0, r.stderr
    data = json.loads(r.stdout)
    assert data["format"] == "sbplan.route/1" and data["status"] == "exact" and data["planner"] == "aux-corner"
    wp = np.array(data["waypoints"])
    assert wp[0].tolist() == [205, 445] and wp[-1].tolist() == [445, 55]
    assert data["length"] == pytest.approx(np.hypot(*np.diff(wp, axis=0).T).sum())
    img = cv2.imread(str(png))
    # an 800 x 800 plot area, with the axes' labels at its left and below it, the legend at its right
    assert img.shape[0] > 800 and img.shape[1] > 900 and img.shape[2] == 3
    # The route's colour (BGR 200, 80, 0), the start's green and the goal's red are drawn.
    for bgr in ((200, 80, 0), (0, 170, 0), (0, 0, 220)):
        assert (np.abs(img.astype(int) - bgr).sum(axis=2) < 30).sum() > 20, bgr


def test_cli_ompl_planner_logs_only_with_verbose():
    args = ("plan", "--obstacles", MAZES / "ompl-maze-normal.png", "--start", "205,445", "--goal", "205,400",
            "--radius", "2", "--planner", "rrt-star", "--time-limit", "0.1")
    r = sbplan(*args)
    assert r.returncode == 0, r.stderr
    assert "Info:" not in r.stdout + r.stderr and "Debug:" not in r.stdout + r.stderr
    assert r.stderr == ""
    assert r.stdout.startswith("route by rrt-star (")
    v = sbplan("-v", *args)
    assert v.returncode == 0 and "Info:" in v.stdout + v.stderr


@pytest.mark.parametrize("extra, fragment", [
    (("--start", "10,10"), "start (10, 10) is inside an obstacle"),
    (("--goal", "500,10"), "outside the workspace bounds"),
    (("--radius", "-1"), "robot_radius"),
    (("--planner", "nope"), "nope"),
    (("--obstacles", "missing.png"), "no such file"),
])
def test_cli_errors_are_one_line(tmp_path, extra, fragment):
    args = list(MAZE_ARGS)
    for k, v in zip(extra[0::2], extra[1::2]):
        if k in args:
            args[args.index(k) + 1] = v
        else:
            args += [k, v]
    r = sbplan(*args, cwd=tmp_path)
    assert r.returncode != 0
    assert "Traceback" not in r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("sbplan: error:") and fragment in lines[0], r.stderr


def test_cli_empty_obstacle_file_is_an_error(tmp_path):
    (tmp_path / "empty.geojson").write_text("")
    r = sbplan("plan", "--obstacles", tmp_path / "empty.geojson", "--start", "1,1", "--goal", "2,2", "--radius", "0")
    assert r.returncode != 0 and r.stderr.startswith("sbplan: error:") and "Traceback" not in r.stderr


def test_ompl_planners_are_silent_through_the_api():
    code = ("import sbplan; from shapely.geometry import box; "
            "r = sbplan.plan([box(4, 2, 6, 8)], (1, 5), (9, 5), robot_radius=0.2, bounds=(0, 0, 10, 10), "
            "planner='rrt-connect', time_limit=0.2); print(r.status)")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert r.stdout == "exact\n" and r.stderr == ""


def test_bench_plan_quick_runs_and_writes_an_ompl_log(tmp_path):
    log = tmp_path / "plan.log"
    r = sbplan("bench", "plan", "--quick", "--worlds", "rect-5", "--planners", "rrt-connect", "--queries", "3",
               "--time-limit", "0.05", "--json", "--ompl-log", log)
    assert r.returncode == 0, r.stderr
    # progress only on stderr (no OMPL log lines); stdout is the JSON
    assert r.stderr and all(line.startswith("bench plan: [") for line in r.stderr.splitlines()), r.stderr
    data = json.loads(r.stdout)
    (row,) = data["rows"]
    assert row["world"] == "rect-5" and row["queries"] == 3 and row["obstacles"] == 5
    assert set(row["ompl"]) == {"rrt-connect"}
    assert "AuxCorner" in log.read_text() and "RRTConnect" in log.read_text()


def write_map(folder, occupied, *, resolution, origin):
    """A nav2 map (PGM + map.yaml) of a boolean (row, col) mask, row 0 at the top."""
    folder.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(folder / "map.pgm"), np.where(occupied, 0, 254).astype(np.uint8))
    (folder / "map.yaml").write_text(
        "image: map.pgm\nresolution: {}\norigin: [{}, {}, {}]\nnegate: 0\noccupied_thresh: 0.65\n"
        "free_thresh: 0.196\n".format(resolution, *origin))
    return folder / "map.yaml"


@pytest.mark.parametrize("yaw", [math.pi / 2, 0.3, -2.0])
def test_nav2_map_with_a_rotated_origin_rotates_the_cells_about_it(tmp_path, yaw):
    occ = np.zeros((6, 8), bool)
    occ[1, 2] = occ[4, 5:7] = True
    ox, oy, res = 1.0, 2.0, 0.5
    got = load_obstacles(write_map(tmp_path / "r", occ, resolution=res, origin=(ox, oy, yaw)))
    flat = load_obstacles(write_map(tmp_path / "f", occ, resolution=res, origin=(0.0, 0.0, 0.0)))
    rotate = lambda g: shapely.affinity.translate(shapely.affinity.rotate(g, yaw, origin=(0, 0), use_radians=True), ox, oy)
    extent = rotate(box(0, 0, 8 * res, 6 * res))
    assert got.bounds == pytest.approx(extent.bounds, abs=1e-12)
    # The occupied cells, rotated about the origin; the rest of the bounding box is an obstacle.
    cells = shapely.union_all([rotate(q) for q in flat.polygons])
    want = cells.union(box(*extent.bounds).difference(extent))
    assert shapely.union_all(got.polygons).symmetric_difference(want).area < 1e-9
    # Cell (row 1, col 2) has its centre at (2.5, 4.5) * res in the image frame (y up from the
    # bottom row), i.e. at the origin + R(yaw) (1.25, 2.25) in the world.
    c = np.array([ox, oy]) + np.array([[math.cos(yaw), -math.sin(yaw)], [math.sin(yaw), math.cos(yaw)]]) @ [1.25, 2.25]
    assert shapely.union_all(got.polygons).contains(shapely.Point(c))
    # A route across the map, past that cell, stays on the map and off the cells.
    pm = PlanningMap(got.polygons, robot_radius=0.1, bounds=got.bounds)
    a = rotate(shapely.Point(0.3, 2.25)).coords[0]
    b = rotate(shapely.Point(3.7, 2.25)).coords[0]
    route = pm.solve(a, b)
    line = LineString(route.waypoints)
    assert len(route.waypoints) > 2 and route.status == "exact"
    assert extent.buffer(1e-9).contains(line)
    assert line.distance(cells) >= 0.1 - 1e-6


def test_nav2_map_with_a_non_finite_yaw_is_a_map_format_error(tmp_path):
    with pytest.raises(MapFormatError, match="origin"):
        load_obstacles(write_map(tmp_path, np.zeros((3, 3), bool), resolution=1.0, origin=(0.0, 0.0, "nan")))


def test_route_drawing_has_axes_a_scale_bar_a_legend_and_labelled_start_and_goal():
    from sbplan.planning import plot

    ob = box(1.0, 1.0, 2.0, 2.0)
    kw = dict(route=np.array([[0.5, 0.5], [2.2, 0.8], [3.5, 2.5]]), start=(0.5, 0.5), goal=(3.5, 2.5), size=400)
    img = plot.draw_route([ob], [ob.buffer(0.2)], (0.0, 0.0, 4.0, 3.0), **kw)
    left, top = plot._LEFT, plot._TOP
    w, h, s = 400, 300, 100.0  # the plot area and its pixels per metre
    assert img.shape[:2] == (top + h + plot._BOTTOM, left + w + plot._LEGEND)

    def ink(region):
        return int((region.max(axis=2) < 120).sum())

    # tick labels at the left of and below the plot area; axis names with the unit
    assert ink(img[top:top + h, :left - 6]) > 100 and ink(img[top + h + 6:, left:left + w]) > 100
    blank = plot.draw_route([ob], [ob.buffer(0.2)], (0.0, 0.0, 4.0, 3.0), units="px", **kw)
    assert not np.array_equal(blank[top + h + 25:], img[top + h + 25:])  # "x (px)" instead of "x (m)"
    # tick marks every nice step (0.5 m here) along the bottom edge of the plot area
    assert plot.nice_step(4.0) == 0.5
    for x in np.arange(0.0, 4.01, 0.5):
        c = int(round(left + x * s))
        assert ink(img[top + h + 1:top + h + 5, c - 1:c + 2]) > 0, x

    def colour(region, bgr):
        return int((np.abs(region.astype(int) - bgr).sum(axis=2) < 30).sum())

    # the legend at the right shows obstacle, clearance, route, start and goal, and a scale bar
    legend = img[:, left + w + 1:]
    for bgr in ((60, 60, 60), (200, 215, 245), (200, 80, 0), (0, 170, 0), (0, 0, 220)):
        assert colour(legend, bgr) > 20, bgr
    assert ink(legend[top + 24 * 5 + 20:]) > 40  # the scale bar and its length
    # "start" and "goal" written next to their discs (in their colours, beyond the disc)
    for pt, bgr in ((kw["start"], (0, 170, 0)), (kw["goal"], (0, 0, 220))):
        c, r = int(round(left + pt[0] * s)), int(round(top + (3.0 - pt[1]) * s))
        yy, xx = np.mgrid[:img.shape[0], :img.shape[1]]
        away = (np.hypot(xx - c, yy - r) > 9) & (np.hypot(xx - c, yy - r) < 60) & (xx < left + w + 1)
        assert colour(np.where(away[..., None], img, 255), bgr) > 15, pt
    # nothing is drawn outside the plot area but axes, labels and legend: the clearance is cut at its edge
    clipped = plot.draw_route([box(3.7, 1.0, 4.5, 2.0)], [box(3.5, 0.8, 4.7, 2.2)], (0.0, 0.0, 4.0, 3.0), size=400)
    assert colour(clipped[:, left + w + 2:left + w + 12], (200, 215, 245)) == 0
