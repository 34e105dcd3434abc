"""The core's compiled loops (numba): centres of area, arc-length resampling and bounding boxes
of a whole :class:`~sbplan.polygons.PolygonBatch` at once, and halving an image.

Detection runs them on every frame's few dozen outlines, and halves every frame. As numpy
expressions over the packed points each is a dozen whole-array passes (index arrays,
``reduceat``, ``interp``) whose cost is in the calls, not the arithmetic; one loop over the points
costs a tenth.

Imported on first use only, like :mod:`sbplan.detection._kernels` (see there). The callers
validate; the kernels trust their inputs: the polygon loops ``points`` C-contiguous float64 (P, 2)
of finite values, ``starts`` and ``counts`` int64, every count >= 3; :func:`halve_u8` a 2-D uint8
image of even sides whose rows are contiguous (any row stride).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def centres_of_area(points, starts, counts, centres, areas):  # pragma: no cover - compiled
    """Equation (1)'s centre of area of each outline, and its unsigned area, written to ``centres``
    (m, 2) and ``areas`` (m,): :func:`sbplan.polygons.centroids`' arithmetic, outline by outline
    (relative to the mean of its vertices, so that large coordinates lose no precision). NaN
    centres for an outline that encloses no area (below 1e-12 of its extent squared)."""
    for k in range(starts.shape[0]):
        s = starts[k]
        c = counts[k]
        ox = 0.0
        oy = 0.0
        for i in range(s, s + c):
            ox += points[i, 0]
            oy += points[i, 1]
        ox /= c
        oy /= c
        f = 0.0
        fx = 0.0
        fy = 0.0
        extent = 1.0
        for i in range(c):
            x0 = points[s + i, 0] - ox
            y0 = points[s + i, 1] - oy
            j = s + i + 1 if i + 1 < c else s
            x1 = points[j, 0] - ox
            y1 = points[j, 1] - oy
            dx = x1 - x0
            f += dx * (y0 + y1) / 2.0
            fx += dx * (x0 * (2.0 * y0 + y1) + x1 * (y0 + 2.0 * y1)) / 6.0
            fy += dx * (y0 * y0 + y0 * y1 + y1 * y1) / 3.0
            extent = max(extent, abs(x0), abs(y0))
        areas[k] = abs(f)
        if abs(f) > 1e-12 * extent * extent:
            centres[k, 0] = fx / f + ox
            centres[k, 1] = fy / (2.0 * f) + oy
        else:
            centres[k, 0] = np.nan
            centres[k, 1] = np.nan


@njit(cache=True, nogil=True)
def resample_closed(points, starts, counts, fractions, out):  # pragma: no cover - compiled
    """Each closed outline sampled at the arc lengths ``fractions`` (n,) of its perimeter (increasing,
    in [0, 1)), linearly between its vertices, written to ``out`` (m, n, 2) ``(x, y)``. Returns the
    index of the first outline of zero perimeter, or -1."""
    n = fractions.shape[0]
    for k in range(starts.shape[0]):
        s = starts[k]
        c = counts[k]
        # (sqrt, not math.hypot: hypot guards against overflow at several times the cost, and pixel
        # coordinates do not overflow)
        length = 0.0
        for i in range(c):
            j = s + i + 1 if i + 1 < c else s
            dx = points[j, 0] - points[s + i, 0]
            dy = points[j, 1] - points[s + i, 1]
            length += math.sqrt(dx * dx + dy * dy)
        if not length > 0:
            return k
        # walk the edges once: the targets increase with j
        edge = 0
        at = 0.0  # arc length at the start of `edge`
        dx = points[s + 1, 0] - points[s, 0]
        dy = points[s + 1, 1] - points[s, 1]
        step = math.sqrt(dx * dx + dy * dy)
        for q in range(n):
            t = length * fractions[q]
            while edge < c - 1 and at + step <= t:
                edge += 1
                at += step
                a = s + edge
                b = a + 1 if edge + 1 < c else s
                dx = points[b, 0] - points[a, 0]
                dy = points[b, 1] - points[a, 1]
                step = math.sqrt(dx * dx + dy * dy)
            a = s + edge
            b = a + 1 if edge + 1 < c else s
            if step > 0:
                u = (t - at) / step
                out[k, q, 0] = points[a, 0] + (points[b, 0] - points[a, 0]) * u
                out[k, q, 1] = points[a, 1] + (points[b, 1] - points[a, 1]) * u
            else:
                out[k, q, 0] = points[a, 0]
                out[k, q, 1] = points[a, 1]
    return -1


@njit(cache=True, nogil=True)
def bounding_boxes(points, starts, counts, picked, out):  # pragma: no cover - compiled
    """The bounding box ``(x0, y0, x1, y1)`` of each outline of ``picked`` (k,), into ``out`` (k, 4)."""
    for q in range(picked.shape[0]):
        k = picked[q]
        s = starts[k]
        x0 = x1 = points[s, 0]
        y0 = y1 = points[s, 1]
        for i in range(s + 1, s + counts[k]):
            x0 = min(x0, points[i, 0])
            x1 = max(x1, points[i, 0])
            y0 = min(y0, points[i, 1])
            y1 = max(y1, points[i, 1])
        out[q, 0] = x0
        out[q, 1] = y0
        out[q, 2] = x1
        out[q, 3] = y1


@njit(cache=True, nogil=True)
def halve_u8(image, out):  # pragma: no cover - compiled
    """``out`` (H / 2, W / 2) uint8: the rounded means of ``image``'s (H, W) 2 x 2 blocks,
    ``(a + b + c + d + 2) >> 2`` as OpenCV's area resize computes them. Row pairs are read in order,
    each once: on a frame that is not in the cache yet (a camera's), the read is most of the cost."""
    h, w = out.shape
    for r in range(h):
        a = image[2 * r]
        b = image[2 * r + 1]
        o = out[r]
        for c in range(w):
            o[c] = (np.uint16(a[2 * c]) + np.uint16(a[2 * c + 1]) + np.uint16(b[2 * c]) + np.uint16(b[2 * c + 1])
                    + np.uint16(2)) >> np.uint16(2)
    return out
