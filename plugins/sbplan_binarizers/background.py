"""Ink is what is clearly darker than the floor around it, the floor found by a closing.

A morphological closing (a maximum filter, then a minimum filter, with a square larger than a
symbol's strokes) erases the dark symbols and keeps everything larger: the floor's brightness,
lighting gradients, highlights, and the sharp edge of a shadow or an obstacle exactly where it is.
A box mean (``local-mean``) smears such an edge over its whole window, so the shadowed side of
the edge turns into a band of false ink that welds onto nearby symbols; the closing does not.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import cv2
import numpy as np

from sbplan.errors import InputError
from sbplan.imageio import as_gray
from sbplan.stages import Binarizer, option


@dataclass(kw_only=True, frozen=True)
class BackgroundBinarizer(Binarizer):
    """Pixels darker than ``(1 - offset)`` times the closed (symbol-free) image around them."""

    name = "background"
    description = "ink = darker than the floor estimated by a morphological closing (keeps shadow edges sharp)"

    window: int = option(0, "side of the closing's square in pixels; 0 = from the symbol size, else 31")
    offset: float = option(0.35, "how much darker than the floor ink is, as a fraction of the floor's level")
    min_contrast: int = option(8, "grey levels below the floor that ink must be at the least")
    downscale: int = option(2, "the closing runs on an image this many times smaller (speed)")
    opening: int = option(-1, "side of the square ink must contain (morphological opening); 0 = off, "
                              "-1 = a 25th of the symbol size, at least 3")

    def __post_init__(self) -> None:
        if self.window < 0 or (self.window and self.window < 3):
            raise InputError(f"window: must be 0 or >= 3 pixels, got {self.window}")
        if not 0.0 <= self.offset < 1.0:
            raise InputError(f"offset: must be in [0, 1), got {self.offset}")
        if self.min_contrast < 0:
            raise InputError(f"min_contrast: must be >= 0, got {self.min_contrast}")
        if self.downscale < 1:
            raise InputError(f"downscale: must be >= 1, got {self.downscale}")
        if self.opening < -1:
            raise InputError(f"opening: must be -1 (automatic), 0 (off) or a side in pixels, got {self.opening}")

    def with_symbol_size(self, size_px: float) -> "BackgroundBinarizer":
        """This binarizer fitted to symbols about ``size_px`` pixels across."""
        fitted = self
        if not self.window:
            fitted = replace(fitted, window=max(int(round(size_px)), 9))
        if self.opening == -1:
            fitted = replace(fitted, opening=max(3, int(round(size_px / 25))))
        return fitted

    def binarize(self, gray: np.ndarray) -> np.ndarray:
        gray = as_gray(gray, name="gray")
        h, w = gray.shape
        window = self.window or 31
        f = max(1, min(self.downscale, window // 6))
        small = cv2.resize(gray, (max(1, w // f), max(1, h // f)), interpolation=cv2.INTER_AREA) if f > 1 else gray
        k = max(3, int(round(window / f)))
        kernel = cv2.getStructuringElement(cv2.MORPH_RECT, (k, k))
        floor = cv2.morphologyEx(small, cv2.MORPH_CLOSE, kernel, borderType=cv2.BORDER_REPLICATE)
        if f > 1:
            floor = cv2.resize(floor, (w, h), interpolation=cv2.INTER_LINEAR)
        thr = np.minimum(cv2.convertScaleAbs(floor, alpha=1.0 - self.offset), cv2.subtract(floor, self.min_contrast))
        ink = (gray < thr).view(np.uint8)
        opening = 3 if self.opening == -1 else self.opening
        if opening > 1:
            # thin dark streaks (texture lines, the rim of a shadow) must not weld onto symbols
            ink = cv2.morphologyEx(ink, cv2.MORPH_OPEN, cv2.getStructuringElement(cv2.MORPH_RECT, (opening, opening)))
        return ink.view(bool)
