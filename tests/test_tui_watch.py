"""The TUI's watch mode, driven with Textual's Pilot on a rendered stream (MJPG AVI read by OpenCV)."""

from __future__ import annotations

import asyncio
import functools

import pytest

pytest.importorskip("textual")

from textual.widgets import Checkbox, DataTable, Log, Static  # noqa: E402

from sbplan.synth import FloorSpec  # noqa: E402
from sbplan.synth.sequence import demo_sequence, write_sequence  # noqa: E402
from sbplan.tui.app import SbplanApp  # noqa: E402
from sbplan.tui.screens.watch import WatchScreen  # noqa: E402
from sbplan.tui.widgets.picture import Picture  # noqa: E402

SIZE = (160, 48)
FLOOR = FloorSpec(width=320, height=240, cols=6, rows=4)


def aio(fn):
    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        return asyncio.run(fn(*args, **kwargs))
    return wrapper


@pytest.fixture(scope="module")
def stream_map(tmp_path_factory):
    folder = tmp_path_factory.mktemp("watch-map")
    write_sequence(folder, FLOOR, demo_sequence(FLOOR, n_frames=30, hysteresis=3), seed=4, kind="avi")
    return folder


def status(app) -> str:
    return str(app.screen.query_one("#watch-status", Static).render())


@aio
async def test_watch_mode_shows_the_stream_pauses_and_replans(stream_map, monkeypatch):
    monkeypatch.chdir(stream_map)
    app = SbplanApp(stream_map, auto=False, hide_timings=True)
    async with app.run_test(size=SIZE) as pilot:
        await pilot.pause()
        await app.workers.wait_for_complete()
        await pilot.press("c")  # calibrate on the stream's reference
        await pilot.pause()
        await app.workers.wait_for_complete()
        cal = app.session.calibration
        assert cal is not None
        # a route across row 2, where an obstacle slides
        (sx, sy), (gx, gy) = cal.pixels_to_world(cal.grid.centres_px[2, [0, -1]])
        app.session.start, app.session.goal = (float(sx), float(sy)), (float(gx), float(gy))
        await pilot.press("w")
        await pilot.pause()
        screen = app.screen
        assert isinstance(screen, WatchScreen)
        assert screen.query_one("#watch-source").value == "sequence.avi"  # the map's stream, found
        # every frame, as fast as it goes (a replay at the stream's rate could drop frames on a busy
        # machine); start (w) and pause (space) at once, so that the stream cannot end in between
        screen.query_one("#watch-realtime", Checkbox).value = False
        screen.action_toggle_watch()
        screen.action_pause()
        await pilot.pause(0.3)
        assert screen.watcher.paused and status(app).startswith("paused")
        frozen = screen.watcher.state.frame
        await pilot.pause(0.5)
        assert screen.watcher.state.frame == frozen  # nothing taken while paused
        await pilot.press("r")  # replan on the next frame
        await pilot.press("space")  # resume, with the key
        assert not screen.watcher.paused
        await app.workers.wait_for_complete()
        await pilot.pause()
        screen._refresh(force=True)
        text = status(app)
        assert text.startswith("ended: ended") and "28 processed, 0 dropped, 1 corrupt" in text, text
        log = "\n".join(screen.query_one("#watch-log", Log).lines)
        assert "obstacle 1 appeared: (0,0) (0,1)" in log and "obstacle 2 left" in log and "route" in log
        assert screen.query_one("#watch-obstacles", DataTable).row_count == 1  # obstacle 1 stays to the end
        picture = screen.query_one("#watch-picture", Picture)
        assert picture.query_one(".image").display
        state = screen.watcher.state
        assert state.route is not None and state.frame == 28
        # after the end: start again is possible, replan is refused with a message
        await pilot.press("r")
        await pilot.pause()
        assert any("start watching first" in n.message for n in app._notifications)
        await pilot.press("escape")
        await pilot.pause()
        assert not isinstance(app.screen, WatchScreen)


@aio
async def test_watch_without_calibration_says_so(stream_map, monkeypatch):
    monkeypatch.chdir(stream_map)
    app = SbplanApp(stream_map, auto=False, hide_timings=True)
    async with app.run_test(size=SIZE) as pilot:
        await pilot.press("w")
        await pilot.pause()
        await pilot.press("w")
        await pilot.pause()
        assert any("calibrate" in n.message for n in app._notifications if n.severity == "error")
        assert app.screen.watcher is None
