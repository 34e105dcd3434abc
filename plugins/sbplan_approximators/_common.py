"""What the built-in approximators share: input handling and deviation measurement."""

from __future__ import annotations

import numpy as np

from sbplan.contours import FREEMAN_STEPS, Contour, as_points
from sbplan.errors import ContourError


def contour_points(contour) -> np.ndarray:
    """The boundary pixels of a Contour (or of an (N, 2) array) as float64 (N, 2), N >= 3."""
    pts = contour.points if isinstance(contour, Contour) else contour
    return as_points(pts, name="contour")


def contour_chain(contour, points: np.ndarray) -> np.ndarray:
    """The Freeman chain of a contour: its own, or derived from 8-connected points.

    Raises ContourError when the points are not an 8-connected closed pixel path.
    """
    if isinstance(contour, Contour) and len(contour.chain) == len(points):
        return np.asarray(contour.chain, dtype=np.int64)
    step = np.roll(points, -1, axis=0) - points
    if not np.array_equal(step, np.round(step)) or np.abs(step).max() > 1 or (np.abs(step).sum(axis=1) == 0).any():
        raise ContourError("contour: points are not an 8-connected closed pixel path, so they have no "
                           "Freeman chain")
    lut = np.full((3, 3), -1, np.int64)
    lut[FREEMAN_STEPS[:, 1] + 1, FREEMAN_STEPS[:, 0] + 1] = np.arange(8)
    return lut[step[:, 1].astype(np.int64) + 1, step[:, 0].astype(np.int64) + 1]


def polygon_deviation(points: np.ndarray, polygon: np.ndarray) -> float:
    """The largest distance from any of ``points`` (N, 2) to the closed polygon's edges (M, 2)."""
    a = polygon
    b = np.roll(polygon, -1, axis=0)
    ab = b - a
    den = np.einsum("ij,ij->i", ab, ab)
    ap = points[:, None, :] - a[None, :, :]
    t = np.clip(np.einsum("nmk,mk->nm", ap, ab) / np.where(den > 0, den, 1.0), 0.0, 1.0)
    d = ap - t[..., None] * ab[None]
    return float(np.sqrt(np.einsum("nmk,nmk->nm", d, d).min(axis=1)).max())


def three_vertices(points: np.ndarray) -> np.ndarray:
    """A fallback triangle for contours too small to keep three vertices: three points about a third
    of the outline apart, in traversal order."""
    n = len(points)
    return points[[0, n // 3, (2 * n) // 3]].copy()
