"""The sbplan terminal app: three screens (calibration, detection, route) over one session."""

from __future__ import annotations

import os
from functools import partial
from typing import Iterable

from textual.app import App, SystemCommand
from textual.binding import Binding
from textual.screen import Screen
from textual_image.widget import HalfcellImage

from ..errors import CameraMotionError, SbplanError
from .screens.calibration import CalibrationScreen
from .screens.detection import DetectionScreen
from .screens.help import HelpScreen
from .screens.route import RouteScreen
from .screens.watch import WatchScreen
from .session import Session

#: (title, help, screen mode, screen action) for the command palette
ACTIONS = [
    ("Open reference image", "load the reference image (or calibration .json) typed on screen 1", "calibration", "open_reference"),
    ("Calibrate", "fit the grid and the match threshold with the chosen stages", "calibration", "calibrate"),
    ("Save calibration", "write the calibration JSON", "calibration", "save"),
    ("Detect", "open the current image and detect occupied cells and obstacles", "detection", "detect"),
    ("Export", "write overlay, occupancy, GeoJSON and nav2 map", "detection", "export"),
    ("Re-anchor calibration", "move the calibration to the camera's present pose (asks before overwriting)",
     "detection", "reanchor"),
    ("Picture full screen", "the current picture over the whole terminal, with zoom", None, "fullscreen"),
    ("Plan route", "plan from start to goal with the chosen planner", "route", "plan"),
    ("Set start at cursor", "move the start to the map cursor", "route", "set_start"),
    ("Set goal at cursor", "move the goal to the map cursor", "route", "set_goal"),
    ("Place dynamic obstacle", "an obstacle at the map cursor; replan from the robot", "route", "place_obstacle"),
    ("Newer image: detect and replan", "obstacles on cells that were free become dynamic obstacles", "route", "newer_image"),
    ("Robot forward", "move the robot 5 % along the route", "route", "robot(1)"),
    ("Robot back", "move the robot 5 % back along the route", "route", "robot(-1)"),
    ("Clear dynamic obstacles", "forget the obstacles placed or reported since the detection; replan",
     "route", "clear_dynamic"),
    ("Obstacle model", "what stands for each obstacle: its MAR, rectangles of its parts, or its outline "
     "(CLI --obstacle-model); replan", "route", "obstacle_model"),
    ("Cancel running step", "stop waiting for the current step and discard its result", None, "cancel"),
]


class SbplanApp(App):
    """``sbplan tui [MAP_DIR]``.

    Parameters
    ----------
    map_dir : str or path, optional
        A map folder with reference.png, scene-*.png and workspace.toml.
    auto : bool
        Run the obvious next step on its own: calibrate once the reference is open, detect when
        the detection screen first shows, plan when the route screen first shows.
    image_class : textual-image widget class, optional
        How pictures are drawn; default half blocks (readable everywhere, deterministic).
    hide_timings : bool
        Show ``···`` instead of milliseconds (snapshot tests).
    """

    CSS_PATH = "app.tcss"
    TITLE = "sbplan"
    MODES = {"calibration": CalibrationScreen, "detection": DetectionScreen, "route": RouteScreen}
    DEFAULT_MODE = "calibration"
    # The footer shows the screens' keys as one entry, so that every key fits in 80 columns.
    _SCREENS = Binding.Group("Screens")
    BINDINGS = [
        Binding("1", "switch_mode('calibration')", "Calibration", group=_SCREENS),
        Binding("2", "switch_mode('detection')", "Detection", group=_SCREENS),
        Binding("3", "switch_mode('route')", "Route", group=_SCREENS),
        Binding("w", "watch", "Watch", show=False),
        Binding("f1,question_mark", "help", "Help"),
        Binding("q", "quit", "Quit"),
    ]
    # Below 110 columns the side panel goes under the picture (app.tcss: .-narrow).
    HORIZONTAL_BREAKPOINTS = [(0, "-narrow"), (110, "-wide")]

    def __init__(self, map_dir: str | os.PathLike | None = None, *, auto: bool = True, image_class=None,
                 hide_timings: bool = False) -> None:
        super().__init__()
        self.image_class = HalfcellImage if image_class is None else image_class
        self.auto = auto
        self.hide_timings = hide_timings
        self.session = Session.from_map(map_dir)
        #: every error shown, oldest first (the notifications themselves expire)
        self.error_log: list[str] = []

    # -- errors ----------------------------------------------------------------------------------
    def report_error(self, exc: BaseException) -> None:
        """Show an error as the CLI would print it; the app stays usable."""
        if isinstance(exc, CameraMotionError):
            message = f"{exc}\nIn the app: re-anchor the calibration on this image (a, screen 2) " \
                      f"when the camera moved a little, or calibrate again on the empty floor (screen 1)."
            title = "sbplan: camera moved"
        elif isinstance(exc, SbplanError):
            message, title = str(exc), "sbplan: error"
        else:  # a bug: say what it was rather than dying
            message, title = f"{type(exc).__name__}: {exc}", "sbplan: internal error"
        self.error_log.append(message)
        self.notify(message, title=title, severity="error", timeout=15)

    # -- actions ---------------------------------------------------------------------------------
    def action_watch(self) -> None:
        """Watch a stream live (screens/watch.py)."""
        if not isinstance(self.screen, WatchScreen):
            self.push_screen(WatchScreen())

    def action_help(self) -> None:
        if not isinstance(self.screen, HelpScreen):
            self.push_screen(HelpScreen())

    async def run_on(self, mode: str | None, action: str) -> None:
        """Show the screen of ``mode`` (None: the current one) and run one of its actions."""
        if mode is not None and self.current_mode != mode:
            await self.switch_mode(mode)
        screen: Screen = self.screen
        await screen.run_action(action)

    def get_system_commands(self, screen: Screen) -> Iterable[SystemCommand]:
        yield from super().get_system_commands(screen)
        for mode, title in (("calibration", "Calibration screen"), ("detection", "Detection screen"),
                            ("route", "Route screen")):
            yield SystemCommand(title, f"switch to the {mode} screen", partial(self.switch_mode, mode))
        yield SystemCommand("Help", "keys and what each screen does", self.action_help)
        yield SystemCommand("Watch a stream", "video, image folder, camera or URL, live", self.action_watch)
        for title, help_text, action_mode, action in ACTIONS:
            yield SystemCommand(title, help_text, partial(self.run_on, action_mode, action))
