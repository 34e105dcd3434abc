"""Screen 2: detect the occupied cells and obstacles in the current image; export them; follow
the camera's movement since calibration and re-anchor the calibration to it."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from rich.markup import escape
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical, VerticalScroll
from textual.widgets import Button, DataTable, Header, Label, Static

from ...detection import exports
from ...detection.exports import overlay_image
from ...detection.obstacles import axis_angle
from ...detection.registration import signed
from ...errors import CameraMotionError, InputError
from ..session import display_path
from ..widgets.busy import Busy
from ..widgets.keys import KeyFooter
from ..widgets.path_input import PathInput
from ..widgets.picture import Picture
from ..widgets.tables import fill_table
from .base import JobScreen

LEGEND = ("[#e62828]▆ occupied cells, outlines[/]  [#ffdc00]▢ obstacle model[/]  [#ff8c00]▢ clearance[/]  "
          "[#3cc83c]● symbols found[/]  [#00c8e6]× symbol shapes off their cell[/]")
#: What :meth:`DetectionScreen.action_export` writes into the export folder.
EXPORTS = ("overlay.png", "occupancy.png", "obstacles.geojson", "nav2/map.yaml", "nav2/map.pgm")

#: the columns of the obstacle and timing tables
OBSTACLE_COLUMNS = ("id", "cells", "size m", "angle °", "centre m")
TIMING_COLUMNS = ("stage", "ms")


def table_rows(det, *, hide_timings: bool = False) -> dict[str, list[tuple[str, ...]]]:
    """The rows of the obstacle and timing tables for a detection (none for None):
    ``{"obstacles": [...], "timings": [...]}``, cells as text, in :data:`OBSTACLE_COLUMNS` and
    :data:`TIMING_COLUMNS` order."""
    rows: dict[str, list[tuple[str, ...]]] = {"obstacles": [], "timings": []}
    if det is None:
        return rows
    for ob in det.obstacles:
        j = ob.to_json()
        size = j.get("size_m")
        rows["obstacles"].append((str(ob.id), str(len(ob.cells)),
                                  f"{size[0]:.2f}×{size[1]:.2f}" if size else "-",
                                  # as sbplan detect prints it: a vertical side is 90, never -90
                                  f"{axis_angle(j['angle_m_deg'], 1):.1f}" if "angle_m_deg" in j else "-",
                                  f"{j['centre_m'][0]:.2f},{j['centre_m'][1]:.2f}" if "centre_m" in j else "-"))
    for stage, ms in det.timings_ms.items():
        rows["timings"].append((stage, "··· " if hide_timings else f"{ms:.1f}"))
    return rows


def camera_lines(motion) -> list[str]:
    """The camera's movement since calibration, for the summary (rich markup); the warning in
    the warning colour."""
    if motion is None or motion.model == "none":
        return ["camera      movement not estimated"]
    lines = ["camera since calibration",
             f"  shift     {signed(motion.shift_px[0], 2)}, {signed(motion.shift_px[1], 2)} px",
             f"  rotation  {signed(motion.rotation_deg, 3)}°",
             f"  scale     {motion.scale:.4f}",
             f"  residual  {motion.residual_px:.2f} px, {motion.symbols_used} symbols ({motion.model})"]
    if motion.warning:
        lines.append(f"[b $warning]⚠ {escape(motion.warning)}[/]")
        lines.append("[$warning]  re-anchor the calibration: a[/]")
    return lines


class DetectionScreen(JobScreen):
    """The current image with occupied cells, obstacles and MARs; the camera's movement;
    obstacle and timing tables."""

    TITLE = "sbplan"
    SUB_TITLE = "2 detection"
    BINDINGS = [
        Binding("d", "detect", "Detect"),
        Binding("r", "detect", "Refresh", show=False),
        Binding("e", "export", "Export"),
        Binding("a", "reanchor", "Re-anchor"),
        Binding("f", "fullscreen", "Zoom"),
    ]
    OUTPUT_FIELDS = {"export-dir": ""}

    def compose(self) -> ComposeResult:
        s = self.session
        self._scene_seen = s.scene_path
        # (scene path, calibration) whose detection failed: not detected again on its own
        self._failed_on: tuple[str, int] | None = None
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
                yield Button("Re-anchor calibration (a)", id="reanchor", compact=True)
                yield Label("Obstacles", classes="heading")
                yield DataTable(id="obstacles", cursor_type="row", zebra_stripes=True)
                yield Label("Timings", classes="heading")
                yield DataTable(id="timings", cursor_type="none")
                yield Label("Export to folder", classes="heading")
                yield PathInput("", id="export-dir")
                yield Button("Export overlay, GeoJSON, nav2 (e)", id="export", compact=True)
        yield Busy()
        yield KeyFooter()

    def on_mount(self) -> None:
        self.on_screen_resume()

    def on_screen_resume(self) -> None:
        s = self.session
        self.follow_map()
        if s.scene_path != self._scene_seen:  # another map was opened on screen 1
            self._scene_seen = s.scene_path
            self.query_one("#scene-path", PathInput).value = display_path(s.scene_path)
        if s.detection is not None and s.detection.calibration is not s.calibration:
            s.detection = None  # calibrated again since: the old cells no longer mean anything
        self._show()
        if self.app.auto and s.detection is None and s.calibration is not None and s.scene_path is not None \
                and not self.busy and self._failed_on != (str(s.scene_path), id(s.calibration)):
            self.action_detect()

    # -- actions ---------------------------------------------------------------------------------
    def action_detect(self) -> None:
        path = self.query_one("#scene-path", PathInput).value.strip()
        if not path:
            self.app.report_error(InputError("scene: type the path of the current camera image"))
            return
        s = self.session

        def job(progress):
            s.require_calibration()
            progress("reading the image", 0.0)
            image = s.load_scene(path)
            progress("registering and detecting", 0.5)
            return self.run_detection(image)

        def failed(exc: Exception) -> None:
            self._failed_on = (path, id(s.calibration))
            s.detection = None
            self._show(error=exc)

        self.start_job(f"detecting on {path}", job, self._detected, failed=failed)

    def run_detection(self, image):
        """The blocking step (worker thread): detection on ``image`` with the session's calibration."""
        return self.session.detect(image)

    def _detected(self, detection) -> None:
        s = self.session
        s.detection = detection
        s.route = s.old_route = None
        s.route_invalid = None
        s.dynamic = []
        self._failed_on = None
        self._show()
        if detection.camera is not None and detection.camera.warning:
            self.notify(f"{detection.camera.warning}\nRe-anchor the calibration to the camera's new pose: a",
                        title="camera moved", severity="warning", timeout=10)

    def action_export(self) -> None:
        s = self.session
        if s.detection is None:
            self.app.report_error(InputError("export: nothing to export; detect first (d)"))
            return
        folder = Path(self.query_one("#export-dir", PathInput).value.strip() or s.out_dir)
        det, image = s.detection, s.scene

        def job(progress):
            model = s.obstacle_model  # what the planner gets, in every file
            writers = (("overlay.png", lambda path: exports.write_overlay(path, image, det, model)),
                       ("occupancy.png", lambda path: exports.write_occupancy(path, det)),
                       ("obstacles.geojson", lambda path: exports.write_geojson(path, det, model)),
                       ("nav2", lambda path: exports.write_nav2(path, det, model=model)))
            for k, (name, write) in enumerate(writers):
                progress(f"writing {name}", k / len(writers))
                write(folder / name)
            return folder

        def export() -> None:
            self.start_job(f"exporting to {folder}", job,
                           lambda f: self.notify(f"wrote {display_path(f)}/: overlay.png, occupancy.png, "
                                                 "obstacles.geojson, nav2/", title="export"))

        self.confirm_overwrite([folder / name for name in EXPORTS], export)

    def action_reanchor(self) -> None:
        """Move the calibration to the camera's pose in the current image (``sbplan calibrate
        --update``): measured first, then written over the calibration file once confirmed."""
        s = self.session
        if s.calibration is None or s.scene is None:
            self.app.report_error(InputError("re-anchor: calibrate (screen 1) and open a current image (d) first"))
            return
        target = s.calibration_path or s.out_dir / "calibration.json"

        def measure(progress):
            progress("registering the image to the calibration", None)
            return s.reanchor()

        def measured(result) -> None:
            cal, motion = result
            question = (f"Re-anchor the calibration to the camera's present pose?\n{motion.summary()}\n\n"
                        f"This {'overwrites' if Path(target).exists() else 'writes'} {display_path(target)}; "
                        f"detection starts again from the new pose.")

            def write(progress):
                progress(f"writing {display_path(target)}", None)
                cal.save(target)
                s.calibration_path = Path(target)
                return cal

            def written(new) -> None:
                s.adopt(new)
                self.notify(f"calibration re-anchored and saved to {display_path(target)}", title="re-anchor")
                self.action_detect()

            self.confirm_overwrite([target], lambda: self.start_job("re-anchoring", write, written),
                                   question=question)

        self.start_job("measuring the camera's movement", measure, measured)

    def action_fullscreen(self) -> None:
        """The overlay over the whole terminal, obstacle numbers as text."""
        det = self.session.detection
        if det is None:
            self.show_fullscreen(self.session.scene, title=display_path(self.session.scene_path))
            return
        cam = det.camera
        labels = []
        for ob in det.obstacles:
            centre = np.asarray(ob.centre_px, dtype=float)
            x, y = cam.to_frame(centre) if cam is not None and cam.moved else centre
            labels.append((x, y, str(ob.id)))
        self.show_fullscreen(self._overlay(), labels, title=f"{display_path(self.session.scene_path)}: "
                             f"{len(det.occupied_cells)} occupied cells, {len(det.obstacles)} obstacles")

    # -- view ------------------------------------------------------------------------------------
    def _overlay(self):
        assert self.session.scene is not None  # the detection was made on it
        # the summary at the right says what the caption would: the picture keeps every symbol visible
        s = self.session
        return overlay_image(s.scene, s.detection, s.obstacle_model, caption=False)

    def _show(self, error: Exception | None = None) -> None:
        s = self.session
        det = s.detection
        picture = self.query_one("#det-picture", Picture)
        table = self.query_one("#obstacles", DataTable)
        timings = self.query_one("#timings", DataTable)
        summary = self.query_one("#det-summary", Static)
        rows = table_rows(det, hide_timings=self.app.hide_timings)
        fill_table(table, OBSTACLE_COLUMNS, rows["obstacles"], keys=[row[0] for row in rows["obstacles"]])
        fill_table(timings, TIMING_COLUMNS, rows["timings"])
        self.query_one("#reanchor", Button).display = s.calibration is not None and s.scene is not None
        if det is None:
            picture.show(s.scene if s.calibration is not None else None,
                         "not calibrated: calibrate on screen 1 first" if s.calibration is None else None)
            if isinstance(error, CameraMotionError):
                summary.update(f"[b $error]camera moved: no detection[/]\n{escape(str(error))}\n"
                               "[$warning]re-anchor (a) if it moved a little, or calibrate again "
                               "on the empty floor (screen 1)[/]")
            elif error is not None:
                summary.update(f"[b $error]no detection[/]\n{escape(str(error))}")
            else:
                summary.update("not calibrated yet (screen 1)" if s.calibration is None else "no detection yet: press d")
            return
        picture.show(self._overlay())
        summary.update("\n".join([
            f"symbols     {det.symbols_found} of {det.symbols_expected} found",
            f"occupied    {len(det.occupied_cells)} cells",
            f"obstacles   {len(det.obstacles)}, drawn as {s.obstacle_model} (screen 3: m)",
            *camera_lines(det.camera),
            f"stages      {', '.join(det.stages.values())}"]))

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
        elif event.button.id == "reanchor":
            self.action_reanchor()
