"""A progress line for a long step, with a cancel button."""

from __future__ import annotations

from textual.app import ComposeResult
from textual.containers import Horizontal
from textual.message import Message
from textual.widgets import Button, Label, LoadingIndicator


class Busy(Horizontal):
    """Shown while a worker runs: what it does, an animated indicator and Cancel."""

    class CancelRequested(Message):
        """The operator pressed Cancel."""

    def compose(self) -> ComposeResult:
        yield LoadingIndicator()
        yield Label("", id="busy-label")
        yield Button("Cancel (esc)", id="busy-cancel", variant="warning", compact=True)

    def on_mount(self) -> None:
        self.display = False

    def start(self, text: str) -> None:
        self.query_one("#busy-label", Label).update(text)
        self.display = True

    def stop(self) -> None:
        self.display = False

    def on_button_pressed(self, event: Button.Pressed) -> None:
        if event.button.id == "busy-cancel":
            event.stop()
            self.post_message(self.CancelRequested())
