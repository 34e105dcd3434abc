"""Antialiased rasterization of symbol rings (shared by the camera view, the PNG tile and the
terminal drawing)."""

from __future__ import annotations

import math
from typing import Sequence

import cv2
import numpy as np

from ..errors import InputError
from ..synth import rings_centroid, symbol_outline

#: Sub-pixel bits handed to cv2.fillPoly: vertices are placed to 1/16 pixel.
_SHIFT = 4


def symbol_rings(symbol) -> list[np.ndarray]:
    """``[outline, *holes]`` of a registered symbol name or of polygons in a unit box (y down)."""
    return symbol_outline(symbol)


def place(rings: Sequence[np.ndarray], *, size: float, angle: float = 0.0,
          centre: tuple[float, float] = (0.0, 0.0)) -> list[np.ndarray]:
    """Scale unit-box rings to ``size`` pixels, rotate them by ``angle`` degrees (counter-clockwise
    as displayed) about their centre of area and move that centre to ``centre`` ``(x, y)``.

    Returns the rings as ``(N, 2)`` float64 ``(x, y)`` arrays, y down.
    """
    if not (isinstance(size, (int, float, np.number)) and math.isfinite(size) and size > 0):
        raise InputError(f"size: expected a positive number of pixels, got {size!r}")
    scaled = [np.asarray(r, np.float64) * float(size) for r in rings]
    c, _ = rings_centroid(scaled)
    a = math.radians(float(angle))
    # Counter-clockwise as displayed is clockwise in y-down maths, hence the transposed rotation.
    rot = np.array([[math.cos(a), math.sin(a)], [-math.sin(a), math.cos(a)]])
    return [(r - c) @ rot.T + np.asarray(centre, np.float64) for r in scaled]


def coverage(rings_px: Sequence[np.ndarray], shape: tuple[int, int], *, supersample: int = 4) -> np.ndarray:
    """Share of each pixel covered by the polygon with holes, shape ``(H, W)`` float32 in [0, 1].

    ``rings_px`` are in pixel coordinates ``(x, y)`` where integer values are pixel centres. The
    polygon is filled with the even-odd rule on a ``supersample`` times finer canvas and averaged
    down, which antialiases the edges like a camera's pixel integration.
    """
    h, w = int(shape[0]), int(shape[1])
    if h < 1 or w < 1:
        raise InputError(f"shape: expected a positive (H, W), got {shape!r}")
    s = int(supersample)
    canvas: np.ndarray = np.zeros((h * s, w * s), np.uint8)
    # Pixel centre (x, y) covers [x - 0.5, x + 0.5); on the fine canvas that is s*x + (s - 1)/2.
    pts = [np.rint(((np.asarray(r) + 0.5) * s - 0.5) * (1 << _SHIFT)).astype(np.int32).reshape(-1, 1, 2)
           for r in rings_px]
    cv2.fillPoly(canvas, pts, 255, lineType=cv2.LINE_8, shift=_SHIFT)
    if s > 1:
        # uint8 averaging keeps 1/255 steps of coverage, far below what the camera model resolves
        canvas = cv2.resize(canvas, (w, h), interpolation=cv2.INTER_AREA)
    return canvas.astype(np.float32) * np.float32(1 / 255)
