"""The working resolution: symbols far larger than the shapes need are found in a smaller image.

A 4K ceiling camera shows a floor's symbols at 150 px and more; contours, approximation and the
outline checks need about 40. Calibration picks an integer factor from the symbol size
(:func:`work_factor`), and every frame is reduced by it (area averaging) before it is binarized and
its contours traced; the polygons found are mapped back to the frame's pixels at once, so every
check after that, and every result, is in the frame's (and the calibration's) pixels as before.
The cost of the per-pixel steps then follows the symbols' size, not the camera's resolution.

Coordinates: pixel centres. A reduced pixel ``(u, v)`` covers frame pixels ``[u f, (u + 1) f)``, so
its centre is frame pixel ``(u + 0.5) f - 0.5``.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from ..imageio import halve

__all__ = ["WorkScale", "work_factor", "WORK_SYMBOL_PX"]

#: Symbols are worked on at about this size (the square root of their area, pixels) or more: the
#: size the outline checks were tuned on (1280 x 960 frames of a 10 x 5 grid show them at ~38 px).
WORK_SYMBOL_PX = 36


def work_factor(symbol_size_px: float) -> int:
    """The reduction factor for symbols of ``symbol_size_px`` (square root of their area): the
    largest power of two that keeps them at :data:`WORK_SYMBOL_PX` or more, at least 1 (OpenCV
    halves an image by area averaging about ten times faster than it reduces it by 3 or 4 at once,
    so a power of two is reached by halvings)."""
    if not math.isfinite(symbol_size_px) or symbol_size_px < 2 * WORK_SYMBOL_PX:
        return 1
    return 1 << int(math.floor(math.log2(symbol_size_px / WORK_SYMBOL_PX)))


class WorkScale:
    """Frame pixels <-> working pixels for a reduction ``factor`` of frames of ``shape`` (H, W).

    With factor 1 every method returns its input unchanged (bit for bit).
    """

    __slots__ = ("factor", "shape", "work_shape", "fx", "fy", "area")

    def __init__(self, factor: int, shape: tuple[int, int]):
        self.factor = max(1, int(factor))
        h, w = int(shape[0]), int(shape[1])
        self.shape = (h, w)
        self.work_shape = (max(1, h // self.factor), max(1, w // self.factor))
        self.fy, self.fx = h / self.work_shape[0], w / self.work_shape[1]
        self.area = self.fx * self.fy

    @property
    def identity(self) -> bool:
        return self.factor == 1

    def reduce(self, gray: np.ndarray) -> np.ndarray:
        """The frame at the working resolution (area averaging)."""
        if self.identity:
            return gray
        gray = self.reduce_part(gray)
        if gray.shape != self.work_shape:
            gray = cv2.resize(gray, (self.work_shape[1], self.work_shape[0]), interpolation=cv2.INTER_AREA)
        return gray

    def reduce_part(self, part: np.ndarray) -> np.ndarray:
        """A part of the frame made ``factor`` times smaller by the halvings :meth:`reduce` uses:
        for a part whose corner and sides are multiples of the factor, exactly the whole frame's
        working pixels there."""
        f, h, w = self.factor, part.shape[0], part.shape[1]
        while f > 1 and f % 2 == 0 and h % 2 == 0 and w % 2 == 0:
            h, w, f = h // 2, w // 2, f // 2
            part = halve(part)
        if f > 1:
            part = cv2.resize(part, (max(1, w // f), max(1, h // f)), interpolation=cv2.INTER_AREA)
        return part

    def to_frame(self, xy: np.ndarray) -> np.ndarray:
        """Working pixels ``(..., 2)`` ``(x, y)`` -> frame pixels."""
        if self.identity:
            return xy
        xy = np.asarray(xy, dtype=np.float64)
        return (xy + 0.5) * (self.fx, self.fy) - 0.5

    def to_work(self, xy: np.ndarray) -> np.ndarray:
        """Frame pixels ``(..., 2)`` ``(x, y)`` -> working pixels."""
        if self.identity:
            return xy
        xy = np.asarray(xy, dtype=np.float64)
        return (xy + 0.5) / (self.fx, self.fy) - 0.5

    def __repr__(self) -> str:
        return f"WorkScale({self.factor}, {self.shape[1]}x{self.shape[0]} -> {self.work_shape[1]}x{self.work_shape[0]})"
