"""GeoJSON that GIS tools place right (issue 18, item 1): WGS84 longitude/latitude (RFC 7946) when
the floor is georeferenced, in workspace.toml or with --georef; local metres, said so, otherwise.
The georeference is checked against geometry computed independently (a meridian arc, the
east-west scale of a parallel) and by round trips through sbplan's own reader."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from dataclasses import replace

import numpy as np
import pytest
import shapely

from _outputs_fixtures import PAPER, paper
from sbplan.detection import exports
from sbplan.errors import MapFormatError
from sbplan.planning import load_obstacles
from sbplan.workspace import Georeference, load_workspace

BERLIN = Georeference(52.5163, 13.3777, 90.0)


def georeferenced(detection, geo=BERLIN):
    cal = detection.calibration
    return replace(detection, calibration=replace(cal, workspace=replace(cal.workspace, georeference=geo)))


def meridian_arc(lat0_deg: float, lat1_deg: float) -> float:
    """Metres along a WGS84 meridian between two latitudes (numerical integral of the meridional radius)."""
    a, e2 = 6378137.0, 6.69437999014e-3
    lat = np.radians(np.linspace(lat0_deg, lat1_deg, 2001))
    m = a * (1 - e2) / (1 - e2 * np.sin(lat) ** 2) ** 1.5
    return float(((m[1:] + m[:-1]) / 2 * np.diff(lat)).sum())  # the trapezoid rule


def test_a_point_north_and_east_of_the_origin_lands_where_the_ellipsoid_says():
    # heading 0: the floor's x axis points north, y west
    geo = Georeference(45.0, 7.0, 0.0)
    (lon, lat), = geo.to_lonlat([[100.0, 0.0]])
    assert lon == pytest.approx(7.0, abs=1e-12)
    assert meridian_arc(45.0, lat) == pytest.approx(100.0, abs=1e-3)
    (lon_w, lat_w), = geo.to_lonlat([[0.0, 100.0]])
    assert lon_w < 7.0  # y is west of x when x points north
    a, e2 = 6378137.0, 6.69437999014e-3
    parallel_radius = a * math.cos(math.radians(45.0)) / math.sqrt(1 - e2 * math.sin(math.radians(45.0)) ** 2)
    assert math.radians(7.0 - lon_w) * parallel_radius == pytest.approx(100.0, abs=1e-3)


@pytest.mark.parametrize("heading", [0.0, 37.5, 90.0, 200.0])
def test_the_georeference_round_trips_to_a_tenth_of_a_millimetre(heading):
    geo = Georeference(-33.86, 151.21, heading)
    xy = np.random.default_rng(0).uniform(-200, 200, (50, 2))
    np.testing.assert_allclose(geo.to_world(geo.to_lonlat(xy)), xy, atol=1e-4)


@pytest.mark.parametrize("bad, fragment", [
    ({"latitude_deg": 91, "longitude_deg": 0, "heading_deg": 0}, "latitude_deg"),
    ({"latitude_deg": 10, "longitude_deg": 200, "heading_deg": 0}, "longitude_deg"),
    ({"latitude_deg": 10, "longitude_deg": 20}, "heading_deg"),
    ({"latitude_deg": "x", "longitude_deg": 20, "heading_deg": 0}, "latitude_deg"),
    ([1, 2, 3], "expected"),
])
def test_bad_georeferences_are_map_format_errors(bad, fragment):
    with pytest.raises(MapFormatError, match=fragment):
        Georeference.from_json(bad)


def _rings(data):
    for f in data["features"]:
        yield f["properties"]["kind"], np.asarray(f["geometry"]["coordinates"][0])


def test_georeferenced_geojson_is_rfc7946_lon_lat():
    _, det, _ = paper()
    data = exports.geojson(georeferenced(det), "mar")
    assert data["sbplan"]["crs"] == "WGS84" and data["sbplan"]["georeference"] == BERLIN.to_json()
    assert len(data["features"]) == 2 * len(det.obstacles) == 6
    for kind, ring in _rings(data):
        assert (ring[0] == ring[-1]).all() and len(ring) >= 4
        lon, lat = ring[:, 0], ring[:, 1]
        # near the origin (the floor is 4 x 3 m), in degrees, not metres near (0, 0)
        assert np.all(np.abs(lon - 13.3777) < 1e-4) and np.all(np.abs(lat - 52.5163) < 1e-4)
        # RFC 7946 7.1: exterior rings counter-clockwise (shoelace > 0 with latitude up)
        assert shapely.Polygon(ring).exterior.is_ccw
    # heading 90: x east, y north; each MAR maps onto the obstacle's metric MAR
    for ob, (kind, ring) in zip(det.obstacles, [r for r in _rings(data) if r[0] == "mar"]):
        back = BERLIN.to_world(ring[:-1])
        assert shapely.Polygon(back).hausdorff_distance(shapely.Polygon(ob.mar_m)) < 2e-4


def test_without_a_georeference_geojson_says_it_is_local_metres():
    _, det, _ = paper()
    data = exports.geojson(det, "mar")
    assert data["sbplan"]["crs"] == "local" and "georeference" not in data["sbplan"]
    assert "metres" in data["sbplan"]["coordinates"]
    ring = next(r for k, r in _rings(data) if k == "mar")
    assert shapely.Polygon(ring[:-1]).hausdorff_distance(shapely.Polygon(det.obstacles[0].mar_m)) < 1e-5
    assert shapely.Polygon(ring).exterior.is_ccw


def test_plan_reads_georeferenced_geojson_back_in_metres(tmp_path):
    _, det, _ = paper()
    exports.write_geojson(tmp_path / "geo.geojson", georeferenced(det))
    exports.write_geojson(tmp_path / "local.geojson", det)
    geo, local = load_obstacles(tmp_path / "geo.geojson"), load_obstacles(tmp_path / "local.geojson")
    assert geo.bounds == local.bounds
    for a, b in zip(geo.polygons, local.polygons):
        assert a.hausdorff_distance(b) < 2e-4


def test_workspace_toml_georeference_reaches_the_geojson_of_sbplan_detect(tmp_path):
    toml = (PAPER / "workspace.toml").read_text() + (
        "[georeference]\nlatitude_deg = 48.137\nlongitude_deg = 11.575\nheading_deg = 0\n")
    (tmp_path / "workspace.toml").write_text(toml)
    ws = load_workspace(tmp_path)
    assert ws.georeference == Georeference(48.137, 11.575, 0.0)
    cal, _, _ = paper()
    cal_file = tmp_path / "calibration.json"
    replace(cal, workspace=ws).save(cal_file)
    run = lambda *a: subprocess.run([sys.executable, "-m", "sbplan", "detect", str(PAPER / "scene-01.png"), "-c",
                                     str(cal_file), *map(str, a)], capture_output=True, text=True)
    r = run("--geojson", tmp_path / "a.geojson", "-o", tmp_path / "a.json")
    assert r.returncode == 0, r.stderr
    a = json.loads((tmp_path / "a.geojson").read_text())
    assert a["sbplan"]["crs"] == "WGS84" and a["sbplan"]["georeference"]["latitude_deg"] == 48.137
    assert json.loads((tmp_path / "a.json").read_text())["workspace"]["georeference"]["heading_deg"] == 0
    lon, lat = np.asarray(a["features"][0]["geometry"]["coordinates"][0]).mean(axis=0)
    assert abs(lat - 48.137) < 1e-4 and abs(lon - 11.575) < 1e-4
    # --georef overrides the workspace's
    r = run("--geojson", tmp_path / "b.geojson", "--georef=-12.5,130.8,45")
    assert r.returncode == 0, r.stderr
    b = json.loads((tmp_path / "b.geojson").read_text())
    assert b["sbplan"]["georeference"] == {"latitude_deg": -12.5, "longitude_deg": 130.8, "heading_deg": 45.0}
    r = run("--geojson", tmp_path / "c.geojson", "--georef", "12,abc")
    assert r.returncode != 0 and r.stderr.startswith("sbplan: error: georeference") and "Traceback" not in r.stderr


@pytest.mark.parametrize("command", ["detect", "demo", "serve"])
def test_every_command_writing_geojson_says_its_crs(command):
    out = subprocess.run([sys.executable, "-m", "sbplan", command, "--help"], capture_output=True, text=True).stdout
    text = " ".join(out.split())
    assert "WGS84" in text and "local" in text and "metres" in text and "--georef" in text
