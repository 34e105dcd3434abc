"""A picture over the whole terminal, with zoom: obstacle numbers readable at 80 x 24."""

from __future__ import annotations

from textual.app import ComposeResult
from textual.binding import Binding
from textual.screen import ModalScreen
from textual.widgets import Static

from ..widgets.zoomview import ZoomView
from ..widgets.keys import KeyFooter


class PictureScreen(ModalScreen):
    """``image`` (gray or BGR array) full-screen; ``labels`` are ``(x, y, text)`` in its pixels.

    ``+``/``-`` zoom, arrows pan, ``0`` fits, ``esc``/``f``/``q`` go back.
    """

    BINDINGS = [Binding("escape,f,q", "dismiss", "Back")]

    def __init__(self, image, labels=(), title: str = "") -> None:
        super().__init__()
        self._image, self._labels, self._title = image, labels, title

    def compose(self) -> ComposeResult:
        yield Static(self._title, id="picture-title")
        yield ZoomView(self._image, self._labels, id="zoom")
        yield KeyFooter()

    def on_mount(self) -> None:
        self.query_one(ZoomView).focus()
