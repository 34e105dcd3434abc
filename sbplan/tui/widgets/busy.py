"""The progress line of a long step: what runs, its stage and share done, and Cancel."""

from __future__ import annotations

from textual.app import ComposeResult
from textual.containers import Horizontal
from textual.message import Message
from textual.widgets import Button, Label, ProgressBar


class Busy(Horizontal):
    """Shown above the footer while a worker runs: what it does, the stage it is at, a bar with
    the share done (indeterminate until the step reports one) and Cancel.

    Each :meth:`start` returns a token; updates and :meth:`stop` with an older token (a step that
    another one replaced) change nothing.
    """

    class CancelRequested(Message):
        """The operator pressed Cancel."""

    def __init__(self, **kwargs) -> None:
        super().__init__(**kwargs)
        self.token = 0
        self.what = ""
        self.stage = ""
        self.fraction: float | None = None

    def compose(self) -> ComposeResult:
        yield Label("", id="busy-label")
        yield ProgressBar(total=None, show_eta=False, id="busy-bar")
        yield Button("Cancel (esc)", id="busy-cancel", variant="warning", compact=True)

    def on_mount(self) -> None:
        self.display = False

    def start(self, what: str) -> int:
        """Show the line for a new step; returns its token."""
        self.token += 1
        self.what, self.stage, self.fraction = what, "", None
        self.query_one(ProgressBar).update(total=None, progress=0)
        self._label()
        self.display = True
        return self.token

    def progress(self, token: int, stage: str, fraction: float | None) -> None:
        """The step ``token`` reached ``stage`` with ``fraction`` (0..1, or None: unknown) done."""
        if token != self.token or not self.display:
            return
        self.stage, self.fraction = stage, fraction
        bar = self.query_one(ProgressBar)
        if fraction is None:
            bar.update(total=None)
        else:
            bar.update(total=100, progress=round(100 * min(max(fraction, 0.0), 1.0)))
        self._label()

    def cancelling(self) -> None:
        """Cancel was asked: the step stops at its next stage."""
        self.stage = "cancelling" + (f" after {self.stage}" if self.stage else "")
        self._label()
        self.query_one("#busy-cancel", Button).disabled = True

    def stop(self, token: int) -> bool:
        """Hide the line if ``token`` is the step shown; True when it was."""
        if token != self.token:
            return False
        self.display = False
        self.query_one("#busy-cancel", Button).disabled = False
        return True

    def _label(self) -> None:
        self.query_one("#busy-label", Label).update(self.what + (f": {self.stage}" if self.stage else ""))

    def on_button_pressed(self, event: Button.Pressed) -> None:
        if event.button.id == "busy-cancel":
            event.stop()
            self.post_message(self.CancelRequested())
