"""Screen 1: calibrate on the reference image (empty floor)."""

from __future__ import annotations

from typing import cast

from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical, VerticalScroll
from textual.widgets import Button, Header, Label, Select, Static

from ...contracts import StageChoices
from ...detection.calibration import DEFAULT_STAGES
from ...errors import CalibrationError, InputError
from ..render import calibration_overlay
from ..session import STAGE_KINDS, display_path, stage_names
from ..widgets.busy import Busy
from ..widgets.keys import KeyFooter
from ..widgets.path_input import PathInput
from ..widgets.picture import Picture
from .base import JobScreen

LEGEND = "[#2890c8]━ cells[/]  [#3cc83c]▢ symbols[/]  [#e62828]+ centres[/]  [#00c8e6]× rejected contours[/]"


class CalibrationScreen(JobScreen):
    """The reference image with the fitted grid, the derived threshold and margin, stage choice."""

    TITLE = "sbplan"
    SUB_TITLE = "1 calibration"
    BINDINGS = [
        Binding("o", "open_reference", "Open"),
        Binding("c", "calibrate", "Calibrate"),
        Binding("ctrl+s", "save", "Save"),
        Binding("f", "fullscreen", "Zoom"),
    ]
    OUTPUT_FIELDS = {"cal-path": "calibration.json"}

    def compose(self) -> ComposeResult:
        s = self.session
        self._names = names = stage_names()
        yield Header()
        with Horizontal(classes="body"):
            with Vertical(classes="main"):
                yield Picture("no reference image: type its path at the right and press Enter", id="cal-picture")
                yield Static(LEGEND, classes="legend")
            with VerticalScroll(classes="side"):
                yield Label("Reference image", classes="heading")
                yield PathInput(display_path(s.reference_path), suffixes=(".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".pgm", ".json"),
                                placeholder="path of the empty-floor image", id="ref-path")
                yield Label("Stages", classes="heading")
                for kind in STAGE_KINDS:
                    options = [(n, n) for n in names[kind]]
                    value = DEFAULT_STAGES[kind] if DEFAULT_STAGES[kind] in names[kind] else Select.NULL
                    yield Label(kind, classes="field")
                    yield Select(options, value=value, allow_blank=value is Select.NULL, id=f"stage-{kind}",
                                 compact=True)
                yield Button("Calibrate (c)", id="calibrate", variant="primary", compact=True)
                yield Static("not calibrated", id="cal-stats")
                yield Label("Save calibration to", classes="heading")
                yield PathInput("", suffixes=(".json",), id="cal-path")
                yield Button("Save (ctrl+s)", id="save", compact=True)
        yield Busy()
        yield KeyFooter()

    def on_mount(self) -> None:
        self.follow_map()
        if self.session.reference is not None:
            self._show()
        elif self.session.reference_path is not None:
            # after the first paint: the screen shows at once, the image follows
            self.call_after_refresh(self.action_open_reference)

    # -- actions ---------------------------------------------------------------------------------
    def action_open_reference(self, calibrate_after: bool | None = None) -> None:
        """Open the reference named in the path input (an image, a map folder, or a saved
        calibration .json); then calibrate when ``calibrate_after`` (default: the app's auto)."""
        if calibrate_after is None:
            calibrate_after = self.app.auto
        path = self.query_one("#ref-path", PathInput).value.strip()
        if not path:
            self.app.report_error(InputError("reference: type the path of the empty-floor image"))
            return
        if path.lower().endswith(".json"):
            def load(progress):
                progress("reading the calibration file", None)
                return self.session.load_calibration(path)

            self.start_job(f"loading calibration {path}", load, lambda cal: self._calibrated(cal, loaded=path))
            return

        def read(progress):
            progress("reading the image", None)
            return self.session.load_reference(path)

        def done(_image) -> None:
            self.session.calibration = None
            self.follow_map()  # a map folder starts that map's session, with its own outputs
            self._show()
            if calibrate_after:
                self.action_calibrate()

        self.start_job(f"opening {path}", read, done)

    def chosen_stages(self) -> StageChoices:
        out = {}
        for kind in STAGE_KINDS:
            value = self.query_one(f"#stage-{kind}", Select).value
            if isinstance(value, str):  # a stage name; not Select.NULL (nothing chosen)
                out[kind] = value
        return cast(StageChoices, out)  # keys from STAGE_KINDS

    def action_calibrate(self) -> None:
        stages = self.chosen_stages()
        label = "calibrating with " + ", ".join(str(name) for name in stages.values())
        self.start_job(label, lambda progress: self.session.calibrate(stages, progress), self._calibrated)

    def _calibrated(self, cal, loaded: str | None = None) -> None:
        self.session.adopt(cal)
        for kind in STAGE_KINDS:
            name = cal.stages.get(kind, {}).get("name")
            select = self.query_one(f"#stage-{kind}", Select)
            if name is not None and name in self._names[kind]:
                select.value = name
        self._show()
        self.notify(f"calibration {'loaded' if loaded else 'done'}: grid {cal.grid.cols} columns × "
                    f"{cal.grid.rows} rows, threshold {cal.threshold:.4f}", title="calibration")
        if self.app.screen is not self and isinstance(self.app.screen, JobScreen):
            self.app.screen.session_changed()  # the operator went on to screen 2 or 3 meanwhile

    def action_save(self) -> None:
        """Save the calibration to the path at the right; an existing file is overwritten only
        after the operator confirmed."""
        if self.session.calibration is None:
            self.app.report_error(CalibrationError("calibration: nothing to save; calibrate first (c)"))
            return
        path = self.query_one("#cal-path", PathInput).value.strip() or self.output_default("cal-path")

        def save() -> None:
            def write(progress):
                progress("writing", None)
                return self.session.save_calibration(path)

            self.start_job(f"saving {path}", write,
                           lambda p: self.notify(f"saved {display_path(p)}", title="calibration"))

        self.confirm_overwrite([path], save)

    def action_fullscreen(self) -> None:
        s = self.session
        self.show_fullscreen(self._picture(), title=f"reference {display_path(s.reference_path)}")

    # -- view ------------------------------------------------------------------------------------
    def _picture(self):
        """The reference with the fitted grid drawn over it, or the bare reference, or None."""
        s = self.session
        cal = s.calibration
        if s.reference is not None and cal is not None and tuple(cal.image_shape) == s.reference.shape[:2]:
            return calibration_overlay(s.reference, cal)
        return s.reference

    def _show(self) -> None:
        s = self.session
        picture = self.query_one("#cal-picture", Picture)
        stats = self.query_one("#cal-stats", Static)
        cal = s.calibration
        picture.show(self._picture())
        if cal is None:
            stats.update("not calibrated" if s.reference is None else
                         f"{s.reference.shape[1]} × {s.reference.shape[0]} px; not calibrated: press c")
            return
        st = cal.stats
        other = st.get("other_distance_min")
        lines = [
            f"grid        {cal.grid.cols} columns × {cal.grid.rows} rows",
            f"pitch       {cal.grid.pitch_px[0]:.1f} × {cal.grid.pitch_px[1]:.1f} px",
            f"symbols     {st.get('symbols', cal.symbols_expected)} of {st.get('after_length_filter', '?')} contours",
            f"rejected    {len(st.get('rejected_centres_px', []))} contours",
            f"threshold   {cal.threshold:.4f}",
            f"margin      {cal.margin:.2f}x" + ("" if cal.margin > 1 else "  (does not separate!)"),
            f"max symbol d {st.get('symbol_distance_max', float('nan')):.4f}",
            f"min other d  {other:.4f}" if other is not None else "min other d  -",
            f"tolerance   {cal.grid.tolerance_px:.1f} px",
            f"metres      {cal.workspace.pitch_m[0]:g} × {cal.workspace.pitch_m[1]:g} per cell",
        ]
        if s.calibration_path is not None:
            lines.append(f"file        {display_path(s.calibration_path)}")
        stats.update("\n".join(lines))

    # -- events ----------------------------------------------------------------------------------
    def on_input_submitted(self, event: PathInput.Submitted) -> None:
        self.set_focus(None)  # so the screen keys (1 2 3, c, ...) work right after Enter
        if event.input.id == "ref-path":
            self.action_open_reference()
        elif event.input.id == "cal-path":
            self.action_save()

    def on_button_pressed(self, event: Button.Pressed) -> None:
        if event.button.id == "calibrate":
            self.action_calibrate()
        elif event.button.id == "save":
            self.action_save()
