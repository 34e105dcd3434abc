"""The operator's terminal app, driven with Textual's Pilot on the example map maps/paper-8x6.

Real calibration, detection, planning and export run underneath; the tests only press keys,
click, type and read what the screens show.
"""

from __future__ import annotations

import json
import threading
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("textual")
shapely = pytest.importorskip("shapely")

from shapely.geometry import LineString, Polygon  # noqa: E402
from textual.widgets import DataTable, Input, Static  # noqa: E402

from sbplan.tui.app import SbplanApp  # noqa: E402
from sbplan.tui.screens.detection import DetectionScreen  # noqa: E402
from sbplan.tui.screens.help import HelpScreen  # noqa: E402
from sbplan.tui.session import point_along  # noqa: E402
from sbplan.tui.widgets.busy import Busy  # noqa: E402
from sbplan.tui.widgets.mapview import MapView  # noqa: E402

from _tui import (MAP, REPO, aio, error_messages, in_repo,  # noqa: E402,F401 (in_repo: autouse)
                  needs_map, settle, text_of, type_into)

SIZE = (160, 48)

pytestmark = needs_map


@aio
async def test_whole_job_calibrate_detect_plan_replan_export(tmp_path):
    app = SbplanApp(MAP, auto=False, hide_timings=True)
    async with app.run_test(size=SIZE) as pilot:
        await settle(app, pilot)
        assert app.session.reference is not None and app.session.calibration is None
        await pilot.press("c")
        await settle(app, pilot)
        cal = app.session.calibration
        assert (cal.grid.cols, cal.grid.rows) == (8, 6)
        stats = text_of(app, "#cal-stats")
        assert "8 columns × 6 rows" in stats and f"{cal.threshold:.4f}" in stats and "margin" in stats

        # detection: 13 occupied cells and 3 obstacles, in the summary and the table
        await pilot.press("2")
        await pilot.press("d")
        await settle(app, pilot)
        det = app.session.detection
        assert len(det.occupied_cells) == 13 and len(det.obstacles) == 3
        summary = text_of(app, "#det-summary")
        assert "occupied    13 cells" in summary and "obstacles   3" in summary
        table = app.screen.query_one("#obstacles", DataTable)
        assert table.row_count == 3
        assert sorted(int(table.get_row_at(i)[1]) for i in range(3)) == sorted(len(o.cells) for o in det.obstacles)
        assert app.screen.query_one("#timings", DataTable).row_count == len(det.timings_ms)

        # export into a fresh folder with the key binding
        out = tmp_path / "export"
        app.screen.query_one("#export-dir", Input).value = str(out)
        app.screen.query_one(DataTable).focus()
        await pilot.press("e")
        await settle(app, pilot)
        assert (out / "overlay.png").stat().st_size > 0 and (out / "occupancy.png").is_file()
        features = json.loads((out / "obstacles.geojson").read_text())["features"]
        assert len(features) >= 3
        assert "resolution:" in (out / "nav2" / "map.yaml").read_text() and (out / "nav2" / "map.pgm").is_file()

        # plan from the workspace's start to its goal
        await pilot.press("3")
        await pilot.press("p")
        await settle(app, pilot)
        route = app.session.route
        radius = cal.workspace.robot_radius_m
        assert route.status == "exact" and len(route.waypoints) >= 2
        np.testing.assert_allclose(route.waypoints[0], cal.workspace.start_m)
        np.testing.assert_allclose(route.waypoints[-1], cal.workspace.goal_m)
        avoided = [Polygon(p) for p in app.session.obstacles_m()]  # the obstacle model's polygons
        assert min(LineString(route.waypoints).distance(m) for m in avoided) >= radius - 1e-6
        assert f"{route.length:.2f} m" in text_of(app, "#route-info")

        # a dynamic obstacle on the route, ahead of the robot, placed with a click on the map
        view = app.screen.query_one("#map", MapView)
        ahead = point_along(route.waypoints, 0.6)
        col, row = view.frame().to_cell(ahead)[0]
        await pilot.click("#map", offset=(int(col), int(row)))
        await pilot.press("o")
        await settle(app, pilot)
        (square,) = [Polygon(d) for d in app.session.dynamic]
        assert LineString(route.waypoints).intersects(square)  # it does block the old route
        new = app.session.route
        assert app.session.old_route is route and new is not route and new.replanned
        np.testing.assert_allclose(new.waypoints[-1], cal.workspace.goal_m)
        new_line = LineString(new.waypoints)
        assert new_line.distance(square) >= radius - 1e-6
        assert min(new_line.distance(m) for m in avoided) >= radius - 1e-6
        assert view.scene["old_route"] is not None and view.scene["route"] is not None
        assert "old route" in text_of(app, "#route-info")
        assert not error_messages(app)


@aio
async def test_open_a_map_folder_typed_on_the_calibration_screen():
    app = SbplanApp(None, auto=True, hide_timings=True)
    async with app.run_test(size=SIZE) as pilot:
        await pilot.pause()
        assert app.session.reference is None
        await type_into(pilot, "#ref-path", "maps/paper-8x6")
        await pilot.press("enter")
        await settle(app, pilot)  # opens, then calibrates on its own (auto)
        await settle(app, pilot)
        assert app.session.map_dir == Path("maps/paper-8x6")
        assert app.session.calibration is not None and app.session.start is not None
        await pilot.press("2")
        await settle(app, pilot)
        assert app.screen.query_one("#scene-path", Input).value == "maps/paper-8x6/scene-01.png"
        assert len(app.session.detection.occupied_cells) == 13


@aio
async def test_bad_paths_unreadable_images_and_unreachable_goals_leave_the_app_usable(tmp_path):
    junk = tmp_path / "junk.png"
    junk.write_bytes(b"this is not a picture")
    app = SbplanApp(MAP, auto=False, hide_timings=True)
    async with app.run_test(size=SIZE) as pilot:
        await settle(app, pilot)
        # a reference that does not exist
        await type_into(pilot, "#ref-path", str(tmp_path / "missing.png"))
        await pilot.press("enter")
        await settle(app, pilot)
        assert any("missing.png: no such file" in m for m in error_messages(app))
        # an unreadable image
        await type_into(pilot, "#ref-path", str(junk))
        await pilot.press("enter")
        await settle(app, pilot)
        assert any("junk.png: not an image" in m for m in error_messages(app))
        # detection before calibration
        await pilot.press("2")
        await pilot.press("d")
        await settle(app, pilot)
        assert any("calibrate on a reference image first" in m for m in error_messages(app))
        # still usable: open the real reference, calibrate, detect
        await pilot.press("1")
        await type_into(pilot, "#ref-path", "maps/paper-8x6/reference.png")
        await pilot.press("enter")
        await settle(app, pilot)
        app.screen.query_one("#cal-stats").focus()
        await pilot.press("c")
        await settle(app, pilot)
        await pilot.press("2")
        await type_into(pilot, "#scene-path", str(junk))
        await pilot.press("enter")
        await settle(app, pilot)
        assert app.session.detection is None
        await type_into(pilot, "#scene-path", "maps/paper-8x6/scene-01.png")
        await pilot.press("enter")
        await settle(app, pilot)
        det = app.session.detection
        assert len(det.obstacles) == 3

        # a goal inside an obstacle, then a goal walled off by dynamic obstacles
        await pilot.press("3")
        await settle(app, pilot)
        inside = Polygon(app.session.obstacles_m()[0]).representative_point().coords[0]
        await type_into(pilot, "#goal", f"{inside[0]:.3f}, {inside[1]:.3f}")
        await pilot.press("enter")
        app.screen.query_one("#map").focus()
        await pilot.press("p")
        await settle(app, pilot)
        assert any("goal" in m and "inside an obstacle" in m for m in error_messages(app))
        assert app.session.route is None
        await type_into(pilot, "#goal", "not a point")
        await pilot.press("enter")
        assert any("goal: expected two numbers" in m for m in error_messages(app))

        cal = app.session.calibration
        xmin, ymin, xmax, ymax = cal.world_bounds()
        x = (xmin + xmax) / 2
        wall = [[x - 0.05, ymin - 1], [x + 0.05, ymin - 1], [x + 0.05, ymax + 1], [x - 0.05, ymax + 1]]
        app.session.dynamic.append(np.array(wall))
        start, goal = cal.workspace.start_m, cal.workspace.goal_m
        assert (start[0] - x) * (goal[0] - x) < 0  # the wall separates them
        await type_into(pilot, "#goal", f"{goal[0]}, {goal[1]}")
        app.screen.query_one("#map").focus()
        n_errors = len(error_messages(app))
        await pilot.press("p")
        await settle(app, pilot)
        assert len(error_messages(app)) == n_errors + 1 and app.session.route is None
        # clearing the wall makes the goal reachable again
        await pilot.press("x")
        await pilot.press("p")
        await settle(app, pilot)
        assert app.session.route is not None and app.session.route.status == "exact"


@aio
async def test_keys_work_while_a_detection_runs_and_cancel_discards_it(monkeypatch):
    gate = threading.Event()
    entered = threading.Event()
    real = DetectionScreen.run_detection

    def held(self, image):
        # holds the worker thread inside the step until the test lets it go
        entered.set()
        gate.wait(30)
        return real(self, image)

    monkeypatch.setattr(DetectionScreen, "run_detection", held)
    app = SbplanApp(MAP, auto=False, hide_timings=True)
    async with app.run_test(size=SIZE) as pilot:
        await settle(app, pilot)
        await pilot.press("c")
        await settle(app, pilot)
        await pilot.press("2")
        await pilot.press("d")
        await pilot.pause()
        assert entered.wait(30)
        screen = app.screen
        assert screen.busy and screen.query_one(Busy).display
        # the UI answers keys while the worker is busy: help opens and closes, screens switch
        await pilot.press("f1")
        assert isinstance(app.screen, HelpScreen)
        await pilot.press("escape")
        assert app.screen is screen
        await pilot.press("3")
        assert app.current_mode == "route"
        await pilot.press("2")
        assert app.screen is screen and screen.busy
        # cancel: the line says so until the step stops; the result is discarded
        await pilot.press("escape")
        assert "cancelling" in str(screen.query_one("#busy-label", Static).render())
        gate.set()
        await settle(app, pilot)
        assert not screen.query_one(Busy).display
        assert app.session.detection is None
        # and a new detection runs to the end
        await pilot.press("d")
        await settle(app, pilot)
        assert len(app.session.detection.obstacles) == 3


@aio
async def test_command_palette_has_every_action_and_runs_them():
    from sbplan.tui.app import ACTIONS
    from sbplan.tui.screens.calibration import CalibrationScreen
    from sbplan.tui.screens.route import RouteScreen

    app = SbplanApp(MAP, auto=False, hide_timings=True)
    async with app.run_test(size=SIZE) as pilot:
        await settle(app, pilot)
        titles = {c.title for c in app.get_system_commands(app.screen)}
        for title, _, mode, action in ACTIONS:
            assert title in titles
            screen_class = {"calibration": CalibrationScreen, "detection": DetectionScreen,
                            "route": RouteScreen, None: None}[mode]
            if screen_class is not None:
                assert hasattr(screen_class, "action_" + action.split("(")[0]), action
        # every footer binding of the job screens has a palette entry
        bound = {b.action for cls in (CalibrationScreen, DetectionScreen, RouteScreen) for b in cls.BINDINGS}
        assert bound <= {a for *_, a in ACTIONS} | {"detect"}
        # run "Calibrate" from the palette by typing its name
        await pilot.press("ctrl+p")
        await pilot.pause()
        for ch in "Calibrate":
            await pilot.press(ch)
        await pilot.pause(0.3)
        await pilot.press("enter")
        await settle(app, pilot)
        assert app.session.calibration is not None
        # the help screen lists the keys
        await pilot.press("question_mark")
        assert isinstance(app.screen, HelpScreen)
        await pilot.press("escape")
        assert not isinstance(app.screen, HelpScreen)


def test_cli_refuses_a_missing_map_and_a_non_terminal(tmp_path):
    import subprocess
    import sys

    def run(*args):
        return subprocess.run([sys.executable, "-m", "sbplan", "tui", *args], capture_output=True, text=True,
                              cwd=REPO, timeout=60)

    missing = run(str(tmp_path / "nowhere"))
    assert missing.returncode != 0
    assert missing.stderr.strip().splitlines() == [f"sbplan: error: {tmp_path / 'nowhere'}: no such map folder"]
    piped = run("maps/paper-8x6")  # stdout is a pipe here
    assert piped.returncode != 0 and "sbplan: error: tui: standard output is not a terminal" in piped.stderr
