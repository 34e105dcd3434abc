"""Douglas–Peucker polygon approximation (OpenCV's approxPolyDP)."""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import ClassVar

import cv2
import numpy as np

from sbplan.contours import Contour
from sbplan.contracts import ContourApproximator, option
from sbplan.errors import InputError
from sbplan.polygons import PolygonBatch

from ._common import contour_points, three_vertices

__all__ = ["DouglasPeucker"]


#: Coordinates beyond this span make the compiled loop's whole-number distances overflow int64
#: (its squared distances times squared chord lengths): such contours take OpenCV's own call.
_EXACT_SPAN = 30_000


@functools.cache
def _compiled():
    """The compiled loop, imported on first use (numba takes a moment; see ``_kernels``), or None
    when it does not give this OpenCV's vertices: it takes OpenCV 5's steps (the distance to the
    chord's segment, opencv/opencv#28119), and older releases measure the distance to its line.
    Checked once, on 300 seeded random closed point lists, against ``cv2.approxPolyDP``."""
    from . import _kernels
    rng = np.random.default_rng(0)
    for _ in range(300):
        points = np.cumsum(rng.integers(-3, 4, (int(rng.integers(3, 40)), 2)), axis=0).astype(np.int32)
        vertices, _ = _kernels.douglas_peucker(points, np.array([0, len(points)], np.int64), 2.25)
        if not np.array_equal(vertices, cv2.approxPolyDP(points, 1.5, True).reshape(-1, 2)):
            return None
    return _kernels


@dataclass(kw_only=True, frozen=True)
class DouglasPeucker(ContourApproximator):
    """Douglas–Peucker approximation of the closed pixel contour, ``cv2.approxPolyDP``'s vertices
    (a frame's contours in one compiled loop with OpenCV's steps, where it gives OpenCV's answer).

    Every contour pixel lies within ``epsilon`` of the polygon. The default 1.5 px: the boundary
    pixels of a digitized straight edge stay within 1 px of the chord between its end pixels, so
    any epsilon of at least 1 collapses a rasterized edge to one segment, and the extra half pixel
    absorbs single-pixel noise at the edges' ends; corners of symbols a few pixels large and more
    are kept. With ``relative > 0`` the tolerance grows with the contour:
    ``max(epsilon, relative * perimeter)``, the usual OpenCV idiom for large outlines.
    """

    name: ClassVar[str] = "douglas-peucker"
    description: ClassVar[str] = "Douglas-Peucker polygon (cv2.approxPolyDP) with a pixel tolerance"

    epsilon: float = option(1.5, "largest distance (pixels) of a contour pixel from the polygon")
    relative: float = option(0.0, "if > 0, tolerance is max(epsilon, relative * contour perimeter)")

    def __post_init__(self) -> None:
        for key in ("epsilon", "relative"):
            v = getattr(self, key)
            if isinstance(v, bool) or not isinstance(v, (int, float, np.number)) or not np.isfinite(v):
                raise InputError(f"option {key}: expected a finite number, got {v!r}")
        if self.epsilon < 0:
            raise InputError(f"option epsilon: must be >= 0 pixels, got {self.epsilon}")
        if not 0 <= self.relative < 0.5:
            raise InputError(f"option relative: must lie in [0, 0.5), got {self.relative}")

    def approximate(self, contour) -> np.ndarray:
        pts = contour_points(contour)
        curve = pts.astype(np.float32).reshape(-1, 1, 2)
        eps = float(self.epsilon)
        if self.relative > 0:
            eps = max(eps, self.relative * cv2.arcLength(curve, True))
        out = cv2.approxPolyDP(curve, eps, True).reshape(-1, 2).astype(np.float64)
        if len(out) < 3:
            return three_vertices(pts)
        return out

    def approximate_many(self, contours) -> PolygonBatch:
        """:meth:`approximate` of many contours, as one :class:`~sbplan.polygons.PolygonBatch`.

        For :class:`~sbplan.contours.Contour` input with a fixed tolerance, the per-contour validation
        and float conversion are skipped (the extractor's pixels are valid by construction): that
        is most of a small contour's cost.
        """
        if not contours:
            return PolygonBatch(np.zeros((0, 2)), np.zeros(0, np.int64))
        if self.relative > 0:
            return PolygonBatch.from_list([self.approximate(c) for c in contours])
        eps = float(self.epsilon)
        try:
            # One compiled loop over all contours (OpenCV's steps, the same vertices: see
            # _kernels): a call of approxPolyDP per contour costs more than its arithmetic.
            # OpenCV's int32 points go in as they come; anything else (not a Contour, other
            # dtypes) takes the path below, as does a contour too short to keep three vertices.
            points = [c.points for c in contours]
            lengths = np.fromiter(map(len, points), np.int64, len(points))
            flat = np.concatenate(points)
        except (AttributeError, TypeError, ValueError):
            return self._approximate_checked(contours, eps)
        kernels = _compiled()
        if (kernels is None or flat.dtype != np.int32 or flat.ndim != 2 or flat.shape[1] != 2 or lengths.min() < 3
                or int(flat.max()) - int(flat.min()) > _EXACT_SPAN):
            return self._approximate_checked(contours, eps)
        starts = np.zeros(len(lengths) + 1, np.int64)
        np.cumsum(lengths, out=starts[1:])
        vertices, counts = kernels.douglas_peucker(flat, starts, eps * eps)
        if counts.min() < 3:
            return self._approximate_checked(contours, eps)
        # vertices picked from pixel contours: finite, >= 3 per polygon, so no validation again
        return PolygonBatch.unchecked(vertices.astype(np.float64), counts)

    def _approximate_checked(self, contours, eps: float) -> PolygonBatch:
        """:meth:`approximate_many`'s general path: per-contour checks and conversions."""
        out = []
        for c in contours:
            if not isinstance(c, Contour) or len(c.points) < 3:
                return PolygonBatch.from_list([self.approximate(c) for c in contours])
            pts = c.points if c.points.dtype == np.int32 else c.points.astype(np.int32)
            poly = cv2.approxPolyDP(pts, eps, True).reshape(-1, 2)
            out.append(poly if len(poly) >= 3 else three_vertices(pts))
        counts = np.fromiter(map(len, out), np.int64, len(out))
        return PolygonBatch(np.concatenate(out).astype(np.float64), counts)
