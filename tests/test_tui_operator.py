"""The operator's day in the terminal app (issue 17, items 1-6; issue 14's camera movement),
driven with Textual's Pilot on maps/paper-8x6 and on scenes rendered with a moved camera.

Real calibration, detection, registration and planning run underneath; the tests press keys,
click and read what the screens show.
"""

from __future__ import annotations

import asyncio
import shutil
import threading
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("textual")
pytest.importorskip("shapely")

from shapely.geometry import LineString, Polygon  # noqa: E402
from textual.widgets import Input, ProgressBar, Select  # noqa: E402
from textual.widgets._footer import FooterKey  # noqa: E402

from sbplan.detection.obstacles import DEFAULT_OBSTACLE_MODEL  # noqa: E402
from sbplan.tui.app import SbplanApp  # noqa: E402
from sbplan.tui.screens.base import JobScreen  # noqa: E402
from sbplan.tui.screens.confirm import ConfirmScreen  # noqa: E402
from sbplan.tui.screens.detection import DetectionScreen  # noqa: E402
from sbplan.tui.screens.help import HelpScreen  # noqa: E402
from sbplan.tui.screens.picture import PictureScreen  # noqa: E402
from sbplan.tui.session import point_along  # noqa: E402
from sbplan.tui.widgets.busy import Busy  # noqa: E402
from sbplan.tui.widgets.keys import KeyFooter  # noqa: E402
from sbplan.tui.widgets.mapview import MapView  # noqa: E402
from sbplan.tui.widgets.zoomview import ZoomView  # noqa: E402

from _tui import (MAP, REPO, RunningApp, aio, error_messages, in_repo,  # noqa: E402,F401 (in_repo: autouse)
                  needs_map, settle, text_of, type_into)

#: The terminal size of these tests: what they assert holds at any size, and a small terminal
#: draws quickest (tests/test_tui_snapshots.py keeps the pictures at 80 x 24 and 140 x 45).
SMALL = (80, 24)

pytestmark = needs_map


async def to_route(app, pilot) -> None:
    """With ``auto=True``: calibrated, detected and planned by showing the three screens."""
    await settle(app, pilot)
    await pilot.press("2")
    await settle(app, pilot)
    await pilot.press("3")
    await settle(app, pilot)


def untouched(app) -> bool:
    """The routed app as it was made: no screen over the job screens, no dynamic obstacle, the
    default obstacle model, the route planned from the start and valid."""
    s = app.session
    return (len(app.screen_stack) == 1 and isinstance(app.screen, JobScreen) and not app.screen.running
            and s.route is not None and s.old_route is None
            and s.route_invalid is None and s.dynamic == [] and s.obstacle_model == DEFAULT_OBSTACLE_MODEL)


@pytest.fixture(scope="module")
def _routed_apps():
    apps: list[RunningApp] = []
    yield apps
    for running in apps:
        running.close()


@pytest.fixture
def routed(_routed_apps, monkeypatch) -> RunningApp:
    """maps/paper-8x6 at 80 x 24, calibrated, detected and planned (auto). The tests share one
    while each leaves it :func:`untouched`; a test that changed it hands the next a new one."""
    monkeypatch.chdir(REPO)
    if not _routed_apps or not untouched(_routed_apps[-1].app):
        if _routed_apps:
            _routed_apps.pop().close()
        running = RunningApp(SbplanApp(MAP, auto=True, hide_timings=True), SMALL)
        _routed_apps.append(running)
        running.run(to_route)
        assert untouched(running.app)
    return _routed_apps[-1]


# -- 1: progress and cancel --------------------------------------------------------------------------
@aio
async def test_progress_shows_above_the_footer_and_cancel_stops_the_calibration(monkeypatch):
    held, gate = threading.Event(), threading.Event()
    stages: list[tuple[str, float | None]] = []
    real = JobScreen._progress

    def holding(self, worker, token, label, stage, fraction):
        stages.append((stage, fraction))
        real(self, worker, token, label, stage, fraction)  # shown on screen (or Cancelled raised)
        if stage == "fitting the grid" and not held.is_set():
            held.set()  # hold the calibration's thread right after it said where it is
            gate.wait(60)

    monkeypatch.setattr(JobScreen, "_progress", holding)
    app = SbplanApp(MAP, auto=False, hide_timings=True)
    async with app.run_test(size=SMALL) as pilot:
        await settle(app, pilot)
        stages.clear()
        await pilot.press("c")
        assert await asyncio.to_thread(held.wait, 60)
        await pilot.pause()
        screen = app.screen
        busy, footer = screen.query_one(Busy), screen.query_one(KeyFooter)
        # the line is on screen, above the footer, with the stage, the share done and Cancel
        assert busy.display and busy.region.height == 1 and busy.region.bottom <= footer.region.y
        assert "calibrating with" in text_of(app, "#busy-label") and "fitting the grid" in text_of(app, "#busy-label")
        assert screen.query_one("#busy-bar", ProgressBar).percentage == pytest.approx(0.25)
        cancel = screen.query_one("#busy-cancel")
        assert cancel.region.right <= SMALL[0] and cancel.region.y == busy.region.y
        await pilot.click("#busy-cancel")
        assert "cancelling" in text_of(app, "#busy-label")
        gate.set()
        await settle(app, pilot)
        # the calibration stopped at its next stage: nothing after it ran, nothing was kept
        names = [s for s, _ in stages]
        assert names[-2:] == ["fitting the grid", "measuring the symbols' outlines"]
        assert app.session.calibration is None and not busy.display
        assert any("cancelled" in n.message for n in app._notifications)
        # run to the end: stages in order, the share done rising to 1
        stages.clear()
        await pilot.press("c")
        await settle(app, pilot)
        assert app.session.calibration is not None
        fractions = [f for _, f in stages]
        assert fractions == sorted(fractions) and fractions[-1] == 1.0 and len(stages) >= 8


# -- 3: outputs follow the map, overwriting asks ----------------------------------------------------------
async def asked(app, pilot, named: str) -> None:
    await pilot.pause()
    assert isinstance(app.screen, ConfirmScreen) and named in text_of(app, "#confirm-question")


@aio
async def test_outputs_follow_the_map_and_overwriting_asks_first(tmp_path, monkeypatch):
    """What the operator reported: paper-8x6 calibrated and saved, then the crowded map opened,
    calibrated and saved with ctrl+s: that wrote over out/paper-8x6/calibration.json."""
    from sbplan.detection.calibration import load_calibration

    monkeypatch.chdir(tmp_path)  # out/ is made here
    paper_cal, paper_out = Path("out/paper-8x6/calibration.json"), Path("out/paper-8x6")
    paper_cal.parent.mkdir(parents=True)
    paper_cal.write_text("keep me")
    (paper_out / "overlay.png").write_text("old")
    app = SbplanApp(MAP, auto=False, hide_timings=True)
    async with app.run_test(size=SMALL) as pilot:
        await settle(app, pilot)
        assert app.screen.query_one("#cal-path", Input).value == str(paper_cal)
        await pilot.press("c")
        await settle(app, pilot)
        # saving over an existing file asks; "n" keeps it, "y" writes
        await pilot.press("ctrl+s")
        await asked(app, pilot, "calibration.json")
        await pilot.press("n")
        await settle(app, pilot)
        assert paper_cal.read_text() == "keep me"
        await pilot.press("ctrl+s")
        await asked(app, pilot, "calibration.json")
        await pilot.press("y")
        await settle(app, pilot)
        assert load_calibration(paper_cal).grid.shape == (6, 8)
        # exporting into a folder that has the files asks too
        await pilot.press("2")
        await settle(app, pilot)
        assert app.screen.query_one("#export-dir", Input).value == str(paper_out)
        await pilot.press("d")
        await settle(app, pilot)
        await type_into(pilot, "#export-dir", str(paper_out))
        await pilot.press("enter")
        await asked(app, pilot, "overlay.png")
        await pilot.press("escape")
        await settle(app, pilot)
        assert (paper_out / "overlay.png").read_text() == "old" and not (paper_out / "obstacles.geojson").exists()
        # another map: its outputs go to its own folder, the first map's calibration stays
        await pilot.press("1")
        await type_into(pilot, "#ref-path", str(REPO / "maps" / "crowded"))
        await pilot.press("enter")
        await settle(app, pilot)
        assert app.session.map_dir == REPO / "maps" / "crowded" and app.session.calibration is None
        assert app.screen.query_one("#cal-path", Input).value == "out/crowded/calibration.json"
        await pilot.press("2")
        assert app.screen.query_one("#export-dir", Input).value == "out/crowded"
        await pilot.press("1")
        await pilot.press("c")
        await settle(app, pilot)
        await pilot.press("ctrl+s")  # nothing there yet: written without asking
        await settle(app, pilot)
        assert load_calibration("out/crowded/calibration.json").grid.shape == (9, 12)
        assert load_calibration(paper_cal).grid.shape == (6, 8)
        assert not error_messages(app)


# -- 4, 5 and 2 share one app on a planned route (``routed``), in this order: 2 changes its route ----------------

# -- 4: 80 x 24 ---------------------------------------------------------------------------------------------
def test_at_80x24_every_key_is_seen_the_panel_goes_below_help_scrolls_and_zoom_reads_numbers(routed):
    routed.run(at_80x24)


async def at_80x24(app, pilot) -> None:
    for mode in ("calibration", "detection", "route"):
        await app.switch_mode(mode)
        await pilot.pause()
        screen = app.screen
        keys = list(screen.query(FooterKey))
        (palette,) = [k for k in keys if k.has_class("-command-palette")]
        shown = {b.action for _, b, _, _ in screen.active_bindings.values() if b.show}
        assert shown <= {k.action for k in keys}, mode
        for k in keys:
            assert k.region.width > 0 and k.region.right <= SMALL[0] and k.region.bottom <= SMALL[1], (mode, k.key)
            if k is not palette and k.region.y == palette.region.y:
                assert k.region.right <= palette.region.x, (mode, k.key)
        main, side = screen.query_one(".main"), screen.query_one(".side")
        assert side.region.width == SMALL[0] and side.region.y >= main.region.bottom, mode
        assert main.region.height >= 8 and side.region.height >= 5, mode
    # help fits the width and scrolls
    await pilot.press("f1")
    assert isinstance(app.screen, HelpScreen)
    box = app.screen.query_one("#help")
    assert box.region.right <= SMALL[0] and box.max_scroll_y > 0
    await pilot.press("pagedown")
    for _ in range(100):  # the scroll is animated: a loaded machine takes its time
        if box.scroll_y > 0:
            break
        await pilot.pause(0.05)
    assert box.scroll_y > 0
    await pilot.press("escape")
    # the detection picture full screen: obstacle numbers are text, at any zoom
    await app.switch_mode("detection")
    await pilot.press("f")
    await pilot.pause()
    assert isinstance(app.screen, PictureScreen)
    zoom = app.screen.query_one(ZoomView)
    assert zoom.region.width == SMALL[0] and zoom.region.height >= SMALL[1] - 3

    def labels() -> set[str]:
        text = "".join(zoom.render_line(y).text for y in range(zoom.size.height))
        return {ch for ch in text if ch.isdigit()}

    assert labels() == {"1", "2", "3"}
    await pilot.press("plus")
    await pilot.press("plus")
    assert zoom.zoom == pytest.approx(2.25) and labels() and labels() <= {"1", "2", "3"}
    await pilot.press("0")
    assert zoom.zoom == 1.0 and labels() == {"1", "2", "3"}
    await pilot.press("escape")
    assert isinstance(app.screen, DetectionScreen)


# -- 5: the obstacle model ------------------------------------------------------------------------------------
def test_the_obstacle_model_has_the_cli_names_and_routes_follow_it(routed):
    import argparse

    from sbplan.cli import build_parser

    plan_parser = next(a for a in build_parser("plan")._actions
                       if isinstance(a, argparse._SubParsersAction)).choices["plan"]
    cli_names = next(a for a in plan_parser._actions if "--obstacle-model" in a.option_strings).choices

    async def body(app, pilot):
        await app.switch_mode("route")
        await pilot.pause()
        s, view = app.session, app.screen.query_one("#map", MapView)
        select = app.screen.query_one("#obstacle-model", Select)
        assert [value for _, value in select._options] == list(cli_names) == ["mar", "parts", "outline"]
        assert select.value == DEFAULT_OBSTACLE_MODEL == s.obstacle_model == "parts"
        radius = s.calibration.workspace.robot_radius_m
        routes = {}
        # m cycles the models in the CLI's order, the list shows the one in use, the route follows
        for model in ("outline", "mar", "parts"):
            before = s.route
            await pilot.press("m")
            await settle(app, pilot)
            assert s.obstacle_model == model == select.value and s.route is not before, model
            avoided = [Polygon(p) for ob in s.detection.obstacles for p in ob.polygons_m(model)]
            assert [Polygon(p).equals(a) for p, a in zip(s.obstacles_m(), avoided)] == [True] * len(avoided), model
            assert [Polygon(p).equals(a) for p, a in zip(view.scene["obstacles"], avoided)] == [True] * len(avoided)
            assert len(view.scene["clearance"]) >= 1, model
            assert min(LineString(s.route.waypoints).distance(a) for a in avoided) >= radius - 1e-6, model
            routes[model] = s.route.length
        # an outline lies inside its MAR and inside its parts: the route around outlines is never longer
        assert routes["outline"] <= min(routes["mar"], routes["parts"]) + 1e-9
        # chosen in the list: the same
        select.value = "outline"
        await settle(app, pilot)
        assert s.obstacle_model == "outline" and s.route.length == pytest.approx(routes["outline"])
        select.value = "parts"
        await settle(app, pilot)
        assert s.obstacle_model == "parts" and s.route.length == pytest.approx(routes["parts"])

    routed.run(body)


# -- 2: a stale route, clearing, duplicates -------------------------------------------------------------
def test_a_blocked_route_is_marked_invalid_x_replans_and_an_obstacle_counts_once(routed):
    routed.run(blocked_route)


async def blocked_route(app, pilot) -> None:
    await app.switch_mode("route")
    await pilot.pause()
    s, view = app.session, app.screen.query_one("#map", MapView)
    first = s.route
    view.set_cursor(point_along(first.waypoints, 0.6))
    await pilot.press("o")
    await settle(app, pilot)
    detour = s.route
    assert detour is not first and detour.replanned
    (square,) = [Polygon(d) for d in s.dynamic]
    # the same obstacle again is one obstacle: nothing changes
    await pilot.press("o")
    await settle(app, pilot)
    assert len(s.dynamic) == 1 and s.route is detour
    # x: the obstacle goes, and the route is planned again from the robot, through where it was
    robot = s.robot_position()
    remaining = detour.length - LineString(detour.waypoints).project(LineString([robot, robot]).centroid)
    await pilot.press("x")
    await settle(app, pilot)
    assert s.dynamic == [] and s.old_route is detour
    np.testing.assert_allclose(s.route.waypoints[0], robot)
    assert LineString(s.route.waypoints).intersects(square) and s.route.length < remaining - 1e-6
    # an obstacle on the goal: replanning fails, the route is marked invalid and drawn as blocked
    n_errors = len(error_messages(app))
    view.set_cursor(s.goal)
    await pilot.press("o")
    await settle(app, pilot)
    assert len(error_messages(app)) == n_errors + 1 and "inside an obstacle" in error_messages(app)[-1]
    assert s.route_invalid and "replanning failed" in s.route_invalid
    assert "route INVALID" in text_of(app, "#route-info")
    assert view.scene["route"] is None and view.scene["blocked_route"] is not None
    # clearing it makes the route valid again
    await pilot.press("x")
    await settle(app, pilot)
    assert s.route_invalid is None and view.scene["route"] is not None
    assert "INVALID" not in text_of(app, "#route-info")


# -- issue 14: the camera's movement, its warning, re-anchoring, the error --------------------------------------
@pytest.fixture(scope="module")
def moved_map(tmp_path_factory):
    """maps/paper-8x6's reference and workspace; scene-01 with the camera moved by 3 px, -2 px and
    0.3 deg (over the warning level), scene-02 moved by 40 % of a pitch (beyond what detection accepts)."""
    from sbplan.imageio import write_image
    from sbplan.synth import render_scene
    from sbplan.synth.maps import recipe

    folder = tmp_path_factory.mktemp("moved") / "paper-moved"
    folder.mkdir()
    for name in ("reference.png", "workspace.toml"):
        shutil.copy(MAP / name, folder / name)
    rec = recipe("paper-8x6")
    ((scene, _),) = rec.scenes
    for name, motion in (("scene-01.png", (3.0, -2.0, 0.3, 1.0)), ("scene-02.png", (0.0, 38.0, 0.0, 1.0))):
        image, _ = render_scene(rec.floor, replace(scene, effects={**dict(scene.effects), "motion": motion}), seed=1)
        write_image(folder / name, image)
    return folder


@aio
async def test_camera_movement_is_shown_warned_and_reanchored_and_too_much_is_a_clear_error(moved_map, monkeypatch):
    from sbplan.detection.calibration import load_calibration

    monkeypatch.chdir(moved_map.parent)  # outputs go to out/paper-moved/ in the temporary folder
    app = SbplanApp(moved_map.name, auto=True, hide_timings=True)
    async with app.run_test(size=SMALL) as pilot:
        await settle(app, pilot)  # opened and calibrated on its own
        await pilot.press("2")  # detects on its own on first show
        await settle(app, pilot)
        s = app.session
        det = s.detection
        assert len(det.occupied_cells) == 13 and len(det.obstacles) == 3
        cam = det.camera
        assert cam.shift_px[0] == pytest.approx(3.0, abs=0.3) and cam.warning
        summary = text_of(app, "#det-summary")
        assert f"{cam.shift_px[0]:+.2f}" in summary and f"{cam.rotation_deg:+.3f}°" in summary
        assert f"{cam.symbols_used} symbols" in summary and f"residual  {cam.residual_px:.2f} px" in summary
        assert cam.warning[:40] in summary.replace("\n", " ")
        assert any(n.severity == "warning" and "camera moved" in n.title for n in app._notifications)
        # re-anchor: measured, then asked before the calibration file is written
        target = Path("out/paper-moved/calibration.json")
        await pilot.press("a")
        await settle(app, pilot)
        assert isinstance(app.screen, ConfirmScreen)
        question = text_of(app, "#confirm-question")
        assert "camera: shift (+3.0" in question and "out/paper-moved/calibration.json" in question
        await pilot.press("n")
        await settle(app, pilot)
        assert not target.exists() and s.detection is det
        await pilot.press("a")
        await settle(app, pilot)
        await pilot.press("y")
        await settle(app, pilot)
        assert target.is_file() and load_calibration(target).stats["updates"]
        assert s.calibration is not det.calibration and s.calibration_path == target
        # detected again from the new pose: the same cells, no movement left
        new = s.detection
        assert new is not None and new is not det and len(new.occupied_cells) == 13
        assert abs(new.camera.shift_px[0]) < 0.3 and not new.camera.warning
        # a camera moved too far: a clear error, the app stays usable
        await type_into(pilot, "#scene-path", str(moved_map.name + "/scene-02.png"))
        await pilot.press("enter")
        await settle(app, pilot)
        assert s.detection is None
        assert "camera moved" in error_messages(app)[-1] or "camera's movement" in error_messages(app)[-1]
        assert "re-anchor" in error_messages(app)[-1] and "calibrate again" in error_messages(app)[-1]
        assert "camera moved: no detection" in text_of(app, "#det-summary")
        await type_into(pilot, "#scene-path", str(moved_map.name + "/scene-01.png"))
        await pilot.press("enter")
        await settle(app, pilot)
        assert len(s.detection.occupied_cells) == 13


# -- tables: drawn at their final column widths from the first paint --------------------------------------------
@aio
async def test_a_table_is_drawn_at_its_final_column_widths_from_the_first_paint():
    """A DataTable sized its columns only when it next went idle; a paint before that (a busy
    machine) drew, and its line cache kept, the header at the labels' widths over wider cells."""
    from textual.app import App
    from textual.widgets import DataTable

    from sbplan.tui.widgets.tables import fill_table

    class OneTable(App):
        def compose(self):
            yield DataTable()

    app = OneTable()
    async with app.run_test(size=(40, 6)) as pilot:
        table = app.query_one(DataTable)
        fill_table(table, ("size m", "id"), [("1.50×1.00", "1"), ("0.5", "12")], keys=["a", "b"])
        header = table.render_line(0).text  # painted before the table went idle
        await pilot.pause()
        assert table.render_line(0).text == header
        assert header.index("id") == table.render_line(1).text.index("1 ", len(" 1.50×1.00"))
        assert [table.get_row("b")[0], table.row_count] == ["0.5", 2]
        fill_table(table, ("stage", "ms"), [])  # emptied: the labels only
        assert table.row_count == 0 and table.render_line(0).text.split() == ["stage", "ms"]
        with pytest.raises(ValueError, match="rows"):
            fill_table(table, ("stage", "ms"), [("binarize",)])
