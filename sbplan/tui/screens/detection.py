"""Screen 2: detect the occupied cells and obstacles in the current image; export them."""

from __future__ import annotations

from pathlib import Path

from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical, VerticalScroll
from textual.widgets import Button, DataTable, Footer, Header, Label, Static

from ...detection import exports
from ...detection.exports import overlay_image
from ...errors import InputError
from ..session import display_path
from ..widgets.busy import Busy
from ..widgets.path_input import PathInput
from ..widgets.picture import Picture
from .base import JobScreen

LEGEND = ("[#e62828]▆ occupied cells, outlines[/]  [#ffdc00]▢ MARs[/]  [#3cc83c]● symbols found[/]  "
          "[#00c8e6]× symbol shapes off their cell[/]")


class DetectionScreen(JobScreen):
    """The current image with occupied cells, obstacles and MARs; obstacle and timing tables."""

    TITLE = "sbplan"
    SUB_TITLE = "2 detection"
    BINDINGS = [
        Binding("d", "detect", "Detect"),
        Binding("r", "detect", "Refresh", show=False),
        Binding("e", "export", "Export"),
    ]

    def compose(self) -> ComposeResult:
        s = self.session
        self._scene_seen = s.scene_path
        yield Header()
        with Horizontal(classes="body"):
            with Vertical(classes="main"):
                yield Picture("no detection yet: open a scene image (d)", id="det-picture")
                yield Static(LEGEND, classes="legend")
            with VerticalScroll(classes="side"):
                yield Label("Current image", classes="heading")
                yield PathInput(display_path(s.scene_path), suffixes=(".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".pgm"),
                                placeholder="path of the current camera image", id="scene-path")
                yield Button("Open & detect (d)", id="detect", variant="primary", compact=True)
                yield Static("no detection yet", id="det-summary")
                yield Label("Obstacles", classes="heading")
                yield DataTable(id="obstacles", cursor_type="row", zebra_stripes=True)
                yield Label("Timings", classes="heading")
                yield DataTable(id="timings", cursor_type="none")
                yield Label("Export to folder", classes="heading")
                yield PathInput(str(s.out_dir), id="export-dir")
                yield Button("Export overlay, GeoJSON, nav2 (e)", id="export", compact=True)
        yield Busy()
        yield Footer()

    def on_mount(self) -> None:
        self.query_one("#obstacles", DataTable).add_columns("id", "cells", "size m", "angle °", "centre m")
        self.query_one("#timings", DataTable).add_columns("stage", "ms")
        self.on_screen_resume()

    def on_screen_resume(self) -> None:
        s = self.session
        if s.scene_path != self._scene_seen:  # another map was opened on screen 1
            self._scene_seen = s.scene_path
            self.query_one("#scene-path", PathInput).value = display_path(s.scene_path)
        if s.detection is not None and s.detection.calibration is not s.calibration:
            s.detection = None  # calibrated again since: the old cells no longer mean anything
        self._show()
        if self.app.auto and s.detection is None and s.calibration is not None and s.scene_path is not None \
                and not self.busy:
            self.action_detect()

    # -- actions ---------------------------------------------------------------------------------
    def action_detect(self) -> None:
        path = self.query_one("#scene-path", PathInput).value.strip()
        if not path:
            self.app.report_error(InputError("scene: type the path of the current camera image"))
            return
        s = self.session

        def job():
            s.require_calibration()
            image = s.load_scene(path)
            return self.run_detection(image)

        self.start_job(f"detecting on {path}", job, self._detected)

    def run_detection(self, image):
        """The blocking step (worker thread): detection on ``image`` with the session's calibration."""
        return self.session.detect(image)

    def _detected(self, detection) -> None:
        s = self.session
        s.detection = detection
        s.route = s.old_route = None
        s.dynamic = []
        self._show()

    def action_export(self) -> None:
        s = self.session
        if s.detection is None:
            self.app.report_error(InputError("export: nothing to export; detect first (d)"))
            return
        folder = Path(self.query_one("#export-dir", PathInput).value.strip() or s.out_dir)
        det, image = s.detection, s.scene

        def job():
            model = s.obstacle_model  # what the planner gets, in every file
            exports.write_overlay(folder / "overlay.png", image, det, model)
            exports.write_occupancy(folder / "occupancy.png", det)
            exports.write_geojson(folder / "obstacles.geojson", det, model)
            exports.write_nav2(folder / "nav2", det, model=model)
            return folder

        self.start_job(f"exporting to {folder}", job,
                       lambda f: self.notify(f"wrote {display_path(f)}/: overlay.png, occupancy.png, "
                                             "obstacles.geojson, nav2/", title="export"))

    # -- view ------------------------------------------------------------------------------------
    def _show(self) -> None:
        s = self.session
        det = s.detection
        picture = self.query_one("#det-picture", Picture)
        table = self.query_one("#obstacles", DataTable)
        timings = self.query_one("#timings", DataTable)
        summary = self.query_one("#det-summary", Static)
        table.clear()
        timings.clear()
        if det is None:
            picture.show(s.scene if s.calibration is not None else None,
                         "not calibrated: calibrate on screen 1 first" if s.calibration is None else None)
            summary.update("not calibrated yet (screen 1)" if s.calibration is None else "no detection yet: press d")
            return
        assert s.scene is not None  # the detection was made on it
        picture.show(overlay_image(s.scene, det, s.obstacle_model))
        summary.update(
            f"symbols     {det.symbols_found} of {det.symbols_expected} found\n"
            f"occupied    {len(det.occupied_cells)} cells\n"
            f"obstacles   {len(det.obstacles)}\n"
            f"stages      {', '.join(det.stages.values())}")
        for ob in det.obstacles:
            j = ob.to_json()
            size = j.get("size_m")
            table.add_row(str(ob.id), str(len(ob.cells)),
                          f"{size[0]:.2f}×{size[1]:.2f}" if size else "-",
                          f"{round(j['angle_m_deg'], 1) + 0.0:.1f}" if "angle_m_deg" in j else "-",
                          f"{j['centre_m'][0]:.2f},{j['centre_m'][1]:.2f}" if "centre_m" in j else "-",
                          key=str(ob.id))
        for stage, ms in det.timings_ms.items():
            timings.add_row(stage, "··· " if self.app.hide_timings else f"{ms:.1f}")

    # -- events ----------------------------------------------------------------------------------
    def on_input_submitted(self, event: PathInput.Submitted) -> None:
        self.set_focus(None)  # so the screen keys (1 2 3, d, e) work right after Enter
        if event.input.id == "scene-path":
            self.action_detect()
        elif event.input.id == "export-dir":
            self.action_export()

    def on_button_pressed(self, event: Button.Pressed) -> None:
        if event.button.id == "detect":
            self.action_detect()
        elif event.button.id == "export":
            self.action_export()
