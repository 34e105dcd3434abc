"""Screen 3: plan a route on the workspace map; replan when a new obstacle blocks it."""

from __future__ import annotations

import numpy as np
from shapely.geometry import LineString, Polygon
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical, VerticalScroll
from textual.widgets import Button, Header, Input, Label, Select, Static

from rich.markup import escape

from ... import registry
from ...errors import InputError, SbplanError
from ...imageio import load_image
from ..session import OBSTACLE_MODELS, display_path, square
from ..widgets.busy import Busy
from ..widgets.keys import KeyFooter
from ..widgets.mapview import MapView
from ..widgets.path_input import PathInput
from .base import JobScreen

LEGEND = ("[#e04040]⣿ obstacles, ⠤ clearance (m: model)[/]  [#b070ff]⣿ dynamic obstacles[/]  [#40e040]⠤ route[/]  "
          "[#ffb000]⠔ old route[/]  [#ff4040]⠔ blocked route[/]  [black on cyan]S[/] start "
          "[black on cyan]G[/] goal [black on cyan]R[/] robot  [black on white]+[/] cursor")


def parse_point(text: str, name: str) -> tuple[float, float]:
    """``"x, y"`` (metres) -> (x, y); InputError naming ``name`` otherwise."""
    parts = text.replace(",", " ").split()
    try:
        x, y = (float(p) for p in parts)
    except ValueError:
        raise InputError(f"{name}: expected two numbers 'x, y' in metres, got {text!r}") from None
    if not (np.isfinite(x) and np.isfinite(y)):
        raise InputError(f"{name}: expected finite numbers, got {text!r}")
    return x, y


_ROBOT = Binding.Group("Robot")


class RouteScreen(JobScreen):
    """The map with obstacles, start, goal and routes; plan, place obstacles, replan."""

    TITLE = "sbplan"
    SUB_TITLE = "3 route"
    # short descriptions and one entry for the robot's two keys: every key fits in 80 columns
    BINDINGS = [
        Binding("p", "plan", "Plan"),
        Binding("s", "set_start", "Start"),
        Binding("g", "set_goal", "Goal"),
        Binding("o", "place_obstacle", "Obstacle"),
        Binding("x", "clear_dynamic", "Clear"),
        Binding("n", "newer_image", "Newer"),
        Binding("m", "obstacle_model", "Model"),
        Binding("left_square_bracket", "robot(-1)", "Robot back", group=_ROBOT),
        Binding("right_square_bracket", "robot(1)", "Robot forward", group=_ROBOT),
        Binding("f", "fullscreen", "Zoom"),
    ]

    def compose(self) -> ComposeResult:
        s = self.session
        self._scene_seen = s.scene_path
        yield Header()
        with Horizontal(classes="body"):
            with Vertical(classes="main"):
                yield MapView(id="map")
                yield Static(LEGEND, classes="legend")
                yield Static("", id="cursor-info", classes="legend")
            with VerticalScroll(classes="side"):
                yield Label("Start x, y (m)", classes="heading")
                yield Input(self._fmt(s.start), placeholder="x, y", id="start", compact=True)
                yield Label("Goal x, y (m)", classes="heading")
                yield Input(self._fmt(s.goal), placeholder="x, y", id="goal", compact=True)
                yield Label("Planner", classes="heading")
                names = registry.planner_names()
                yield Select([(n, n) for n in names], value=s.planner if s.planner in names else Select.NULL,
                             id="planner", compact=True)
                yield Label("Obstacles as", classes="heading")
                yield Select([(f"{name}: {what}", name) for name, what in OBSTACLE_MODELS.items()],
                             value=s.obstacle_model, allow_blank=False, id="obstacle-model", compact=True)
                yield Button("Plan (p)", id="plan", variant="primary", compact=True)
                yield Static("no route yet", id="route-info")
                yield Label("Dynamic obstacle", classes="heading")
                yield Static("o: place one at the cursor\nx: clear them and replan", classes="hint")
                yield Label("Newer image", classes="heading")
                yield PathInput(display_path(s.scene_path), suffixes=(".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".pgm"),
                                id="newer-path")
                yield Button("Detect & replan (n)", id="newer", compact=True)
        yield Busy()
        yield KeyFooter()

    @staticmethod
    def _fmt(p) -> str:
        return "" if p is None else f"{p[0]:.2f}, {p[1]:.2f}"

    def on_mount(self) -> None:
        self.query_one("#map", MapView).focus()

    def on_screen_resume(self) -> None:
        s = self.session
        if s.scene_path != self._scene_seen:  # another map was opened on screen 1
            self._scene_seen = s.scene_path
            self.query_one("#newer-path", PathInput).value = display_path(s.scene_path)
        self.query_one("#start", Input).value = self._fmt(s.start)
        self.query_one("#goal", Input).value = self._fmt(s.goal)
        self.query_one("#obstacle-model", Select).value = s.obstacle_model
        self._show()
        if self.app.auto and s.route is None and s.detection is not None and s.start and s.goal and not self.busy:
            self.action_plan()

    # -- actions ---------------------------------------------------------------------------------
    def _read_endpoints(self) -> None:
        s = self.session
        for key in ("start", "goal"):
            text = self.query_one(f"#{key}", Input).value.strip()
            setattr(s, key, parse_point(text, key) if text else None)
        planner = self.query_one("#planner", Select).value
        if isinstance(planner, str):  # a planner's name; not Select.NULL (nothing chosen)
            s.planner = planner

    def action_plan(self) -> None:
        try:
            self._read_endpoints()
        except InputError as exc:
            self.app.report_error(exc)
            return
        s = self.session
        self.start_job(f"planning with {s.planner}", self._planning(s.plan), self._planned)

    @staticmethod
    def _planning(fn, *args):
        """A planning step for start_job: the planner runs at most its time limit, so Cancel
        takes effect when it returns."""
        def job(progress):
            progress("planning", None)
            return fn(*args)

        return job

    def _planned(self, route) -> None:
        s = self.session
        s.route, s.old_route, s.route_invalid = route, None, None
        self._show()

    def _cursor(self) -> np.ndarray | None:
        return self.query_one("#map", MapView).cursor

    def _set_endpoint(self, key: str) -> None:
        c = self._cursor()
        if c is None:
            return
        setattr(self.session, key, (float(c[0]), float(c[1])))
        self.query_one(f"#{key}", Input).value = self._fmt(c)
        self._show()

    def action_set_start(self) -> None:
        self._set_endpoint("start")

    def action_set_goal(self) -> None:
        self._set_endpoint("goal")

    def action_place_obstacle(self) -> None:
        """A dynamic obstacle (one grid pitch square) at the cursor; replan from the robot."""
        s, c = self.session, self._cursor()
        if s.calibration is None or c is None:
            self.app.report_error(InputError("obstacle: calibrate and detect first (screens 1 and 2)"))
            return
        side = float(min(s.calibration.workspace.pitch_m))
        self.add_dynamic([square(c, side)], f"obstacle at ({c[0]:.2f}, {c[1]:.2f}) m")

    def add_dynamic(self, obstacles: list, what: str) -> None:
        """Add dynamic obstacles (those not there yet) and replan from the robot around them; a
        route they block and that cannot be replanned is marked invalid."""
        s = self.session
        new = s.not_yet_dynamic(obstacles)
        if not new:
            self.notify(f"{what}: already there; nothing changed", title="route")
            return
        s.dynamic.extend(new)
        self._show()
        if s.route is None:
            return

        def failed(exc: Exception) -> None:
            if s.route is None:
                return
            line = LineString(s.route.waypoints)
            if any(line.intersects(Polygon(o)) for o in new) or s.route_invalid:
                s.route_invalid = f"blocked by {what}; replanning failed: {exc}"
            self._show()

        self.start_job(f"replanning around {what}", self._planning(s.replan, new), self._replanned, failed=failed)

    def _replanned(self, route) -> None:
        s = self.session
        if route.replanned:
            s.old_route, s.route = s.route, route
            s.route_invalid = None
            s.robot_fraction = 0.0  # the new route starts where the robot is
            self.notify(f"replanned: {route.length:.2f} m", title="route")
        else:
            self.notify("the new obstacle does not touch the route: no change", title="route")
        self._show()

    def action_newer_image(self) -> None:
        """Detect on a newer image; obstacles on cells free before are reported and replanned around."""
        s = self.session
        path = self.query_one("#newer-path", PathInput).value.strip()
        if not path:
            self.app.report_error(InputError("newer image: type the path of the newer camera image"))
            return

        def job(progress):
            progress("reading the image", 0.0)
            image = load_image(path)
            progress("registering and detecting", 0.5)
            return s.detect(image)

        def done(det) -> None:
            new = s.new_obstacles_in(det)
            if not new:
                self.notify("the newer image shows no new obstacle", title="route")
                return
            self.add_dynamic(new, f"{len(new)} new obstacle(s)")

        self.start_job(f"detecting on {path}", job, done)

    def action_obstacle_model(self) -> None:
        """The next obstacle model (mar, parts, outline), as if chosen in the list: a route planned
        on the old one is planned again."""
        names = list(OBSTACLE_MODELS)
        self.query_one("#obstacle-model", Select).value = names[(names.index(self.session.obstacle_model) + 1)
                                                                % len(names)]

    def action_robot(self, step: int) -> None:
        s = self.session
        s.robot_fraction = float(np.clip(s.robot_fraction + 0.05 * step, 0.0, 1.0))
        self._show()

    def action_clear_dynamic(self) -> None:
        """Forget the dynamic obstacles; a route bent or blocked by them is planned again from
        the robot's position around the detected obstacles alone."""
        s = self.session
        if not s.dynamic:
            return
        s.dynamic = []
        self._show()
        if s.route is None:
            return
        robot = s.robot_position()

        def done(route) -> None:
            s.old_route, s.route, s.route_invalid = s.route, route, None
            s.robot_fraction = 0.0
            self.notify(f"dynamic obstacles cleared; replanned: {route.length:.2f} m", title="route")
            self._show()

        def failed(exc: Exception) -> None:
            s.route_invalid = f"replanning after the dynamic obstacles were cleared failed: {exc}"
            self._show()

        self.start_job("replanning without the dynamic obstacles", self._planning(s.plan, robot), done,
                       failed=failed)

    def action_fullscreen(self) -> None:
        """The map over the whole screen (again: back)."""
        view = self.query_one("#map", MapView)
        if self.maximized is view:
            self.minimize()
        else:
            self.maximize(view, container=False)
            view.focus()

    # -- view ------------------------------------------------------------------------------------
    def _show(self) -> None:
        s = self.session
        view = self.query_one("#map", MapView)
        info = self.query_one("#route-info", Static)
        cal = s.calibration
        if cal is None:
            info.update("not calibrated yet (screen 1)")
            return
        route = None if s.route is None else s.route.waypoints
        view.draw(bounds=cal.world_bounds(), pitch=cal.workspace.pitch_m, obstacles=s.obstacles_m(),
                  clearance=s.clearance_m(),
                  dynamic=s.dynamic, route=None if s.route_invalid else route,
                  blocked_route=route if s.route_invalid else None,
                  old_route=None if s.old_route is None else s.old_route.waypoints,
                  start=s.start, goal=s.goal, robot=s.robot_position())
        if s.route is None:
            info.update("no route yet: press p" + ("" if s.detection is not None else
                                                    "\n(no detection: planning on an empty floor)"))
            self._cursor_info()
            return
        r = s.route
        t = "··· ms" if self.app.hide_timings else f"{r.time_s * 1e3:.1f} ms"
        lines = []
        if s.route_invalid:
            lines += [f"[b $error]route INVALID[/]: {escape(s.route_invalid)}", ""]
        lines += [f"length      {r.length:.2f} m", f"time        {t}", f"status      {r.status}",
                  f"planner     {r.planner}", f"guarantee   {escape(self._guarantee(r.planner))}",
                  f"obstacles   {s.obstacle_model} (m)", f"waypoints   {len(r.waypoints)}",
                  f"robot at    {s.robot_fraction:.0%} of route"]
        if s.old_route is not None:
            lines.append(f"old route   {s.old_route.length:.2f} m")
        if s.dynamic:
            lines.append(f"dynamic     {len(s.dynamic)} obstacle(s)")
        info.update("\n".join(lines))
        self._cursor_info()

    @staticmethod
    def _guarantee(planner: str) -> str:
        try:
            return registry.planner(planner).guarantee
        except SbplanError:
            return "unknown planner"

    def _cursor_info(self) -> None:
        c = self._cursor()
        self.query_one("#cursor-info", Static).update(
            "" if c is None else f"cursor ({c[0]:.2f}, {c[1]:.2f}) m   arrows/click move, shift+arrows by a cell")

    # -- events ----------------------------------------------------------------------------------
    def on_map_view_cursor_moved(self, event: MapView.CursorMoved) -> None:
        self._cursor_info()

    def on_input_submitted(self, event: Input.Submitted) -> None:
        if event.input.id in ("start", "goal"):
            try:
                self._read_endpoints()
            except InputError as exc:
                self.app.report_error(exc)
                return  # the cursor stays in the field to fix it
            self._show()
            self.query_one("#map", MapView).focus()
        elif event.input.id == "newer-path":
            self.query_one("#map", MapView).focus()
            self.action_newer_image()

    def on_select_changed(self, event: Select.Changed) -> None:
        s = self.session
        if event.select.id == "planner" and isinstance(event.value, str):  # not Select.NULL
            s.planner = event.value
        elif event.select.id == "obstacle-model" and isinstance(event.value, str) and event.value != s.obstacle_model:
            s.obstacle_model = event.value
            self._show()
            if s.route is not None:  # the route was planned around the other shapes
                self.action_plan()

    def on_button_pressed(self, event: Button.Pressed) -> None:
        if event.button.id == "plan":
            self.action_plan()
        elif event.button.id == "newer":
            self.action_newer_image()
