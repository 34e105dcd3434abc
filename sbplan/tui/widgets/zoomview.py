"""A picture drawn with half blocks at any zoom, with text labels that stay readable."""

from __future__ import annotations

from functools import lru_cache

import cv2
import numpy as np
from rich.segment import Segment
from rich.style import Style
from textual.binding import Binding
from textual.strip import Strip
from textual.widget import Widget

#: Zoom factors one step apart, and the largest (one image pixel per 8 x 8 half-block dots).
ZOOM_STEP = 1.5
MAX_ZOOM = 16.0
_BACKGROUND = (24, 24, 24)
_LABEL = Style(color="black", bgcolor="#ffdc00", bold=True)


@lru_cache(maxsize=4096)
def _style(top: tuple[int, int, int], bottom: tuple[int, int, int]) -> Style:
    return Style(color=f"rgb({top[0]},{top[1]},{top[2]})", bgcolor=f"rgb({bottom[0]},{bottom[1]},{bottom[2]})")


class ZoomView(Widget, can_focus=True):
    """An image (gray or BGR array) scaled to the widget, zoomed about a centre, with labels.

    One terminal cell shows two image pixels, one above the other (``▀`` in two colours), so the
    picture keeps its aspect ratio in any terminal, tmux included. Labels (obstacle numbers) are
    drawn as text on top at their pixel's cell, readable at any zoom.

    Keys: ``+``/``-`` zoom, arrows pan, ``0`` fits the whole picture; the mouse wheel zooms too.
    """

    _PAN = Binding.Group("Pan")
    BINDINGS = [
        Binding("plus,equals_sign", "zoom(1)", "Zoom in"),
        Binding("minus", "zoom(-1)", "Zoom out"),
        Binding("0", "fit", "Fit"),
        Binding("left", "pan(-1, 0)", "Pan left", group=_PAN),
        Binding("right", "pan(1, 0)", "Pan right", group=_PAN),
        Binding("up", "pan(0, -1)", "Pan up", group=_PAN),
        Binding("down", "pan(0, 1)", "Pan down", group=_PAN),
    ]

    def __init__(self, image: np.ndarray, labels=(), **kwargs) -> None:
        super().__init__(**kwargs)
        a = np.asarray(image)
        rgb = cv2.cvtColor(a, cv2.COLOR_GRAY2RGB) if a.ndim == 2 else np.ascontiguousarray(a[:, :, 2::-1])
        self.image = rgb
        self.labels = [(float(x), float(y), str(text)) for x, y, text in labels]
        self.zoom = 1.0
        h, w = rgb.shape[:2]
        self.centre = np.array([w / 2, h / 2])
        self._strips: list[Strip] | None = None
        self._drawn_for: tuple[int, int] | None = None

    # -- geometry --------------------------------------------------------------------------------
    def scale(self) -> float:
        """Half-block dots per image pixel at the current zoom."""
        h, w = self.image.shape[:2]
        cols, rows = max(self.size.width, 1), max(self.size.height, 1)
        return min(cols / w, 2 * rows / h) * self.zoom

    def _clamp(self) -> None:
        h, w = self.image.shape[:2]
        s = self.scale()
        half = np.array([self.size.width, 2 * self.size.height]) / (2 * s)
        size = np.array([w, h], float)
        # a picture smaller than the view stays centred; a larger one keeps the view inside it
        self.centre = np.where(2 * half >= size, size / 2, np.clip(self.centre, half, size - half))

    def to_dots(self, xy: np.ndarray) -> np.ndarray:
        """Image pixels ``(x, y)`` (N, 2) -> half-block dots ``(col, dot row)`` (N, 2)."""
        s = self.scale()
        origin = np.array([self.size.width / 2, self.size.height]) - self.centre * s
        return np.asarray(xy, float).reshape(-1, 2) * s + origin

    # -- drawing ---------------------------------------------------------------------------------
    def _render_lines(self) -> list[Strip]:
        cols, rows = self.size.width, self.size.height
        canvas = np.empty((2 * rows, cols, 3), np.uint8)
        canvas[:] = _BACKGROUND
        h, w = self.image.shape[:2]
        s = self.scale()
        (ox, oy), = self.to_dots(np.zeros((1, 2)))
        # the image's pixels that fall on the canvas, and where they go
        x0, x1 = max(0.0, -ox / s), min(float(w), (cols - ox) / s)
        y0, y1 = max(0.0, -oy / s), min(float(h), (2 * rows - oy) / s)
        c0, c1 = int(round(x0 * s + ox)), int(round(x1 * s + ox))
        r0, r1 = int(round(y0 * s + oy)), int(round(y1 * s + oy))
        if c1 > c0 and r1 > r0:
            crop = self.image[int(np.floor(y0)):int(np.ceil(y1)), int(np.floor(x0)):int(np.ceil(x1))]
            interp = cv2.INTER_AREA if s < 1 else cv2.INTER_NEAREST
            canvas[r0:r1, c0:c1] = cv2.resize(crop, (c1 - c0, r1 - r0), interpolation=interp)
        labels: dict[tuple[int, int], str] = {}
        if self.labels:
            dots = self.to_dots(np.array([(x, y) for x, y, _ in self.labels]))
            for (dc, dr), (_, _, text) in zip(dots, self.labels):
                row, col = int(dr // 2), int(dc) - len(text) // 2
                for i, ch in enumerate(text):
                    if 0 <= row < rows and 0 <= col + i < cols:
                        labels[(row, col + i)] = ch
        lines = []
        for r in range(rows):
            top, bottom = canvas[2 * r], canvas[2 * r + 1]
            segments = []
            for c in range(cols):
                label = labels.get((r, c))
                if label is not None:
                    segments.append(Segment(label, _LABEL))
                else:
                    segments.append(Segment("▀", _style(tuple(top[c].tolist()), tuple(bottom[c].tolist()))))
            lines.append(Strip(Segment.simplify(segments), cols))
        return lines

    def render_line(self, y: int) -> Strip:
        size = (self.size.width, self.size.height)
        if self._strips is None or self._drawn_for != size:
            self._clamp()
            self._strips, self._drawn_for = self._render_lines(), size
        return self._strips[y] if y < len(self._strips) else Strip.blank(self.size.width)

    def _changed(self) -> None:
        self._clamp()
        self._strips = None
        self.refresh()

    # -- actions ---------------------------------------------------------------------------------
    def action_zoom(self, step: int) -> None:
        self.zoom = float(np.clip(self.zoom * ZOOM_STEP ** step, 1.0, MAX_ZOOM))
        self._changed()

    def action_fit(self) -> None:
        self.zoom = 1.0
        self._changed()

    def action_pan(self, dx: int, dy: int) -> None:
        s = self.scale()
        # an eighth of the view per key press
        self.centre = self.centre + np.array([dx * self.size.width, dy * 2 * self.size.height]) / (8 * s)
        self._changed()

    def on_mouse_scroll_up(self, event) -> None:
        self.action_zoom(1)

    def on_mouse_scroll_down(self, event) -> None:
        self.action_zoom(-1)
