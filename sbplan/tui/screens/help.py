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
| `f1` `?` | this help |
| `esc` | cancel the running step |
| `tab` | next field; `→` or `End` accepts a path completion |
| `q` | quit |

**1 Calibration.** `o` opens the reference image typed at the right (or a saved calibration
`.json`); `c` calibrates with the chosen stages (re-run after changing a stage); `ctrl+s` saves
the calibration. The picture shows the fitted cells, the symbols found, their centres and the
rejected contours; the side shows the derived threshold and the margin (above 1: symbols and
everything else are separated).

**2 Detection.** `d` opens the current image and detects (also `r`, refresh); occupied cells,
obstacle outlines and their minimum-area rectangles are drawn over it; the table lists each
obstacle's cells, size, angle and centre in metres. `e` exports the overlay, occupancy image,
GeoJSON and a nav2 map into the export folder.

**3 Route.** Arrows (shift: one cell) or a click move the cursor; `s` / `g` put the start / goal
there (or type them); `p` plans with the chosen planner. `[` `]` move the robot along the route.
`o` places a dynamic obstacle at the cursor and replans from the robot; `n` detects on a newer
image and replans around obstacles on cells that were free. The old route stays drawn (yellow)
next to the new one (green). `x` clears the dynamic obstacles.
"""


class HelpScreen(ModalScreen):
    """Keys and what each screen does."""

    BINDINGS = [Binding("escape,q,f1,question_mark", "dismiss", "Close")]

    def compose(self) -> ComposeResult:
        with VerticalScroll(id="help"):
            yield Markdown(HELP)
