"""What the local binarizers share: ink is darker than a local brightness level by a relative
offset, computed on a reduced image for speed, with thin streaks opened away."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import ClassVar

import cv2
import numpy as np

from sbplan.errors import InputError
from sbplan.imageio import as_gray
from sbplan.stages import Binarizer, option


@dataclass(kw_only=True, frozen=True)
class LocalThresholdBinarizer(Binarizer):
    """Pixels darker than ``(1 - offset)`` times a local level (subclasses say which level).

    A base class, not a stage of its own (it has no name).
    """

    #: the window as a multiple of the symbol size, and its least side, when fitted to symbols
    window_per_symbol: ClassVar[float] = 1.0
    min_window: ClassVar[int] = 9

    window: int = option(0, "side of the local window in pixels; 0 = from the symbol size, else 31")
    offset: float = option(0.2, "how much darker than the local level ink is, as a fraction of that level")
    min_contrast: int = option(8, "grey levels below the local level that ink must be at the least")
    downscale: int = option(2, "the local level is computed on an image this many times smaller (speed)")
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

    def with_symbol_size(self, size_px: float) -> "LocalThresholdBinarizer":
        """This binarizer with its automatic options fitted to symbols ``size_px`` pixels across."""
        fitted = self
        if not self.window:
            fitted = replace(fitted, window=max(int(round(size_px * self.window_per_symbol)), self.min_window))
        if self.opening == -1:
            fitted = replace(fitted, opening=max(3, int(round(size_px / 25))))
        return fitted

    def local_level(self, small: np.ndarray, window: int) -> np.ndarray:
        """The brightness ink is compared with, on the reduced image, for a window of ``window``
        reduced pixels. Same shape and dtype as ``small``."""
        raise NotImplementedError

    def binarize(self, gray: np.ndarray) -> np.ndarray:
        gray = as_gray(gray, name="gray")
        h, w = gray.shape
        window = self.window or 31
        # The local level varies slowly: computing it on a reduced image and enlarging it again
        # costs a fraction of the full-size filter.
        f = max(1, min(self.downscale, window // 5))
        small = cv2.resize(gray, (max(1, w // f), max(1, h // f)), interpolation=cv2.INTER_AREA) if f > 1 else gray
        level = self.local_level(small, max(3, int(round(window / f))))
        thr = np.minimum(cv2.convertScaleAbs(level, alpha=1.0 - self.offset), cv2.subtract(level, self.min_contrast))
        if f > 1:
            # Nearest-neighbour enlargement: the threshold changes by a grey level or two between
            # neighbouring reduced pixels, and this is a quarter of the hot path's cost cheaper.
            thr = cv2.resize(thr, (w, h), interpolation=cv2.INTER_NEAREST)
        ink = (gray < thr).view(np.uint8)
        opening = 3 if self.opening == -1 else self.opening
        if opening > 1:
            # Shadow rims and texture lines are thin dark streaks; where one touches a symbol it
            # welds onto the symbol's outline. An opening removes streaks thinner than the square.
            ink = cv2.morphologyEx(ink, cv2.MORPH_OPEN, cv2.getStructuringElement(cv2.MORPH_RECT, (opening, opening)))
        return ink.view(bool)
