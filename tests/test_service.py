"""sbplan serve: the real server (uvicorn on 127.0.0.1, a free port) and real clients (httpx,
websockets) over TCP, on the paper's floor (maps/paper-8x6)."""

from __future__ import annotations

import asyncio
import concurrent.futures
import json
import struct
import threading
import zlib

import numpy as np
import pytest
import shapely
from shapely.geometry import LineString, Polygon, box
from websockets.exceptions import InvalidStatus

import sbplan
from sbplan.cli import main
from sbplan.detection import calibrate
from sbplan.planning import load_obstacles
from sbplan.service import Limits
from sbplan.service.core import OutEvent
from sbplan.service.events import FELL_BEHIND, Broker
from sbplan.service.images import image_header
from sbplan.service.server import is_loopback
from sbplan.service.sources import FolderSource

from _service import (EMPTY_PNG, GOAL, MAP, SCENE_PNG, START, client, jpeg, png, receive, running, wait_for,
                      ws_connect)

TOKEN = "s3cret-token-for-the-tests"


@pytest.fixture(scope="module")
def cal():
    return calibrate(str(MAP / "reference.png"), workspace=str(MAP))


def _obstacles(state: dict) -> list[Polygon]:
    return [Polygon(o["mar_m"]) for o in state["obstacles"]]


def _clearance(waypoints, obstacles) -> float:
    line = LineString(waypoints)
    return min((line.distance(p) for p in obstacles), default=np.inf)


def _is_error(r, status: int, code: str) -> dict:
    assert r.status_code == status, r.text
    assert r.headers["content-type"].startswith("application/json")
    body = r.json()
    assert body["code"] == code, body
    assert body["message"] and "\n" not in body["message"] and "Traceback" not in r.text
    return body


# -- endpoints ------------------------------------------------------------------------------------
def test_before_the_first_frame_there_is_nothing_to_plan_on(cal):
    with running(cal) as (url, _), client(url) as http:
        health = http.get("/health").json()
        assert health["status"] == "ok" and health["frame"] is None and health["auth"] is False
        for path in ("/state", "/obstacles.geojson", "/map.yaml", "/map.pgm"):
            _is_error(http.get(path), 409, "no-frame")
        _is_error(http.post("/routes", json={"start": START, "goal": GOAL}), 409, "no-frame")


def test_detect_makes_the_frame_the_state_and_every_export_serves_it(cal, tmp_path):
    with running(cal) as (url, _), client(url) as http:
        r = http.post("/detect", content=SCENE_PNG, headers={"content-type": "image/png"})
        assert r.status_code == 200, r.text
        det = r.json()
        assert det["format"] == "sbplan.detection/1" and det["frame"] == 1 and det["source"] == "post"
        assert len(det["occupied_cells"]) == 13 and len(det["obstacles"]) == 3
        state = http.get("/state").json()
        assert state["frame"] == 1 and state["age_s"] >= 0
        assert state["occupied_cells"] == det["occupied_cells"]
        ob = state["obstacles"][0]
        assert {"outline_px", "mar_px", "outline_m", "mar_m"} <= set(ob) and len(ob["mar_m"]) == 4
        assert set(state["camera"]) >= {"shift_px", "rotation_deg", "scale", "model"}

        geo = http.get("/obstacles.geojson")
        assert geo.headers["content-type"].startswith("application/geo+json")
        assert geo.headers["x-sbplan-frame"] == "1"
        (tmp_path / "obstacles.geojson").write_bytes(geo.content)
        loaded = load_obstacles(tmp_path / "obstacles.geojson")  # the parts the service plans around
        assert len(loaded.polygons) >= 3 and loaded.bounds == (0.0, 0.0, 4.0, 3.0)
        assert geo.json()["sbplan"]["obstacle_model"] == "parts"

        yaml, pgm = http.get("/map.yaml"), http.get("/map.pgm")
        assert yaml.headers["x-sbplan-frame"] == pgm.headers["x-sbplan-frame"] == "1"
        assert pgm.content.startswith(b"P5")
        (tmp_path / "nav2").mkdir()
        (tmp_path / "nav2" / "map.yaml").write_bytes(yaml.content)
        (tmp_path / "nav2" / "map.pgm").write_bytes(pgm.content)
        nav2 = shapely.union_all(load_obstacles(tmp_path / "nav2" / "map.yaml").polygons)
        # the same parts: every 5 cm map pixel they reach into, so none further than a pixel's diagonal
        parts = shapely.union_all(loaded.polygons)
        assert parts.difference(nav2).area < 1e-9 and nav2.difference(parts.buffer(0.05 * 2 ** 0.5)).area < 1e-9


def test_detect_takes_a_jpeg_in_a_multipart_field(cal):
    with running(cal) as (url, _), client(url) as http:
        r = http.post("/detect", files={"image": ("frame.jpg", jpeg(SCENE_PNG), "image/jpeg")})
        assert r.status_code == 200, r.text
        assert len(r.json()["occupied_cells"]) == 13
        _is_error(http.post("/detect", files={"picture": ("frame.jpg", jpeg(SCENE_PNG), "image/jpeg")}),
                  415, "not-an-image")


def test_routes_are_planned_kept_replanned_and_deleted(cal):
    with running(cal) as (url, _), client(url) as http:
        state = http.post("/detect", content=SCENE_PNG).json()
        obstacles = _obstacles(state)
        r = http.post("/routes", json={"start": START, "goal": GOAL, "owner": "robot-1"})
        assert r.status_code == 201, r.text
        route = r.json()
        assert route["id"] == "r1" and route["version"] == 1 and route["reason"] == "created"
        assert route["state"] == "ok" and route["frame"] == 1 and route["robot_radius_m"] == 0.15
        wp = route["waypoints_m"]
        assert wp[0] == list(START) and wp[-1] == list(GOAL)
        # the same answer as the library on the same obstacles
        again = sbplan.plan(obstacles, START, GOAL, robot_radius=0.15, bounds=(0, 0, 4, 3))
        assert route["length_m"] == pytest.approx(again.length, rel=1e-6, abs=2e-6)  # rounded to 1 um
        assert _clearance(wp, obstacles) >= 0.15 - 1e-6

        assert http.get("/routes/r1").json() == route
        assert [x["id"] for x in http.get("/routes", params={"owner": "robot-1"}).json()["routes"]] == ["r1"]
        assert http.get("/routes", params={"owner": "robot-2"}).json()["routes"] == []

        # the robot, on its route's third waypoint, sees an obstacle on the next leg
        position = wp[2]
        extra = box(2.4, 1.0, 2.6, 1.2)
        assert LineString(wp[2:]).intersects(extra)
        r = http.post("/routes/r1/replan", json={"position": position,
                                                  "obstacle": [list(c) for c in extra.exterior.coords[:-1]]})
        assert r.status_code == 200, r.text
        new = r.json()
        assert new["version"] == 2 and new["reason"] == "replan" and new["extra_obstacles"] == 1
        assert new["waypoints_m"][0] == position and new["position_m"] == position
        assert _clearance(new["waypoints_m"], obstacles + [extra]) >= 0.15 - 1e-6

        assert http.delete("/routes/r1").json() == {"id": "r1", "deleted": True}
        _is_error(http.get("/routes/r1"), 404, "unknown-route")
        _is_error(http.delete("/routes/r1"), 404, "unknown-route")


def test_openapi_and_the_event_schema_describe_the_api(cal):
    with running(cal) as (url, _), client(url) as http:
        spec = http.get("/openapi.json").json()
        assert {"/health", "/state", "/obstacles.geojson", "/map.yaml", "/map.pgm", "/detect", "/routes",
                "/routes/{route_id}", "/routes/{route_id}/replan", "/events/schema"} <= set(spec["paths"])
        assert "RouteRequest" in spec["components"]["schemas"]
        assert spec["paths"]["/state"]["get"]["security"] == [{"bearer": []}]
        assert "security" not in spec["paths"]["/health"]["get"]
        assert http.get("/docs").status_code == 200
        schema = json.dumps(http.get("/events/schema").json())
        for kind in ("hello", "detection", "route", "route-deleted", "frame-rejected", "source", "error"):
            assert f'"const": "{kind}"' in schema


# -- bad input ------------------------------------------------------------------------------------
def _png_header(width: int, height: int) -> bytes:
    """A PNG signature and IHDR chunk declaring a size, nothing else."""
    ihdr = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    return (b"\x89PNG\r\n\x1a\n" + struct.pack(">I", 13) + b"IHDR" + ihdr
            + struct.pack(">I", zlib.crc32(b"IHDR" + ihdr)))


def test_bad_input_gets_a_4xx_with_a_code_and_one_line(cal):
    with running(cal, limits=Limits(max_body=len(SCENE_PNG) + 1000, max_pixels=1_000_000)) as (url, _), \
            client(url) as http:
        assert http.post("/detect", content=SCENE_PNG).status_code == 200
        post = lambda body, **kw: http.post("/routes", content=body, headers={"content-type": "application/json"}, **kw)  # noqa: E731
        _is_error(post(b'{"start": [0.25, 1.75], "goal": [3.75'), 400, "malformed-json")
        bad = _is_error(http.post("/routes", json={"start": "here", "goal": GOAL}), 422, "invalid-request")
        assert bad["errors"][0]["loc"] == ["body", "start"] and "body.start" in bad["message"]
        _is_error(http.post("/routes", json={"start": START, "goal": GOAL, "robot_radius": -1}), 422, "invalid-request")
        _is_error(http.post("/routes", json={"start": START, "goal": GOAL, "robot_radus": 0.1}), 422, "invalid-request")
        _is_error(post(b'{"start": [1e999, 1.75], "goal": [3.75, 1.75]}'), 422, "invalid-request")
        _is_error(http.post("/routes", json={"start": START}), 422, "invalid-request")
        _is_error(http.post("/routes", json=[1, 2]), 422, "invalid-request")
        inside = _is_error(http.post("/routes", json={"start": [1.0, 1.5], "goal": GOAL}), 422, "start-in-obstacle")
        assert "inside an obstacle" in inside["message"]
        _is_error(http.post("/routes", json={"start": START, "goal": [3.0, 2.0]}), 422, "goal-in-obstacle")
        _is_error(http.post("/routes", json={"start": START, "goal": [9.0, 1.0]}), 422, "out-of-bounds")
        route = http.post("/routes", json={"start": START, "goal": GOAL}).json()
        _is_error(http.post(f"/routes/{route['id']}/replan", json={"position": START, "obstacle": [[0, 0], [1, 1], [2, 2]]}),
                  422, "invalid-input")
        _is_error(http.post("/routes/r99/replan", json={"position": START}), 404, "unknown-route")
        _is_error(http.get("/routes/nonsense"), 422, "invalid-request")
        _is_error(http.get("/nowhere"), 404, "not-found")
        _is_error(http.put("/state"), 405, "method-not-allowed")

        # images: not one, damaged, the wrong size, too many pixels, too many bytes
        _is_error(http.post("/detect", content=b"GIF89a not what we take"), 415, "not-an-image")
        _is_error(http.post("/detect", content=(MAP / "workspace.toml").read_bytes()), 415, "not-an-image")
        _is_error(http.post("/detect", content=SCENE_PNG[:2000]), 415, "not-an-image")
        _is_error(http.post("/detect", content=b""), 415, "not-an-image")
        _is_error(http.post("/detect", content=SCENE_PNG, headers={"content-type": "text/plain"}),
                  415, "unsupported-media-type")
        _is_error(http.post("/detect", content=_png_header(400, 300)), 422, "wrong-image-size")
        # 100 000 x 100 000 pixels declared in 33 bytes: refused from the header, never decoded
        _is_error(http.post("/detect", content=_png_header(100_000, 100_000)), 413, "image-too-large")
        big = SCENE_PNG + bytes(2000)
        _is_error(http.post("/detect", content=big), 413, "body-too-large")
        # without Content-Length (chunked): counted as it arrives
        chunks = lambda: iter([big[i:i + 4096] for i in range(0, len(big), 4096)])  # noqa: E731
        _is_error(http.post("/detect", content=chunks()), 413, "body-too-large")
        _is_error(post(b'{"start": [0.25, 1.75], "goal": [3.75, 1.75], "owner": "' + b"x" * 70_000 + b'"}'),
                  413, "body-too-large")
        # and the service still works
        assert http.get("/state").json()["frame"] == 1
        assert http.post("/routes", json={"start": START, "goal": GOAL}).status_code == 201


def test_a_camera_moved_too_far_is_a_conflict_not_a_crash(cal):
    from sbplan.synth import SceneSpec, render_scene
    from sbplan.synth.maps import recipe

    moved, _ = render_scene(recipe("paper-8x6").floor, SceneSpec(n_obstacles=0, effects={"motion": (60, 0, 0, 1.0)}),
                            seed=3)
    events: list[OutEvent] = []
    with running(cal, listeners=[events.append]) as (url, _), client(url) as http:
        assert http.post("/detect", content=SCENE_PNG).status_code == 200
        err = _is_error(http.post("/detect", content=png(moved)), 409, "camera-moved")
        assert "recalibrate" in err["message"]
        assert http.get("/state").json()["frame"] == 1  # the state stays the last good frame
        assert http.post("/detect", content=EMPTY_PNG).json()["frame"] == 2
        # (the rejection's event is sent by the state thread, after the answer may have gone; the
        # next frame is made current on that thread after it, so by now it has been sent)
        rejected = [json.loads(e.text) for e in events if e.type == "frame-rejected"]
        assert [r["code"] for r in rejected] == ["camera-moved"]


def test_frames_beyond_the_waiting_limit_are_refused_busy(cal):
    with running(cal, limits=Limits(max_pending_frames=1)) as (url, service), client(url) as http:
        gate = threading.Event()
        service._detect_pool.submit(gate.wait)  # hold the detection thread
        with concurrent.futures.ThreadPoolExecutor(1) as pool:
            first = pool.submit(http.post, "/detect", content=SCENE_PNG)
            wait_for(lambda: service._pending == 1)
            _is_error(http.post("/detect", content=EMPTY_PNG), 503, "busy")
            gate.set()
            assert first.result().json()["frame"] == 1
        assert http.post("/detect", content=EMPTY_PNG).json()["frame"] == 2


def test_image_header_reads_png_and_jpeg_sizes():
    assert image_header(SCENE_PNG) == ("png", 792, 552)
    assert image_header(jpeg(SCENE_PNG)) == ("jpeg", 792, 552)
    assert image_header(_png_header(7, 3)) == ("png", 7, 3)


# -- the token ------------------------------------------------------------------------------------
def test_a_token_guards_everything_but_health(cal):
    with running(cal, token=TOKEN) as (url, _):
        with client(url) as http:
            assert http.get("/health").json()["auth"] is True
            for path in ("/state", "/routes", "/openapi.json", "/docs", "/map.pgm"):
                r = http.get(path)
                _is_error(r, 401, "unauthorized")
                assert r.headers["www-authenticate"].startswith("Bearer")
            _is_error(http.post("/detect", content=SCENE_PNG), 401, "unauthorized")
            _is_error(http.get("/state", headers={"Authorization": "Bearer wrong-token-wrong-token"}), 401, "unauthorized")
            _is_error(http.get("/state", headers={"Authorization": f"Basic {TOKEN}"}), 401, "unauthorized")
        with client(url, headers={"Authorization": f"Bearer {TOKEN}"}) as http:
            assert http.post("/detect", content=SCENE_PNG).status_code == 200
            assert http.get("/state").json()["frame"] == 1
        with pytest.raises(InvalidStatus) as denied:
            ws_connect(url)
        assert denied.value.response.status_code == 403
        with pytest.raises(InvalidStatus):
            ws_connect(url, additional_headers={"Authorization": "Bearer wrong-token-wrong-token"})
        with ws_connect(url, additional_headers={"Authorization": f"Bearer {TOKEN}"}) as ws:
            assert receive(ws)["type"] == "hello"


def test_serve_refuses_an_open_host_without_a_token_and_bad_options(cal, tmp_path, capsys, monkeypatch):
    monkeypatch.delenv("SBPLAN_TOKEN", raising=False)
    missing = str(tmp_path / "missing.json")
    assert main(["serve", "-c", missing, "--host", "0.0.0.0"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("sbplan: error: --host 0.0.0.0 opens the service") and "\n" not in err
    assert main(["serve", "-c", missing, "--host", "0.0.0.0", "--token", "short"]) == 2
    assert "at least 16 characters" in capsys.readouterr().err
    assert main(["serve", "-c", missing]) != 0  # a missing calibration: one line, no traceback
    assert "Traceback" not in capsys.readouterr().err
    good = str(tmp_path / "cal.json")
    cal.save(good)
    assert main(["serve", "-c", good, "--planner", "teleport"]) == 8  # a missing plugin stage
    assert "unknown planner 'teleport'" in capsys.readouterr().err
    assert main(["serve", "-c", good, "--source", str(tmp_path / "nowhere")]) == 2
    assert "not a folder of images" in capsys.readouterr().err
    assert main(["serve", "-c", good, "--planner-processes", "-1"]) == 2
    assert "--planner-processes: must be >= 0" in capsys.readouterr().err
    assert is_loopback("127.0.0.1") and is_loopback("::1") and is_loopback("localhost")
    assert not is_loopback("0.0.0.0") and not is_loopback("192.168.1.5")


# -- events ---------------------------------------------------------------------------------------
def test_a_route_a_new_obstacle_blocks_is_replanned_and_pushed_to_its_owner(cal):
    with running(cal) as (url, _), client(url) as http:
        assert http.post("/detect", content=EMPTY_PNG).json()["obstacles"] == []
        route = http.post("/routes", json={"start": START, "goal": GOAL, "owner": "robot-1"}).json()
        assert route["waypoints_m"] == [list(START), list(GOAL)]  # a straight line on the empty floor
        other = http.post("/routes", json={"start": [0.25, 0.25], "goal": [0.25, 2.75], "owner": "robot-2"}).json()
        with ws_connect(url, "/events?owner=robot-1") as mine, ws_connect(url, "/events?owner=robot-2") as theirs, \
                ws_connect(url) as everyone:
            hello = receive(mine)
            assert hello["type"] == "hello" and hello["frame"] == 1 and hello["owner"] == "robot-1"
            for ws in (theirs, everyone):
                receive(ws, types={"hello"})
            # robot-1 reports that it moved along its route
            mine.send(json.dumps({"type": "position", "route": route["id"], "position": [0.3, 1.75]}))
            mine.send(json.dumps({"type": "position", "route": "r77", "position": [0.3, 1.75]}))
            assert receive(mine)["code"] == "unknown-route"
            mine.send("not json")
            assert receive(mine)["code"] == "invalid-message"

            det = http.post("/detect", content=SCENE_PNG).json()  # two obstacles now cross row 2
            assert det["routes_replanned"] == [route["id"]]  # robot-2's route, along x = 0.25, is clear
            got = receive(mine, types={"detection"})
            assert got["frame"] == 2 and len(got["obstacles"]) == 3
            pushed = receive(mine, types={"route"})["route"]
            assert pushed["id"] == route["id"] and pushed["reason"] == "blocked" and pushed["version"] == 2
            assert pushed["frame"] == 2 and pushed["state"] == "ok"
            assert pushed["position_m"] == [0.3, 1.75] and pushed["waypoints_m"][0] == [0.3, 1.75]
            assert _clearance(pushed["waypoints_m"], _obstacles(det)) >= 0.15 - 1e-6
            assert http.get(f"/routes/{route['id']}").json() == pushed

            # the unfiltered client saw it too; robot-2's client saw the detection but not robot-1's route
            assert receive(everyone, types={"route"})["route"]["id"] == route["id"]
            assert receive(theirs, types={"detection"})["frame"] == 2
            http.post("/routes", json={"start": [0.25, 0.25], "goal": [3.75, 0.25], "owner": "robot-2"})
            assert receive(theirs, types={"route"})["route"]["owner"] == "robot-2"
            assert http.get(f"/routes/{other['id']}").json()["version"] == 1


def test_a_client_that_vanishes_mid_stream_leaves_the_others_served(cal):
    with running(cal) as (url, _), client(url) as http, ws_connect(url) as stays, \
            ws_connect(url, close_timeout=0.1) as gone:
        http.post("/detect", content=EMPTY_PNG)
        receive(stays, types={"detection"})
        receive(gone, types={"detection"})
        assert http.get("/health").json()["clients"] == 2
        for _ in range(3):  # events in flight while it vanishes
            http.post("/routes", json={"start": START, "goal": GOAL})
        gone.socket.close()  # no close frame: the TCP connection just ends
        http.post("/detect", content=SCENE_PNG)
        wait_for(lambda: http.get("/health").json()["clients"] == 1)
        assert receive(stays, types={"detection"})["frame"] == 2
        http.post("/detect", content=EMPTY_PNG)
        assert receive(stays, types={"detection"})["frame"] == 3
        stays.close()
        wait_for(lambda: http.get("/health").json()["clients"] == 0)
        assert http.get("/state").json()["frame"] == 3


def test_a_client_that_falls_behind_is_told_to_reconnect():
    async def scenario():
        broker = Broker(asyncio.get_running_loop())
        Broker.queue_size, size = 2, Broker.queue_size
        try:
            slow, fast = broker.subscribe(None), broker.subscribe(None)
        finally:
            Broker.queue_size = size
        for seq in (1, 2, 3):
            broker._dispatch(OutEvent(seq, "detection", f'{{"seq": {seq}}}'))
            if seq < 3:
                fast.queue.get_nowait()
        return broker, slow, fast

    broker, slow, fast = asyncio.run(scenario())
    assert slow not in broker.subscribers and slow.queue.get_nowait() is FELL_BEHIND  # closed with 1013
    assert fast in broker.subscribers and fast.queue.get_nowait() == '{"seq": 3}'


# -- shared state ---------------------------------------------------------------------------------
def test_concurrent_requests_never_see_a_half_updated_state(cal):
    with running(cal) as (url, _), client(url) as http:
        http.post("/detect", content=EMPTY_PNG)
        seen: list[tuple[int, int, int]] = []

        def reader():
            for _ in range(40):
                s = http.get("/state").json()
                seen.append((s["frame"], len(s["occupied_cells"]), len(s["obstacles"])))

        with concurrent.futures.ThreadPoolExecutor(4) as pool:
            readers = [pool.submit(reader) for _ in range(3)]
            frames = [http.post("/detect", content=png).json()["frame"] for png in [SCENE_PNG, EMPTY_PNG] * 3]
            for f in readers:
                f.result()
        assert frames == [2, 3, 4, 5, 6, 7]
        # odd frames are the empty floor, even ones the scene: cells and obstacles always of one frame
        assert all((cells, obs) == ((0, 0) if frame % 2 else (13, 3)) for frame, cells, obs in seen)
        assert len({f for f, _, _ in seen}) > 1


@pytest.mark.parametrize("processes", [0, 1], ids=["state-thread", "planning-process"])
def test_concurrent_route_requests_get_the_libraries_answers(cal, processes):
    rng = np.random.default_rng(3)
    with running(cal, planner_processes=processes) as (url, _), client(url) as http:
        obstacles = _obstacles(http.post("/detect", content=SCENE_PNG).json())
        enlarged = shapely.union_all([p.buffer(0.16) for p in obstacles])
        queries = []
        while len(queries) < 24:
            s, g = rng.uniform((0.2, 0.2), (3.8, 2.8), (2, 2))
            if not enlarged.contains(shapely.Point(s)) and not enlarged.contains(shapely.Point(g)):
                queries.append((s.tolist(), g.tolist()))

        def ask(q):
            return http.post("/routes", json={"start": q[0], "goal": q[1]})

        with concurrent.futures.ThreadPoolExecutor(8) as pool:
            answers = list(pool.map(ask, queries))
        assert all(r.status_code == 201 for r in answers), [r.text for r in answers if r.status_code != 201]
        assert len({r.json()["id"] for r in answers}) == len(queries)
        for (s, g), r in zip(queries, answers):
            expected = sbplan.plan(obstacles, s, g, robot_radius=0.15, bounds=(0, 0, 4, 3))
            assert r.json()["length_m"] == pytest.approx(expected.length, rel=1e-6, abs=2e-6)


def test_a_planning_process_answers_errors_and_its_loss_falls_back_to_the_state_thread(cal):
    with running(cal, planner_processes=1) as (url, service), client(url) as http:
        http.post("/detect", content=SCENE_PNG)
        _is_error(http.post("/routes", json={"start": [1.0, 1.5], "goal": GOAL}), 422, "start-in-obstacle")
        first = http.post("/routes", json={"start": START, "goal": GOAL})
        assert first.status_code == 201 and first.json()["planner"] == "aux-corner"
        (worker,) = service._planners._workers
        worker.proc.kill()
        wait_for(lambda: not service._planners.alive)
        again = http.post("/routes", json={"start": START, "goal": GOAL})
        assert again.status_code == 201, again.text
        assert again.json()["length_m"] == first.json()["length_m"]


def test_a_route_planned_on_a_frame_a_newer_one_replaced_is_checked_against_it(cal):
    # A planning process answers after the state moved on: the route is checked against the newer
    # frame when it is recorded (the newer frame's check of every route missed it).
    from sbplan.service import models

    with running(cal) as (url, service), client(url) as http:
        http.post("/detect", content=EMPTY_PNG)
        old = service.snapshot()
        req = models.RouteRequest(start=START, goal=GOAL)
        straight = sbplan.plan(list(old.obstacles), START, GOAL, robot_radius=0.15, bounds=old.bounds)
        http.post("/detect", content=SCENE_PNG)  # two of its obstacles block the straight line
        model = service._state_submit(service._add_route, req, old, 0.15, straight).result()
        assert model.version == 2 and model.reason == "blocked" and model.length_m > straight.length + 0.1
        assert http.get(f"/routes/{model.id}").json()["version"] == 2


def test_routes_beyond_the_limit_drop_the_least_recently_changed(cal):
    with running(cal, max_routes=3) as (url, _), client(url) as http:
        http.post("/detect", content=EMPTY_PNG)
        ids = [http.post("/routes", json={"start": START, "goal": GOAL}).json()["id"] for _ in range(3)]
        http.post(f"/routes/{ids[0]}/replan", json={"position": START})  # r1 changed last
        ids.append(http.post("/routes", json={"start": START, "goal": GOAL}).json()["id"])
        assert [r["id"] for r in http.get("/routes").json()["routes"]] == [ids[2], ids[0], ids[3]]
        _is_error(http.get(f"/routes/{ids[1]}"), 404, "unknown-route")


# -- a folder as the live source ------------------------------------------------------------------
def test_a_folder_source_is_read_in_order_and_bad_frames_are_skipped(cal, tmp_path):
    folder = tmp_path / "frames"
    folder.mkdir()
    (folder / "01-empty.png").write_bytes(EMPTY_PNG)
    (folder / "02-broken.png").write_bytes(b"this is not a PNG")
    (folder / "03-scene.png").write_bytes(SCENE_PNG)
    (folder / "notes.txt").write_text("not a frame")
    events: list[OutEvent] = []
    with running(cal, source=FolderSource(folder), listeners=[events.append]) as (url, _), client(url) as http:
        wait_for(lambda: any(e.type == "source" for e in events))
        got = [json.loads(e.text) for e in events]
        assert [(e["type"], e.get("name")) for e in got] == [
            ("detection", "01-empty.png"), ("frame-rejected", "02-broken.png"), ("detection", "03-scene.png"),
            ("source", None)]
        assert [e["seq"] for e in got] == [1, 2, 3, 4]
        assert got[1]["code"] == "not-an-image" and got[2]["frame"] == 2
        assert got[3]["state"] == "ended" and got[3]["frames"] == 2 and got[3]["rejected"] == 1
        state = http.get("/state").json()
        assert state["frame"] == 2 and state["name"] == "03-scene.png" and state["source"] == "folder:frames"
        assert len(state["obstacles"]) == 3
        assert http.get("/health").json()["source"] == "folder:frames"


def test_the_listening_socket_says_it_is_tcp():
    """asyncio turns Nagle's algorithm off only on connections of a socket made with IPPROTO_TCP;
    with proto 0 every answer on a kept-alive connection waited about 40 ms for the client's ACK."""
    import socket

    from sbplan.service.server import bind

    sock = bind("127.0.0.1", 0)
    try:
        assert sock.proto == socket.IPPROTO_TCP
    finally:
        sock.close()


def test_the_core_and_the_cli_do_not_import_the_web_stack():
    """FastAPI and uvicorn are the serve extra's: the library and `sbplan --help` work without them."""
    import subprocess
    import sys

    code = ("import sys, sbplan, sbplan.detection, sbplan.planning, sbplan.cli\n"
            "sbplan.cli.build_parser()\n"
            "print(sorted(m for m in sys.modules if m.split('.')[0] in ('fastapi', 'uvicorn', 'starlette')))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


def test_kept_alive_answers_come_whole_a_head_request_and_a_websocket_included(cal, monkeypatch):
    """The server holds each response's head until its body's first write (one write, see
    sbplan.service.onewrite): a HEAD answer (no body is ever written), the answers after it on
    the same connection, a body too large to be joined to its head (the limit lowered so that
    the OpenAPI document is one) and a WebSocket upgrade must still arrive."""
    import socket

    from sbplan.service import onewrite

    monkeypatch.setattr(onewrite, "_JOIN_MAX", 1024)

    def read_answer(sock, buf: bytes, *, body: bool) -> tuple[bytes, bytes, bytes]:
        while b"\r\n\r\n" not in buf:
            chunk = sock.recv(65536)
            assert chunk, "the server closed the connection"
            buf += chunk
        head, _, rest = buf.partition(b"\r\n\r\n")
        length = int(next(v for k, _, v in (h.partition(b": ") for h in head.split(b"\r\n")[1:])
                          if k.lower() == b"content-length"))
        n = length if body else 0
        while len(rest) < n:
            chunk = sock.recv(65536)
            assert chunk, "the server closed the connection"
            rest += chunk
        return head, rest[:n], rest[n:]

    with running(cal) as (url, _):
        host, port = url.removeprefix("http://").rsplit(":", 1)
        with socket.create_connection((host, int(port)), timeout=10) as sock:
            buf = b""
            for method, path in (("GET", "/health"), ("HEAD", "/health"), ("GET", "/openapi.json"),
                                 ("GET", "/health"), ("HEAD", "/health")):
                sock.sendall(f"{method} {path} HTTP/1.1\r\nHost: {host}\r\n\r\n".encode())
                head, body, buf = read_answer(sock, buf, body=method == "GET")
                # (HEAD: the service's routes answer GET only, with a JSON error of some length)
                assert head.startswith(b"HTTP/1.1 200" if method == "GET" else b"HTTP/1.1 405"), head
                assert b"content-length: 0" not in head.lower()
                if path == "/health" and method == "GET":
                    assert json.loads(body)["status"] == "ok"
                elif method == "GET":
                    assert len(body) > 1024 and json.loads(body)["paths"]
            assert buf == b""  # a HEAD answer carries no body
        with ws_connect(url) as ws:
            assert receive(ws, types={"hello"})["type"] == "hello"
