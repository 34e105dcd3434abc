"""Otsu's global threshold: the classic choice, kept for comparison.

It picks one threshold for the whole image, so a lighting gradient or a shadow moves symbols to
the wrong side of it: the paper's reason for wanting something better.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from sbplan.contracts import Binarizer
from sbplan.imageio import as_gray


@dataclass(kw_only=True, frozen=True)
class OtsuBinarizer(Binarizer):
    """Pixels darker than Otsu's global threshold."""

    name = "otsu"
    description = "one global threshold by Otsu's method (fragile under gradients and shadows)"

    def binarize(self, gray: np.ndarray) -> np.ndarray:
        gray = as_gray(gray, name="gray")
        _, binary = cv2.threshold(gray, 0, 1, cv2.THRESH_BINARY_INV | cv2.THRESH_OTSU)
        return binary.astype(bool)
