"""Watch mode: a camera stream, live. The picture, the stable obstacles and the route update as the
stream changes; the status shows frames per second, latency, dropped frames and the camera's
movement. The pipeline is :class:`sbplan.live.Watcher`, run in a thread worker; this screen only
shows its state and events."""

from __future__ import annotations

import collections
from pathlib import Path
from typing import TYPE_CHECKING, Any

from textual import work
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical, VerticalScroll
from textual.screen import Screen
from textual.widgets import Button, Checkbox, DataTable, Footer, Header, Label, Log, Static
from textual.worker import get_current_worker

from ...detection.registration import signed
from ...errors import InputError
from ...live import Watcher, open_source, paced
from ...live.overlay import live_overlay
from ..session import display_path
from ..widgets.path_input import PathInput
from ..widgets.picture import Picture
from ..widgets.tables import fill_table

if TYPE_CHECKING:
    from textual import getters

    from ...live.watcher import Event
    from ..app import SbplanApp
    from ..session import Session

LEGEND = "[#e62828]▆ occupied cells[/]  [#ffdc00]▢ obstacles (MARs) with ids[/]  [#3cc83c]━ route S → G[/]"
#: Seconds between redraws of the picture and the status while watching.
REFRESH_S = 0.25
#: Event lines kept in the log.
LOG_LINES = 200
#: the columns of the obstacle table
WATCH_COLUMNS = ("id", "cells", "centre m")


def default_source(map_dir: Path | None) -> str:
    """The map folder's stream (sequence.avi or frames/, as ``sbplan synth --sequence`` writes), if any."""
    if map_dir is None:
        return ""
    for name in ("sequence.avi", "frames"):
        if (map_dir / name).exists():
            return display_path(map_dir / name)
    return ""


def event_line(e: Event) -> str:
    """One event as a short line for the log."""
    at = f"#{e['frame']:<5}" if e.get("frame") is not None else "      "
    kind = e["type"]
    if kind.startswith("obstacle_"):
        ob = e["obstacle"]
        cells = " ".join(f"({r},{c})" for r, c in ob["cells"])
        return f"{at} obstacle {ob['id']} {kind[9:]}: {cells}"
    if kind == "camera_moved":
        if not e["registered"]:
            return f"{at} camera lost: {e['error']}"
        cam = e["camera"]
        return (f"{at} camera moved: shift ({cam['shift_px'][0]:+.1f}, {cam['shift_px'][1]:+.1f}) px, "
                f"rotation {cam['rotation_deg']:+.2f} deg")
    if kind == "route":
        if e["route"] is None:
            return f"{at} no route: {e['reason']}"
        return (f"{at} route {e['route']['length_m']:.2f} m, {len(e['route']['waypoints_m'])} waypoints"
                f"{' (replan)' if e['incremental'] else ''}")
    if kind == "stalled":
        return f"{at} stalled: no frame for {e['since_last_frame_s']:.1f} s"
    if kind == "reconnected":
        return f"{at} reconnected after {e['down_s']:.1f} s{' (reopened)' if e['reopened'] else ''}"
    if kind == "ended":
        return f"{at} ended: {e['reason']}{': ' + e['error'] if e['error'] else ''}"
    return f"{at} {kind}"


class WatchScreen(Screen):
    """``w`` on any screen: watch a video, image folder, camera index or URL with the session's
    calibration; start and goal (route screen, or the map's workspace) give the route."""

    CSS_PATH = "watch.tcss"
    TITLE = "sbplan"
    SUB_TITLE = "watch"
    BINDINGS = [
        Binding("w", "toggle_watch", "Start/stop"),
        Binding("space", "pause", "Pause"),
        Binding("r", "replan", "Replan"),
        Binding("escape", "leave", "Back"),
    ]

    if TYPE_CHECKING:  # the app this screen runs in (Textual's own pattern; it types it as any App)
        app = getters.app(SbplanApp)

    def __init__(self, source: str | None = None, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self._source = source
        self.watcher: Watcher | None = None
        # events from the worker, drained by the refresh timer: the pipeline never waits for the screen
        self._inbox: collections.deque[Event] = collections.deque()
        self._shown_frame: int | None = None
        self._ended: Event | None = None

    @property
    def session(self) -> Session:
        return self.app.session

    @property
    def running(self) -> Watcher | None:
        """The watcher while it watches (None before the first start and once it ended)."""
        return self.watcher if self._ended is None else None

    @property
    def watching(self) -> bool:
        return self.running is not None

    @property
    def paused(self) -> bool:
        return self.watcher is not None and self.watcher.paused

    def compose(self) -> ComposeResult:
        yield Header()
        with Horizontal(classes="body"):
            with Vertical(classes="main"):
                yield Picture("not watching: give a source and press w", id="watch-picture")
                yield Static(LEGEND, classes="legend")
            with VerticalScroll(classes="side"):
                yield Label("Source", classes="heading")
                yield PathInput(self._source if self._source is not None else default_source(self.session.map_dir),
                                suffixes=(".avi", ".mp4", ".mkv", ".mov"),
                                placeholder="video, image folder, camera index or URL", id="watch-source")
                yield Checkbox("replay a file at its own rate", value=True, id="watch-realtime", compact=True)
                yield Button("Start / stop (w)", id="watch-toggle", variant="primary", compact=True)
                yield Static("not watching", id="watch-status")
                yield Label("Obstacles", classes="heading")
                yield DataTable(id="watch-obstacles", cursor_type="none", zebra_stripes=True)
                yield Label("Events", classes="heading")
                yield Log(id="watch-log", max_lines=LOG_LINES)
        yield Footer()

    def on_mount(self) -> None:
        fill_table(self.query_one("#watch-obstacles", DataTable), WATCH_COLUMNS, [])
        self.set_interval(REFRESH_S, self._refresh)

    def on_unmount(self) -> None:
        if self.watcher is not None:
            self.watcher.stop()

    # -- actions ---------------------------------------------------------------------------------
    def action_toggle_watch(self) -> None:
        running = self.running
        if running is not None:
            running.stop()
            return
        s = self.session
        try:
            cal = s.require_calibration()
            source = self.query_one("#watch-source", PathInput).value.strip()
            if not source:
                raise InputError("source: type a video file, image folder, camera index or URL")
            start, goal = (s.start, s.goal) if s.start is not None and s.goal is not None else (None, None)
            src = open_source(source)
            if not src.live and self.query_one("#watch-realtime", Checkbox).value:
                src = paced(src)  # as the camera delivered it: the latest frame, drops counted
            self.watcher = watcher = Watcher(src, cal, start=start, goal=goal, keep_image=True)
        except Exception as exc:  # noqa: BLE001  (shown to the operator; the app stays usable)
            self.app.report_error(exc)
            return
        self._ended, self._shown_frame = None, None
        self._inbox.clear()
        self.query_one("#watch-log", Log).clear()
        self._run(watcher)

    def action_pause(self) -> None:
        running = self.running
        if running is None:
            return
        if running.paused:
            running.resume()
        else:
            running.pause()
        self._refresh(force=True)

    def action_replan(self) -> None:
        s = self.session
        running = self.running
        if running is None:
            self.app.report_error(InputError("replan: start watching first (w)"))
            return
        if s.start is None or s.goal is None:
            self.app.report_error(InputError("start/goal: set both on the route screen (3) first"))
            return
        running.replan(s.start, s.goal)
        self.notify("the route is planned again on the next frame", title="replan")

    def action_leave(self) -> None:
        running = self.running
        if running is not None:
            running.stop()
        self.app.pop_screen()

    def on_button_pressed(self, event: Button.Pressed) -> None:
        if event.button.id == "watch-toggle":
            self.action_toggle_watch()

    def on_input_submitted(self, event: PathInput.Submitted) -> None:
        self.set_focus(None)
        if event.input.id == "watch-source" and not self.watching:
            self.action_toggle_watch()

    # -- the worker ------------------------------------------------------------------------------
    @work(thread=True, exclusive=True, group="watch", exit_on_error=False)
    def _run(self, watcher: Watcher) -> None:
        worker = get_current_worker()
        try:
            for event in watcher.events():
                if worker.is_cancelled or not self.app.is_running:
                    watcher.stop()
                self._inbox.append(event)
        except Exception as exc:  # noqa: BLE001  (a bug: shown, the app stays usable)
            if self.app.is_running:
                self.app.call_from_thread(self.app.report_error, exc)

    def _event(self, event: Event) -> bool:
        """Show one event; True when the picture should be redrawn."""
        self.query_one("#watch-log", Log).write_line(event_line(event))
        if event["type"] == "ended":
            self._ended = event
            if event["error"]:
                self.notify(event["error"], title="watch ended", severity="error", timeout=10)
        return event["type"].startswith("obstacle_") or event["type"] in ("route", "ended")

    # -- view ------------------------------------------------------------------------------------
    def _refresh(self, force: bool = False) -> None:
        w = self.watcher
        status = self.query_one("#watch-status", Static)
        if w is None:
            return
        while self._inbox:
            force = self._event(self._inbox.popleft()) or force
        state = w.state
        stats = w.stats()
        if state.image is not None and (force or state.frame != self._shown_frame):
            self._shown_frame = state.frame
            self.query_one("#watch-picture", Picture).show(live_overlay(state.image, state, w.calibration))
        if self._ended is not None:
            mode = f"ended: {self._ended['reason']}"
        else:
            mode = "paused" if self.paused else "watching"
        cam = state.camera
        if state.camera_error:
            camera = "lost (recalibrate)"
        elif cam is None or cam.model == "none":
            camera = "-"
        else:
            camera = f"({signed(cam.shift_px[0], 1)}, {signed(cam.shift_px[1], 1)}) px {signed(cam.rotation_deg, 2)}°"
        lat = stats["latency_ms"]
        hide = self.app.hide_timings
        fps = "···" if hide or stats["fps"] is None else f"{stats['fps']:.1f}"
        latency = "···" if hide or lat is None else f"{lat['median']:.0f} / {lat['p99']:.0f} ms"
        route = "-"
        if state.route is not None:
            route = f"{state.route.length:.2f} m"
        elif state.route_error:
            route = f"none ({state.route_error})"
        status.update(
            f"{mode}\n"
            f"frame       {'-' if state.frame is None else state.frame}\n"
            f"fps         {fps}\n"
            f"latency     {latency} (median / p99)\n"
            f"frames      {stats['frames_processed']} processed, {stats['frames_dropped']} dropped, "
            f"{stats['frames_corrupt']} corrupt\n"
            f"camera      {camera}\n"
            f"obstacles   {len(state.obstacles)}\n"
            f"route       {route}")
        table = self.query_one("#watch-obstacles", DataTable)
        rows = [(str(ob.id), " ".join(f"({r},{c})" for r, c in ob.cells),
                 "-" if ob.mar_m is None else f"{ob.mar_m.mean(axis=0)[0]:.2f},{ob.mar_m.mean(axis=0)[1]:.2f}")
                for ob in state.obstacles]
        if [tuple(table.get_row_at(i)) for i in range(table.row_count)] != rows:
            fill_table(table, WATCH_COLUMNS, rows)
