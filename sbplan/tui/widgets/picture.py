"""An image view: textual-image where the terminal shows graphics, half blocks otherwise."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from PIL import Image as PILImage
from textual.app import ComposeResult
from textual.containers import Container
from textual.widgets import Static
from textual_image.widget import BaseImage

if TYPE_CHECKING:
    from textual import getters

    from ..app import SbplanApp


def to_pil(image: np.ndarray) -> PILImage.Image:
    """A gray (H, W) or BGR (H, W, 3) uint8 array as an RGB PIL image."""
    a = np.asarray(image)
    if a.ndim == 2:
        return PILImage.fromarray(a).convert("RGB")
    return PILImage.fromarray(np.ascontiguousarray(a[:, :, 2::-1]))


class Picture(Container):
    """Shows one image scaled to the available space, or a placeholder text.

    The renderer class comes from the app (``app.image_class``): the terminal's graphics protocol
    when one was detected before the app started, half blocks under tests and in tmux.
    """

    if TYPE_CHECKING:  # the app this widget runs in (Textual's own pattern; it types it as any App)
        app = getters.app(SbplanApp)

    def __init__(self, placeholder: str = "no image", **kwargs) -> None:
        super().__init__(**kwargs)
        self._placeholder = placeholder

    def compose(self) -> ComposeResult:
        yield Static(self._placeholder, classes="placeholder")
        yield self.app.image_class(None, classes="image")

    def show(self, image: np.ndarray | None, placeholder: str | None = None) -> None:
        """Show ``image`` (gray or BGR array), or the placeholder when None."""
        view = self.query_one(".image", BaseImage)  # (every textual-image widget is one)
        note = self.query_one(".placeholder", Static)
        if placeholder is not None:
            note.update(placeholder)
        view.image = None if image is None else to_pil(image)
        view.display = image is not None
        note.display = image is None
