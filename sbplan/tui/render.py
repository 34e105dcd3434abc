"""Drawing for the terminal: the calibration overlay picture and the braille map. No Textual.

The map is rasterized in numpy at braille-dot resolution (2 x 4 dots per terminal cell) and then
packed into one character per cell, so it reads in any terminal, tmux included.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np
from numpy.typing import ArrayLike

from ..imageio import as_gray

# BGR, as OpenCV draws
_GRID, _SYMBOL, _CENTRE, _REJECTED = (200, 140, 40), (60, 200, 60), (40, 40, 230), (230, 200, 0)


def calibration_overlay(image: np.ndarray, calibration) -> np.ndarray:
    """The reference with the fitted grid: cell borders (blue), found symbols (green outlines),
    cell centres (red crosses) and rejected contours (cyan x). Returns BGR (H, W, 3) uint8.

    Lines are drawn thick enough (about 1/150 of the image width) to survive the downscaling to
    a terminal's half-block resolution.
    """
    gray = as_gray(image, name="reference")
    out = cv2.cvtColor(gray, cv2.COLOR_GRAY2BGR)
    h, w = gray.shape
    t = max(1, round(max(h, w) / 300))
    grid = calibration.grid
    corners = grid.cell_corners_px()  # (rows + 1, cols + 1, 2)
    lines = [np.rint(corners[r]).astype(np.int32) for r in range(corners.shape[0])]
    lines += [np.rint(corners[:, c]).astype(np.int32) for c in range(corners.shape[1])]
    cv2.polylines(out, lines, False, _GRID, t, cv2.LINE_AA)
    polys = [np.rint(p).astype(np.int32) for p in calibration.symbol_polygons]
    cv2.polylines(out, polys, True, _SYMBOL, 2 * t, cv2.LINE_AA)
    size = 4 * t
    for x, y in np.asarray(calibration.stats.get("rejected_centres_px", []), float).reshape(-1, 2):
        cv2.drawMarker(out, (int(round(x)), int(round(y))), _REJECTED, cv2.MARKER_TILTED_CROSS, 2 * size, t)
    for x, y in grid.centres_px.reshape(-1, 2):
        cv2.drawMarker(out, (int(round(x)), int(round(y))), _CENTRE, cv2.MARKER_CROSS, 2 * size, 2 * t)
    return out


# -- the braille map ------------------------------------------------------------------------------
_BITS = np.array([[0x01, 0x08], [0x02, 0x10], [0x04, 0x20], [0x40, 0x80]], np.int32)  # [dot row, dot col]


@dataclass
class MapFrame:
    """World metres <-> terminal cells for a map of ``cols x rows`` cells showing ``bounds``.

    Braille dots are taken as square (a terminal cell is about twice as tall as wide), so the
    world keeps its aspect ratio; the floor is centred in the area.
    """

    cols: int
    rows: int
    bounds: tuple[float, float, float, float]  # xmin, ymin, xmax, ymax (metres, y up)
    scale: float = field(init=False)  # dots per metre
    x0: float = field(init=False)
    y0: float = field(init=False)

    def __post_init__(self) -> None:
        xmin, ymin, xmax, ymax = self.bounds
        wd, hd = 2 * self.cols, 4 * self.rows
        self.scale = min((wd - 1) / max(xmax - xmin, 1e-9), (hd - 1) / max(ymax - ymin, 1e-9))
        # dot coordinates of (xmin, ymax), the top-left corner of the floor
        self.x0 = (wd - (xmax - xmin) * self.scale) / 2
        self.y0 = (hd - (ymax - ymin) * self.scale) / 2

    def to_dots(self, xy: ArrayLike) -> np.ndarray:
        """World ``(x, y)`` (N, 2) -> dot ``(col, row)`` (N, 2), float."""
        p = np.asarray(xy, float).reshape(-1, 2)
        xmin, _, _, ymax = self.bounds
        return np.column_stack([self.x0 + (p[:, 0] - xmin) * self.scale, self.y0 + (ymax - p[:, 1]) * self.scale])

    def to_cell(self, xy: np.ndarray) -> np.ndarray:
        """World ``(x, y)`` (N, 2) -> terminal cell ``(col, row)`` (N, 2), int."""
        d = self.to_dots(xy)
        return np.column_stack([np.floor(d[:, 0] / 2), np.floor(d[:, 1] / 4)]).astype(int)

    def cell_to_world(self, col: float, row: float) -> np.ndarray:
        """The world point at the centre of terminal cell ``(col, row)``."""
        xmin, _, _, ymax = self.bounds
        dx, dy = 2 * col + 1.0, 4 * row + 2.0
        return np.array([xmin + (dx - self.x0) / self.scale, ymax - (dy - self.y0) / self.scale])


class BrailleCanvas:
    """Layers of dots packed into braille characters; the top layer with dots in a cell colours it.

    Parameters
    ----------
    frame : MapFrame
    layers : sequence of str
        Layer names, bottom first.
    """

    def __init__(self, frame: MapFrame, layers: tuple[str, ...]):
        self.frame = frame
        self.layers = tuple(layers)
        self.masks = np.zeros((len(layers), 4 * frame.rows, 2 * frame.cols), np.uint8)
        self.labels: dict[tuple[int, int], tuple[str, str]] = {}

    def _mask(self, layer: str) -> np.ndarray:
        return self.masks[self.layers.index(layer)]

    def fill(self, layer: str, polygon: np.ndarray) -> None:
        """Fill a world polygon (K, 2)."""
        pts = np.rint(self.frame.to_dots(polygon) * 16).astype(np.int32)
        cv2.fillPoly(self._mask(layer), [pts], 1, cv2.LINE_8, shift=4)

    def line(self, layer: str, points: ArrayLike, *, closed: bool = False, dotted: bool = False) -> None:
        """A world polyline (K, 2)."""
        pts = np.rint(self.frame.to_dots(points) * 16).astype(np.int32)
        m = self._mask(layer)
        if dotted:
            tmp = np.zeros_like(m)
            cv2.polylines(tmp, [pts], closed, 1, 1, cv2.LINE_8, shift=4)
            yy, xx = np.indices(tmp.shape)
            m |= tmp & ((xx + yy) % 2 == 0)
        else:
            cv2.polylines(m, [pts], closed, 1, 1, cv2.LINE_8, shift=4)

    def label(self, world_xy, text: str, layer: str) -> None:
        """A character (or a few) at the cell holding ``world_xy``, coloured like ``layer``."""
        col, row = self.frame.to_cell(np.asarray(world_xy, float))[0]
        for i, ch in enumerate(text):
            if 0 <= row < self.frame.rows and 0 <= col + i < self.frame.cols:
                self.labels[(int(row), int(col) + i)] = (ch, layer)

    def cells(self) -> tuple[np.ndarray, np.ndarray]:
        """Per terminal cell: the character code (rows, cols) and the colouring layer index (-1: none)."""
        n, hd, wd = self.masks.shape
        rows, cols = hd // 4, wd // 2
        blocks = self.masks.reshape(n, rows, 4, cols, 2).transpose(0, 1, 3, 2, 4)  # n, r, c, 4, 2
        bits = (blocks * _BITS).sum(axis=(3, 4))  # n, r, c
        union = np.bitwise_or.reduce(bits, axis=0) if n else np.zeros((rows, cols), np.int32)
        present = bits > 0
        top = np.where(present.any(axis=0), n - 1 - np.argmax(present[::-1], axis=0), -1)
        codes = np.where(union > 0, 0x2800 + union, ord(" "))
        for (r, c), (ch, layer) in self.labels.items():
            codes[r, c] = ord(ch)
            top[r, c] = self.layers.index(layer)
        return codes, top
