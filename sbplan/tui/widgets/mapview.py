"""The workspace map, drawn with braille dots: obstacles, start, goal, robot, old and new route."""

from __future__ import annotations

import numpy as np
from rich.style import Style
from rich.text import Text
from textual import events
from textual.binding import Binding
from textual.message import Message
from textual.widget import Widget

from ..render import BrailleCanvas, MapFrame

#: bottom first; the top layer with a dot in a cell gives the cell its colour
LAYERS = ("grid", "obstacle", "old_route", "dynamic", "blocked_route", "route", "marker", "cursor")
# explicit colours: the theme's ANSI red and magenta look alike, and dynamic obstacles must stand out
STYLES = {
    "grid": Style(color="grey42"),
    "obstacle": Style(color="#e04040", bold=True),
    "old_route": Style(color="#ffb000"),
    "dynamic": Style(color="#b070ff", bold=True),
    "blocked_route": Style(color="#ff4040", bold=True),
    "route": Style(color="#40e040", bold=True),
    "marker": Style(color="black", bgcolor="cyan", bold=True),
    "cursor": Style(color="black", bgcolor="white", bold=True),
}


class MapView(Widget, can_focus=True):
    """The floor in world metres (x right, y up), scaled to the widget.

    Arrow keys move the cursor by one terminal cell, shift+arrows by a grid pitch; a click puts
    the cursor where it lands. The screen sets what is drawn with :meth:`draw`.
    """

    BINDINGS = [
        Binding("left", "move(-1, 0)", "cursor", show=False),
        Binding("right", "move(1, 0)", "cursor", show=False),
        Binding("up", "move(0, -1)", "cursor", show=False),
        Binding("down", "move(0, 1)", "cursor", show=False),
        Binding("shift+left", "jump(-1, 0)", show=False),
        Binding("shift+right", "jump(1, 0)", show=False),
        Binding("shift+up", "jump(0, 1)", show=False),
        Binding("shift+down", "jump(0, -1)", show=False),
    ]

    class CursorMoved(Message):
        """The cursor moved to ``xy`` (world metres)."""

        def __init__(self, xy: tuple[float, float]) -> None:
            super().__init__()
            self.xy = xy

    def __init__(self, **kwargs) -> None:
        super().__init__(**kwargs)
        self.bounds: tuple[float, float, float, float] | None = None
        self.pitch: tuple[float, float] = (1.0, 1.0)
        self.scene: dict = {}
        self.cursor: np.ndarray | None = None

    # -- what to draw ----------------------------------------------------------------------------
    def draw(self, *, bounds, pitch, obstacles=(), dynamic=(), route=None, old_route=None, blocked_route=None,
             start=None, goal=None, robot=None, clearance=()) -> None:
        """Set the map's content (all world metres, ``(x, y)``) and repaint. ``blocked_route`` is
        a route that can no longer be driven: drawn dotted in red instead of as the route.
        ``clearance``: rings drawn as dotted lines around the obstacles (the planner's enlargement
        by the robot radius)."""
        self.bounds, self.pitch = tuple(bounds), tuple(pitch)
        self.scene = dict(obstacles=list(obstacles), dynamic=list(dynamic), route=route, old_route=old_route,
                          blocked_route=blocked_route, start=start, goal=goal, robot=robot, clearance=list(clearance))
        if self.cursor is None:
            xmin, ymin, xmax, ymax = self.bounds
            self.cursor = np.array([(xmin + xmax) / 2, (ymin + ymax) / 2])
        self.refresh()

    def frame(self) -> MapFrame | None:
        if self.bounds is None or self.size.width < 2 or self.size.height < 2:
            return None
        return MapFrame(self.size.width, self.size.height, self.bounds)

    def render(self) -> Text:
        frame = self.frame()
        if frame is None:
            return Text("no map yet: calibrate (screen 1), then detect (screen 2)", style="italic")
        canvas = BrailleCanvas(frame, LAYERS)
        xmin, ymin, xmax, ymax = frame.bounds
        px, py = self.pitch
        for x in np.arange(xmin, xmax + 1e-9, px):
            canvas.line("grid", [(x, ymin), (x, ymax)], dotted=True)
        for y in np.arange(ymin, ymax + 1e-9, py):
            canvas.line("grid", [(xmin, y), (xmax, y)], dotted=True)
        sc = self.scene
        for poly in sc.get("obstacles", []):
            canvas.fill("obstacle", poly)
        for ring in sc.get("clearance", []):
            canvas.line("obstacle", ring, closed=True, dotted=True)
        for poly in sc.get("dynamic", []):
            canvas.fill("dynamic", poly)
        if sc.get("old_route") is not None:
            canvas.line("old_route", sc["old_route"], dotted=True)
        if sc.get("blocked_route") is not None:
            canvas.line("blocked_route", sc["blocked_route"], dotted=True)
        if sc.get("route") is not None:
            canvas.line("route", sc["route"])
        for key, ch in (("start", "S"), ("goal", "G"), ("robot", "R")):
            if sc.get(key) is not None:
                canvas.label(sc[key], ch, "marker")
        if self.cursor is not None and self.has_focus:
            canvas.label(self.cursor, "+", "cursor")
        codes, top = canvas.cells()
        text = Text(no_wrap=True, overflow="crop")
        styles = [STYLES[name] for name in LAYERS]
        for r in range(codes.shape[0]):
            row, tops = codes[r], top[r]
            # runs of one colour become one span
            edges = np.flatnonzero(np.diff(tops)) + 1
            for a, b in zip(np.concatenate([[0], edges]), np.concatenate([edges, [len(row)]])):
                chunk = "".join(map(chr, row[a:b]))
                text.append(chunk, styles[tops[a]] if tops[a] >= 0 else None)
            if r < codes.shape[0] - 1:
                text.append("\n")
        return text

    # -- cursor ----------------------------------------------------------------------------------
    def _set_cursor(self, xy: np.ndarray) -> None:
        if self.bounds is None:
            return
        xmin, ymin, xmax, ymax = self.bounds
        self.cursor = np.array([np.clip(xy[0], xmin, xmax), np.clip(xy[1], ymin, ymax)])
        self.post_message(self.CursorMoved((float(self.cursor[0]), float(self.cursor[1]))))
        self.refresh()

    def set_cursor(self, xy) -> None:
        """Put the cursor at world ``xy``."""
        self._set_cursor(np.asarray(xy, float))

    def action_move(self, dc: int, dr: int) -> None:
        frame = self.frame()
        if frame is None or self.cursor is None:
            return
        step = 1.0 / frame.scale
        self._set_cursor(self.cursor + np.array([2 * dc * step, -4 * dr * step]))

    def action_jump(self, dx: int, dy: int) -> None:
        if self.cursor is not None:
            self._set_cursor(self.cursor + np.array([dx * self.pitch[0], dy * self.pitch[1]]))

    def on_click(self, event: events.Click) -> None:
        frame = self.frame()
        if frame is None:
            return
        self.focus()
        self._set_cursor(frame.cell_to_world(event.x, event.y))

    def on_focus(self) -> None:
        self.refresh()

    def on_blur(self) -> None:
        self.refresh()
