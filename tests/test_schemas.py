"""Every JSON sbplan writes validates against the JSON Schema it ships (issue 18, item 11):
the detection result (its camera member included), the calibration file, the route and the
GeoJSON, as the library, the command line, the demo and the service write them, and the
service's WebSocket events. Each schema also refuses a broken document, so that the validation
can fail. (The events of ``sbplan watch`` have their schema in sbplan/live/schemas/, checked by
tests/test_live.py against every event its test streams produce.)"""

from __future__ import annotations

import copy
import json
import subprocess
import sys
from dataclasses import replace
from importlib import resources

import jsonschema
import pytest
import shapely
from shapely.geometry import box

import sbplan
from _outputs_fixtures import PAPER, ROOT, moved_floor, paper
from sbplan.detection import Detector, exports
from sbplan.errors import MapFormatError
from sbplan.workspace import Georeference

NAMES = ("detection", "calibration", "route", "geojson", "service-events")


def schema(name: str) -> dict:
    return json.loads((resources.files("sbplan") / "schemas" / f"{name}.schema.json").read_text(encoding="utf-8"))


def errors(name: str, document) -> list[str]:
    validator = jsonschema.Draft202012Validator(schema(name), format_checker=jsonschema.FormatChecker())
    return [f"{'/'.join(map(str, e.absolute_path))}: {e.message[:200]}" for e in validator.iter_errors(document)]


def through_json(obj):
    """What a reader of the file gets (tuples become lists, numpy values numbers)."""
    from sbplan.imageio import json_default

    return json.loads(json.dumps(obj, default=json_default))


@pytest.mark.parametrize("name", NAMES)
def test_the_schemas_are_valid_2020_12_schemas(name):
    jsonschema.Draft202012Validator.check_schema(schema(name))
    assert schema(name)["$schema"] == "https://json-schema.org/draft/2020-12/schema"


def detections():
    cal, det, image = paper()
    moved_cal, frame = moved_floor()
    # no symbol at all (registration off: it would refuse): every cell occupied, one obstacle
    empty = Detector(cal, register=False)(image * 0 + 255)
    moved = Detector(moved_cal)(frame)
    assert moved.camera.warning and det.camera.warning is None
    geo = replace(cal, workspace=replace(cal.workspace, georeference=Georeference(52.5, 13.4, 30.0)))
    return {"paper": det, "moved": moved, "nothing-found": empty, "georeferenced": replace(det, calibration=geo)}


def test_detection_results_validate():
    for what, det in detections().items():
        assert errors("detection", through_json(det.to_json())) == [], what


def test_calibration_files_validate(tmp_path):
    cal, _, _ = paper()
    moved_cal, _ = moved_floor()
    for what, c in {"paper": cal, "rendered": moved_cal}.items():
        c.save(tmp_path / f"{what}.json")
        assert errors("calibration", json.loads((tmp_path / f"{what}.json").read_text())) == [], what


def test_routes_validate(tmp_path):
    wall = [box(4, 2, 6, 8)]
    routes = [sbplan.plan(wall, (1, 5), (9, 5), robot_radius=0.2, bounds=(0, 0, 10, 10)),
              sbplan.plan(wall, (1, 1), (9, 1), robot_radius=0.2, bounds=(0, 0, 10, 10)),
              sbplan.plan(wall, (1, 5), (9, 5), robot_radius=0.2, bounds=(0, 0, 10, 10), planner="rrt-connect",
                          time_limit=0.5)]
    routes.append(sbplan.replan(routes[0], routes[0].waypoints[0], [box(7.0, 2.5, 7.5, 3.5)]))
    for route in routes:
        assert errors("route", through_json(route.to_dict())) == [], route
    r = subprocess.run([sys.executable, "-m", "sbplan", "plan", "--obstacles", str(PAPER.parent / "ompl-mazes" /
                        "ompl-maze-thin.png"), "--start", "205,445", "--goal", "445,55", "--radius", "1", "--json"],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert errors("route", json.loads(r.stdout)) == []


def test_geojson_validates_local_and_georeferenced(tmp_path):
    for what, det in detections().items():
        path = exports.write_geojson(tmp_path / f"{what}.geojson", det)
        assert errors("geojson", json.loads(path.read_text())) == [], what


def test_the_demo_outputs_validate(tmp_path):
    r = subprocess.run([sys.executable, "-m", "sbplan", "demo", str(PAPER), "-o", str(tmp_path), "--georef",
                        "48.1,11.6,90"], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    for name, file in [("calibration", "calibration.json"), ("detection", "result.json"), ("route", "route.json"),
                       ("geojson", "obstacles.geojson")]:
        assert errors(name, json.loads((tmp_path / file).read_text())) == [], file


def test_each_schema_refuses_a_broken_document():
    cal, det, _ = paper()
    doc = through_json(det.to_json())
    broken = copy.deepcopy(doc)
    del broken["camera"]["matrix"]
    assert errors("detection", broken)
    broken = copy.deepcopy(doc)
    broken["occupied_cells"][0] = [1]
    assert errors("detection", broken)
    broken = through_json(cal.to_json())
    broken["format"] = "sbplan.calibration/2"
    assert errors("calibration", broken)
    route = through_json(sbplan.plan([box(4, 2, 6, 8)], (1, 5), (9, 5), robot_radius=0.2,
                                     bounds=(0, 0, 10, 10)).to_dict())
    route["time"] = route.pop("time_s")
    assert errors("route", route)
    geo = exports.geojson(det, georeference=Georeference(52.5, 13.4, 0.0))
    geo["features"][0]["geometry"]["coordinates"][0][0] = [200.0, 52.5]  # not a longitude
    assert errors("geojson", geo)
    local = exports.geojson(det)
    local["sbplan"]["crs"] = "WGS84"  # lon/lat claimed without the georeference that makes them
    assert errors("geojson", local)


def test_the_service_serves_schema_valid_json_in_both_crs(tmp_path):
    """The service's detection JSON (POST /detect, GET /state), its GeoJSON and its WebSocket
    events validate against the shipped schemas; its nav2 image is marked as one. Its responses go through response models: they
    must keep the GeoJSON's `crs` and the workspace's georeference (a model that dropped them
    served lon/lat that `plan` would read as metres)."""
    from _service import GOAL, SCENE_PNG, START, client, running, ws_connect
    from sbplan.planning import load_obstacles

    cal, det, _ = paper()
    geo_cal = replace(cal, workspace=replace(cal.workspace, georeference=Georeference(52.5, 13.4, 30.0)))
    events: list[str] = []
    for what, c in {"local": cal, "WGS84": geo_cal}.items():
        with running(c, listeners=[lambda e: events.append(e.text)]) as (url, _), client(url) as http, \
                ws_connect(url) as ws:
            events.append(ws.recv(timeout=20))  # hello: sent to each connection, not through listeners
            detected = http.post("/detect", content=SCENE_PNG, headers={"content-type": "image/png"})
            assert detected.status_code == 200, detected.text
            assert http.post("/routes", json={"start": START, "goal": GOAL}).status_code == 201
            state = http.get("/state").json()
            r = http.get("/obstacles.geojson")
            assert r.status_code == 200, r.text
            doc = r.json()
            pgm = http.get("/map.pgm").content
        # the served nav2 image says what it is, as the one detect writes: plan wants its map.yaml
        (tmp_path / "map.pgm").write_bytes(pgm)
        with pytest.raises(MapFormatError, match="map.yaml"):
            load_obstacles(tmp_path / "map.pgm")
        for body in (detected.json(), state):
            assert errors("detection", body) == [], what
            assert body["workspace"]["georeference"] == (None if c is cal else geo_cal.workspace.georeference.to_json())
        assert doc["sbplan"]["crs"] == what and errors("geojson", doc) == [], what
        (tmp_path / f"{what}.geojson").write_bytes(r.content)
        loaded = load_obstacles(tmp_path / f"{what}.geojson")
        for a, b in zip(loaded.polygons, (ob.mar_m for ob in det.obstacles)):
            assert a.hausdorff_distance(shapely.Polygon(b)) < 1e-3, what
    kinds = [json.loads(text)["type"] for text in events]
    assert {"hello", "detection", "route"} <= set(kinds), kinds
    for text in events:
        assert errors("service-events", json.loads(text)) == [], text[:200]


def test_the_shipped_service_event_schema_is_what_the_service_serves():
    """GET /events/schema is made from the service's models; the shipped file must say the same
    (after changing a model: write sbplan.service.models.events_schema() to the file)."""
    from sbplan.service.models import events_schema

    assert schema("service-events") == events_schema()
