"""Is a matched symbol the whole symbol? A check that uses where the fixed camera saw it.

Fourier descriptors and areas are global: an obstacle that clips a twentieth of a symbol changes
them by about as much as defocus or a lighting change does. But the camera is fixed, so every
cell's symbol outline lies where the reference saw it. Defocus and light move the whole outline
in or out by about the same amount; an obstacle moves part of it a lot. The deviation of a found
outline from its cell's reference outline, after removing the common shift, separates the two.
"""

from __future__ import annotations

import cv2
import numpy as np

from .geometry import resample_xy

#: Points per outline at which the deviation is measured.
SAMPLES = 64


def signed_distance_map(polygons: list[np.ndarray], shape: tuple[int, int]) -> np.ndarray:
    """Signed distance in pixels to the nearest reference outline: negative inside a symbol.

    Parameters
    ----------
    polygons : list of ndarray (K, 2)
        Reference symbol outlines ``(x, y)``.
    shape : (H, W)

    Returns
    -------
    ndarray of shape (H, W), float32.
    """
    mask = np.zeros(shape, np.uint8)
    cv2.fillPoly(mask, [np.rint(p * 16).astype(np.int32) for p in polygons], 255, cv2.LINE_8, shift=4)
    outside = cv2.distanceTransform(255 - mask, cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    inside = cv2.distanceTransform(mask, cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    # distanceTransform gives 1 on both sides of the border; shift each side by half a pixel so
    # the border itself reads 0 and the map is continuous across it
    return np.where(mask > 0, 0.5 - inside, outside - 0.5).astype(np.float32)


def outline_deviation(polygons: list[np.ndarray], distance_map: np.ndarray) -> np.ndarray:
    """How far each outline strays from the reference outlines, beyond a common shift.

    Returns, per polygon, the largest absolute deviation (pixels) of its arc-length samples'
    signed distances (bilinear) from their median, shape (n,).
    """
    if not polygons:
        return np.zeros(0)
    x, y = resample_xy(polygons, SAMPLES)
    # bilinear samples: the outline's sub-pixel position matters at this scale
    d = cv2.remap(distance_map, x.astype(np.float32), y.astype(np.float32), cv2.INTER_LINEAR,
                  borderMode=cv2.BORDER_REPLICATE)
    dev = np.abs(d - np.median(d, axis=1, keepdims=True))
    return dev.max(axis=1)
