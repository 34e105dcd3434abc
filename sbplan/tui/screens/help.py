"""The help screen: what each screen does and its keys."""

from __future__ import annotations

from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import VerticalScroll
from textual.screen import ModalScreen
from textual.widgets import Markdown

HELP = """\
# sbplan — operator's terminal

The floor is covered with a grid of identical symbols; a ceiling camera sees it. A symbol that the
empty-floor **reference** shows and the **current image** lacks marks its cell as occupied;
occupied cells form obstacles, and routes go around them.

| key | everywhere |
|---|---|
| `1` `2` `3` | calibration, detection, route screen |
| `ctrl+p` | command palette: every action by name |
| `f1` `?` | this help (arrows, `pgup`/`pgdn` scroll it) |
| `f` | the picture (or the map) over the whole terminal |
| `esc` | cancel the running step |
| `tab` | next field; `→` or `End` accepts a path completion |
| `q` | quit |

A long step (open, calibrate, detect, export, plan) shows a line above the footer: what runs,
its stage, a bar and Cancel. Cancel stops the step at its next stage; nothing it would have
made is kept. Writing over an existing file asks first.

**1 Calibration.** `o` opens the reference image typed at the right (a map folder starts that
map, with its own output folder; a saved calibration `.json` is loaded); `c` calibrates with the
chosen stages (re-run after changing a stage); `ctrl+s` saves the calibration. The picture shows
the fitted cells, the symbols found, their centres and the rejected contours; the side shows the
derived threshold and the margin (above 1: symbols and everything else are separated).

**2 Detection.** `d` opens the current image and detects (also `r`, refresh); occupied cells,
obstacle outlines and their minimum-area rectangles are drawn over it; the table lists each
obstacle's cells, size, angle and centre in metres. The summary gives the camera's movement
since calibration (shift, rotation, scale, residual, symbols used) and warns when it is large;
`a` re-anchors the calibration to the camera's present pose (as `sbplan calibrate --update`),
asking before it overwrites the calibration file. A camera that moved too far is an error:
calibrate again on the empty floor. `e` exports the overlay, occupancy image, GeoJSON and a
nav2 map. In full screen (`f`), `+`/`-` zoom, arrows pan, `0` fits; obstacle numbers are text.

**3 Route.** Arrows (shift: one cell) or a click move the cursor; `s` / `g` put the start / goal
there (or type them); `p` plans with the chosen planner around the detected obstacles taken as
MARs or outlines (the same names as `sbplan plan --use`). `[` `]` move the robot along the
route. `o` places a dynamic obstacle at the cursor and replans from the robot; `n` detects on a
newer image and replans around obstacles on cells that were free; `x` clears the dynamic
obstacles and replans. The old route stays drawn (amber) next to the new one (green); a route a
new obstacle blocks and that could not be replanned is drawn red and marked INVALID.
"""


class HelpScreen(ModalScreen):
    """Keys and what each screen does."""

    BINDINGS = [Binding("escape,q,f1,question_mark", "dismiss", "Close")]

    def compose(self) -> ComposeResult:
        with VerticalScroll(id="help"):
            yield Markdown(HELP)

    def on_mount(self) -> None:
        # focused, so the arrows and page keys scroll it in a small terminal
        self.query_one("#help").focus()
