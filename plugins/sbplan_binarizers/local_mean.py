"""Local-mean thresholding: ink is what is clearly darker than its neighbourhood.

A global threshold breaks under the lighting errors the paper names (gradients, shadows,
highlights, a gain change of 40 %). Comparing each pixel with the mean of a window about the size of
a symbol survives all of them, because every one of them changes slowly compared with a symbol's
stroke. The offset is relative to the local mean, so it scales with the light: in a dark corner a
symbol's contrast is smaller in grey levels, but not in ratio.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import cv2
import numpy as np

from sbplan.errors import InputError
from sbplan.imageio import as_gray
from sbplan.stages import Binarizer, option


@dataclass(kw_only=True, frozen=True)
class LocalMeanBinarizer(Binarizer):
    """Pixels darker than ``(1 - offset)`` times the mean of a ``window`` box around them."""

    name = "local-mean"
    description = "ink = darker than the local mean by a relative offset (robust to gradients and shadows)"

    window: int = option(0, "box side in pixels (odd); 0 = derived from the symbol size, else 31")
    offset: float = option(0.18, "how much darker than the local mean ink is, as a fraction of the mean")
    min_contrast: int = option(6, "grey levels below the local mean that ink must be at the least")
    downscale: int = option(4, "the local mean is computed on an image this many times smaller (speed)")
    opening: int = option(-1, "side of the square ink must contain (morphological opening); 0 = off, "
                                "-1 = a 25th of the symbol size, at least 3")

    def __post_init__(self) -> None:
        if self.window < 0 or (self.window and (self.window < 3 or self.window % 2 == 0)):
            raise InputError(f"window: must be 0 or an odd number >= 3, got {self.window}")
        if not 0.0 <= self.offset < 1.0:
            raise InputError(f"offset: must be in [0, 1), got {self.offset}")
        if self.min_contrast < 0:
            raise InputError(f"min_contrast: must be >= 0, got {self.min_contrast}")
        if self.opening < -1:
            raise InputError(f"opening: must be -1 (automatic), 0 (off) or a side in pixels, got {self.opening}")
        if self.downscale < 1:
            raise InputError(f"downscale: must be >= 1, got {self.downscale}")

    def with_symbol_size(self, size_px: float) -> "LocalMeanBinarizer":
        """This binarizer with its window fitted to symbols of about ``size_px`` pixels across."""
        fitted = self
        if not self.window:
            fitted = replace(fitted, window=max(int(round(size_px * 2.5)) | 1, 15))
        if self.opening == -1:
            fitted = replace(fitted, opening=max(3, int(round(size_px / 25))))
        return fitted

    def binarize(self, gray: np.ndarray) -> np.ndarray:
        gray = as_gray(gray, name="gray")
        window = self.window or 31
        h, w = gray.shape
        f = max(1, min(self.downscale, window // 5))
        if f > 1:
            # A box mean is smooth: computing it on a reduced image and enlarging it again costs a
            # fraction of the full-size filter and changes the threshold by well under a grey level.
            small = cv2.resize(gray, (max(1, w // f), max(1, h // f)), interpolation=cv2.INTER_AREA)
            k = max(3, (window // f) | 1)
            mean_small = cv2.blur(small, (k, k), borderType=cv2.BORDER_REPLICATE)
            mean = cv2.resize(mean_small, (w, h), interpolation=cv2.INTER_LINEAR)
        else:
            mean = cv2.blur(gray, (window, window), borderType=cv2.BORDER_REPLICATE)
        # threshold = mean * (1 - offset), but at least min_contrast below the mean
        scale = 1.0 - self.offset
        thr = cv2.convertScaleAbs(mean, alpha=scale)
        thr = np.minimum(thr, cv2.subtract(mean, self.min_contrast))
        ink = (gray < thr).view(np.uint8)
        opening = 3 if self.opening == -1 else self.opening
        if opening > 1:
            # Shadow edges and texture lines are thin dark streaks; where one touches a symbol it
            # welds onto the symbol's outline and changes its shape. An opening removes streaks
            # thinner than the square and leaves the symbols' broad strokes as they are.
            kernel = cv2.getStructuringElement(cv2.MORPH_RECT, (opening, opening))
            ink = cv2.morphologyEx(ink, cv2.MORPH_OPEN, kernel)
        return ink.view(bool)
