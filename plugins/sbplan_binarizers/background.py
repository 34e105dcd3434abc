"""Ink is what is clearly darker than the floor around it, the floor found by a closing.

A morphological closing (a maximum filter with a square about a symbol's size, then a slightly
smaller minimum filter) erases the dark symbols and keeps everything larger: the floor's
brightness, lighting gradients, highlights, and the sharp edge of a shadow or an obstacle where it
is. A box mean (``local-mean``) smears such an edge over its whole window, so the shadowed side of
the edge turns into a band of false ink that welds onto nearby symbols; the closing does not.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from sbplan.errors import InputError
from sbplan.stages import option

from ._local import LocalThresholdBinarizer


@dataclass(kw_only=True, frozen=True)
class BackgroundBinarizer(LocalThresholdBinarizer):
    """Pixels darker than ``(1 - offset)`` times the closed (symbol-free) image around them."""

    name = "background"
    description = "ink = darker than the floor estimated by a morphological closing (keeps shadow edges sharp)"

    # A soft cast shadow darkens the floor by up to half; at 20 % its rim next to an obstacle
    # read as ink (measured: shadows F1 0.95 -> 1.0 at 35 %).
    offset: float = option(0.35, "how much darker than the floor ink is, as a fraction of the floor's level")

    # A full closing (erosion as wide as the dilation) reaches past a soft glare blob and puts the
    # floor too low inside it, so washed-out ink rises above the threshold (highlights F1 0.95 on
    # 16 scenes); a plain maximum filter puts it too high beside anything bright, and shadow rims
    # turn into ink (shadows 0.95). Eroding with three quarters of the window: both >= 0.996.
    erosion: float = option(0.75, "side of the closing's erosion as a fraction of its dilation's (1 = a closing)")

    def __post_init__(self) -> None:
        super().__post_init__()
        if not 0.0 < self.erosion <= 1.0:
            raise InputError(f"erosion: must be in (0, 1], got {self.erosion}")

    def local_level(self, small: np.ndarray, window: int) -> np.ndarray:
        kernel = cv2.getStructuringElement(cv2.MORPH_RECT, (window, window))
        brightest = cv2.dilate(small, kernel, borderType=cv2.BORDER_REPLICATE)
        side = max(1, int(round(window * self.erosion)))
        shrink = cv2.getStructuringElement(cv2.MORPH_RECT, (side, side))
        return cv2.erode(brightest, shrink, borderType=cv2.BORDER_REPLICATE)
