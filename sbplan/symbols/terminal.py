"""A symbol drawn in the terminal with Unicode half-blocks or braille dots.

Terminal cells are about twice as tall as wide, so both modes use square "pixels": half-blocks
split a cell into 1 x 2 pixels (``▀ ▄ █``), braille into 2 x 4 dots (U+2800..U+28FF).
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from .raster import coverage, place, symbol_rings

__all__ = ["MODES", "draw"]

MODES = ("half", "braille")
_HALF = np.array([" ", "▄", "▀", "█"])
# Braille dot bits, indexed [row, col] of the 4 x 2 dot cell.
_BRAILLE_BITS = np.array([[0x01, 0x08], [0x02, 0x10], [0x04, 0x20], [0x40, 0x80]], np.int64)


def draw(symbol, *, width: int = 32, mode: str = "half", angle: float = 0.0, invert: bool = False) -> str:
    """The symbol as lines of text.

    Parameters
    ----------
    symbol : str or polygon(s)
        A registered symbol name, or ``[outline, *holes]`` in a unit box (y down).
    width : int
        Width of the drawing in terminal columns (4..400). The height follows from the shape.
    mode : {"half", "braille"}
        Half-block pixels (1 x 2 per cell) or braille dots (2 x 4 per cell).
    angle : float
        Rotation in degrees, counter-clockwise as displayed.
    invert : bool
        Draw the floor instead of the ink (for light-on-dark terminals that want a printed look).

    Returns
    -------
    str
        ``rows`` lines of exactly ``width`` characters, joined by newlines (no trailing newline).
    """
    if mode not in MODES:
        raise InputError(f"mode: expected one of {', '.join(MODES)}, got {mode!r}")
    if isinstance(width, bool) or not isinstance(width, (int, np.integer)) or not 4 <= width <= 400:
        raise InputError(f"width: expected an integer between 4 and 400 columns, got {width!r}")
    px_w, cell_h = (width, 2) if mode == "half" else (2 * width, 4)
    margin = 1 if mode == "half" else 2
    rings = place(symbol_rings(symbol), size=1.0, angle=angle)
    pts = np.vstack(rings)
    lo, span = pts.min(axis=0), np.ptp(pts, axis=0)
    scale = (px_w - 2 * margin) / max(span[0], span[1])
    px_h = int(np.ceil(span[1] * scale)) + 2 * margin
    px_h += (-px_h) % cell_h
    off = np.array([margin, (px_h - span[1] * scale) / 2]) - lo * scale - 0.5
    on = coverage([r * scale + off for r in rings], (px_h, px_w), supersample=4) >= 0.5
    if invert:
        on = ~on
    if mode == "half":
        top, bottom = on[0::2], on[1::2]
        chars = _HALF[top.astype(int) * 2 + bottom.astype(int)]
    else:
        cells = on.reshape(px_h // 4, 4, width, 2).transpose(0, 2, 1, 3)
        codes = 0x2800 + (cells * _BRAILLE_BITS).sum(axis=(2, 3))
        chars = np.vectorize(chr)(codes)
    return "\n".join("".join(row) for row in chars)
