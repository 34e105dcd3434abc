"""Local-mean thresholding: ink is what is clearly darker than the mean around it.

A global threshold breaks under the lighting errors the paper names (gradients, shadows, a gain
change of 40 %). Comparing each pixel with the mean of a window a few symbols wide survives most of
them, because they change slowly compared with a symbol's stroke; the offset is relative to the
mean, so it scales with the light. Next to a sharp shadow or obstacle edge the box mean smears the
edge over its window (the ``background`` binarizer does not).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from sbplan.contracts import option

from ._local import LocalThresholdBinarizer


@dataclass(kw_only=True, frozen=True)
class LocalMeanBinarizer(LocalThresholdBinarizer):
    """Pixels darker than ``(1 - offset)`` times the mean of a ``window`` box around them."""

    name = "local-mean"
    description = "ink = darker than the local mean by a relative offset (robust to gradients and shadows)"
    window_per_symbol = 2.5
    min_window = 15

    offset: float = option(0.18, "how much darker than the local mean ink is, as a fraction of the mean")
    min_contrast: int = option(6, "grey levels below the local mean that ink must be at the least")
    downscale: int = option(4, "the local mean is computed on an image this many times smaller (speed)")

    def level_reach(self, window: int) -> int:
        return window // 2  # the box's anchor is its centre

    def local_level(self, small: np.ndarray, window: int) -> np.ndarray:
        return cv2.blur(small, (window, window), borderType=cv2.BORDER_REPLICATE)
