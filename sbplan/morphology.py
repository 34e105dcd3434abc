"""Morphology on masks that leaves shapes where they are.

OpenCV erodes and dilates with the same anchor (the kernel's middle, ``side // 2``). An opening
(erosion, then dilation) by a square of even side therefore moves every shape one pixel right and
down: a 10 px square at x 10..19 comes out at 11..20. Detection relates the outlines traced in a
binary image to the grey image they came from (edge probes, grey-level centres, the scratch
repair), so a pixel's drift matters: at a symbol size where the binarizer's opening is 4 px (a
4K frame's working image, a 1920x1080 one) every outline sat a pixel off its grey edge.
"""

from __future__ import annotations

import functools

import cv2
import numpy as np

__all__ = ["open_square"]


def open_square(mask: np.ndarray, side: int) -> np.ndarray:
    """``mask`` (H, W), uint8) opened by a ``side`` x ``side`` square: the union of the squares
    that fit in it, where they fit.

    An odd side is OpenCV's own ``MORPH_OPEN``; for an even side the dilation takes the mirrored
    anchor, so nothing moves. Returns a new uint8 array of ``mask``'s shape.

    Examples
    --------
    >>> import numpy as np
    >>> mask = np.zeros((30, 30), np.uint8)
    >>> mask[10:20, 10:20] = 1
    >>> ys, xs = np.nonzero(open_square(mask, 4))
    >>> int(xs.min()), int(xs.max()), int(ys.min()), int(ys.max())
    (10, 19, 10, 19)
    """
    kernel = _square(side)
    if side % 2:
        return cv2.morphologyEx(mask, cv2.MORPH_OPEN, kernel)
    a = side // 2
    return cv2.dilate(cv2.erode(mask, kernel, anchor=(a, a)), kernel, anchor=(side - 1 - a, side - 1 - a))


@functools.lru_cache(maxsize=16)
def _square(side: int) -> np.ndarray:
    """The square structuring element (made once, not per frame)."""
    return cv2.getStructuringElement(cv2.MORPH_RECT, (side, side))
