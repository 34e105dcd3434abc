"""Plane geometry of closed outlines: areas, centres of area, perimeters, arc-length resampling and
the paper's contour length filter.

Every function takes points ``(x, y)`` in image pixels (origin top-left, y down) as an array of
shape ``(N, 2)``; the outline closes from the last point back to the first, which is not repeated.
Functions whose name is a plural (:func:`centroids`, :func:`signed_areas`, :func:`perimeters`,
:func:`resample_many`) take a sequence of such arrays and work on all of them at once, without a
Python loop over the outlines, because the detection hot path calls them for every contour of an
image.

Orientation convention: a signed area is *positive* when the outline runs counter-clockwise as
displayed (y down), matching ``sbplan.contours.Contour.orientation == +1`` for outer boundaries.
That is the opposite sign of the textbook shoelace formula applied to raw ``(x, y)`` pixel
coordinates, and of ``cv2.contourArea(..., oriented=True)``.
"""

from __future__ import annotations

import collections.abc
import functools
from typing import Sequence

import cv2
import numpy as np

from .contours import Contour, as_points
from .errors import ContourError, InputError

__all__ = [
    "PolygonBatch",
    "signed_area", "signed_areas", "perimeter", "perimeters", "centroid", "centroids",
    "resample_closed", "resample_many", "resample_xy", "resample_complex", "chain_length", "contour_length",
    "length_filter",
    "pack", "apply_homography",
]

_SQRT2 = float(np.sqrt(2.0))


# -- packing many outlines into one array ------------------------------------------------------

class PolygonBatch(collections.abc.Sequence[np.ndarray]):
    """Many closed outlines stored back to back, which :func:`pack` takes without copying.

    Stages that make many polygons at once (an approximator's ``approximate_many``) return one, so
    that every later vectorized step (descriptors, areas, centres, resampling) skips the
    concatenation and validation of the outlines. It is a read-only sequence of ``(N_i, 2)``
    float64 views, so code that iterates over polygons takes it unchanged.

    Parameters
    ----------
    points : ndarray of shape (sum N_i, 2), float64
        Finite vertices ``(x, y)``, outline ``k`` at ``points[starts[k]:starts[k] + counts[k]]``.
    counts : ndarray of shape (m,), int64
        N_i, each >= 3.
    """

    __slots__ = ("points", "starts", "counts", "_resampled")

    def __init__(self, points: np.ndarray, counts: np.ndarray):
        counts = np.asarray(counts, dtype=np.int64)
        points = np.asarray(points, dtype=np.float64)
        if points.ndim != 2 or points.shape[1] != 2 or int(counts.sum()) != len(points):
            raise ContourError(f"PolygonBatch: {len(points)} points do not split into outlines of {counts.tolist()}")
        if len(counts) and (counts.min() < 3 or not np.isfinite(points).all()):
            raise ContourError("PolygonBatch: every outline needs at least 3 finite points")
        self._set(points, counts)

    def _set(self, points: np.ndarray, counts: np.ndarray) -> None:
        self.points = points
        self.counts = counts
        self.starts = np.zeros(len(counts), np.int64)
        np.cumsum(counts[:-1], out=self.starts[1:])
        # n -> resample_complex(self, n): the descriptors and the outline check of one frame
        # resample the same outlines, the check at half the descriptors' rate
        self._resampled: dict[int, np.ndarray] = {}

    @classmethod
    def unchecked(cls, points: np.ndarray, counts: np.ndarray) -> "PolygonBatch":
        """A batch made without validation, for producers whose output is valid by construction
        (an approximator's vertices picked from pixel contours, a ``take`` of a batch): the checks
        cost about as much as the rest of a small batch's construction, once per frame.

        ``points`` must be a float64 (sum N_i, 2) array of finite values, ``counts`` int64 with
        every N_i >= 3 and summing to ``len(points)``; nothing checks that.
        """
        obj = cls.__new__(cls)
        obj._set(points, counts)
        return obj

    @classmethod
    def from_list(cls, polygons: Sequence[np.ndarray]) -> "PolygonBatch":
        """Pack a list of ``(N_i, 2)`` outlines (validated as :func:`pack` does)."""
        points, _, counts = pack(polygons)
        return cls(points, counts)

    def __len__(self) -> int:
        return len(self.counts)

    def __getitem__(self, i):
        if isinstance(i, slice):
            return self.take(np.arange(len(self))[i])
        s = int(self.starts[i])
        return self.points[s:s + int(self.counts[i])]

    def take(self, indices) -> "PolygonBatch":
        """The outlines at ``indices`` (int array or bool mask), in that order, as a new batch."""
        idx = np.arange(len(self))[np.asarray(indices)] if np.asarray(indices).dtype == bool \
            else np.asarray(indices, dtype=np.int64)
        counts = self.counts[idx]
        if not len(counts):
            return PolygonBatch(np.zeros((0, 2)), counts)
        # index of every kept point: each outline's start, then 0, 1, 2, ... within it
        offsets = np.arange(int(counts.sum())) - np.repeat(np.cumsum(counts) - counts, counts)
        return PolygonBatch.unchecked(self.points[np.repeat(self.starts[idx], counts) + offsets], counts)

    def boxes(self, indices: np.ndarray | None = None) -> np.ndarray:
        """Bounding boxes ``(x0, y0, x1, y1)`` of the outlines at ``indices`` (int array; default
        all): shape (k, 4), float64."""
        picked = np.arange(len(self)) if indices is None else np.ascontiguousarray(indices, np.int64)
        out = np.empty((len(picked), 4))
        if len(picked):
            _compiled().bounding_boxes(self.points, self.starts, self.counts, picked, out)
        return out

    def _cached_resample(self, n: int) -> np.ndarray | None:
        for have, w in self._resampled.items():
            if have % n == 0:
                # sample j of n lies at arc length j/n, which is sample j * have/n of have
                k = have // n
                return w if k == 1 else w[:, ::k]
        return None


def _read_only(a: np.ndarray) -> np.ndarray:
    a.flags.writeable = False
    return a


def pack(polygons: Sequence[np.ndarray], *, name: str = "polygons", min_points: int = 3):
    """Concatenate many outlines into one array for vectorized work.

    Parameters
    ----------
    polygons : sequence of array_like, each of shape (N_i, 2)
        Closed outlines ``(x, y)``, N_i >= ``min_points``.

    Returns
    -------
    points : ndarray of shape (sum N_i, 2), float64
    starts : ndarray of shape (m,), int64
        Index of each outline's first point in ``points``.
    counts : ndarray of shape (m,), int64
        N_i.

    Raises
    ------
    ContourError
        Naming the first bad outline (wrong shape, too few points, NaN or infinite values).
    """
    if isinstance(polygons, PolygonBatch) and min_points <= 3:
        return polygons.points, polygons.starts, polygons.counts
    m = len(polygons)
    if m == 0:
        return np.zeros((0, 2)), np.zeros(0, np.int64), np.zeros(0, np.int64)
    try:
        # The fast path: one concatenation, one finiteness check. Per-outline validation only runs
        # to name the culprit when this fails.
        arrays = [p if isinstance(p, np.ndarray) else np.asarray(p, dtype=np.float64) for p in polygons]
        arrays = [a[:, 0, :] if a.ndim == 3 and a.shape[1] == 1 else a for a in arrays]
        counts = np.fromiter((len(a) for a in arrays), np.int64, m)
        if any(a.ndim != 2 or a.shape[1] != 2 for a in arrays):
            raise ValueError("shape")
        points = np.concatenate(arrays, axis=0, dtype=np.float64)
        ok = bool((counts >= min_points).all()) and bool(np.isfinite(points).all())
    except (TypeError, ValueError):
        ok = False
    if not ok:
        for i, p in enumerate(polygons):
            as_points(p, name=f"{name}[{i}]", min_points=min_points)
        raise ContourError(f"{name}: not a sequence of (N, 2) point arrays")  # pragma: no cover
    starts = np.zeros(m, np.int64)
    np.cumsum(counts[:-1], out=starts[1:])
    return points, starts, counts


def _next_index(starts: np.ndarray, counts: np.ndarray, total: int) -> np.ndarray:
    """For each packed point, the index of the following point of the same closed outline."""
    nxt = np.arange(1, total + 1, dtype=np.int64)
    nxt[starts + counts - 1] = starts
    return nxt


# -- areas ---------------------------------------------------------------------------------------

def signed_area(points) -> float:
    """Signed area enclosed by a closed polygon.

    Parameters
    ----------
    points : array_like of shape (N, 2)
        Vertices ``(x, y)``, N >= 3.

    Returns
    -------
    float
        Positive when the polygon runs counter-clockwise as displayed (y down), negative when
        clockwise; the absolute value is the area in square pixels for a simple polygon.
    """
    p = as_points(points)
    p = p - p.mean(axis=0)  # local origin: the cross products stay small, so no cancellation
    x, y = p[:, 0], p[:, 1]
    return -0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))


def signed_areas(polygons: Sequence[np.ndarray]) -> np.ndarray:
    """:func:`signed_area` of many polygons, shape (m,)."""
    pts, starts, counts = pack(polygons)
    if len(starts) == 0:
        return np.zeros(0)
    nxt = _next_index(starts, counts, len(pts))
    origin = np.repeat(pts[starts], counts, axis=0)
    p = pts - origin
    q = p[nxt]
    cross = p[:, 0] * q[:, 1] - q[:, 0] * p[:, 1]
    return -0.5 * np.add.reduceat(cross, starts)


# -- perimeters and lengths ----------------------------------------------------------------------

def perimeter(points) -> float:
    """Length of the closed polygon through ``points`` (N, 2), closing edge included."""
    p = as_points(points)
    d = np.roll(p, -1, axis=0) - p
    return float(np.hypot(d[:, 0], d[:, 1]).sum())


def perimeters(polygons: Sequence[np.ndarray]) -> np.ndarray:
    """:func:`perimeter` of many polygons, shape (m,)."""
    pts, starts, counts = pack(polygons)
    if len(starts) == 0:
        return np.zeros(0)
    d = pts[_next_index(starts, counts, len(pts))] - pts
    return np.add.reduceat(np.hypot(d[:, 0], d[:, 1]), starts)


def chain_length(chain) -> float:
    """Length of a Freeman chain: 1 per even (axis) step, sqrt(2) per odd (diagonal) step."""
    c = np.asarray(chain)
    if c.ndim != 1:
        raise ContourError(f"chain: expected a 1-D array of Freeman codes, got shape {c.shape}")
    odd = int(np.count_nonzero(c & 1)) if c.size else 0
    return (c.size - odd) + _SQRT2 * odd


def contour_length(contour) -> float:
    """Length of a pixel contour: the sum of its chain's step lengths.

    A :class:`~sbplan.contours.Contour` with a chain is measured on the chain; anything else is
    measured as the closed polygon through its points (identical for an 8-connected pixel chain).
    A one- or two-pixel contour has the length of its closed point path (0 for one pixel).
    """
    if isinstance(contour, Contour):
        if len(contour.chain):
            return chain_length(contour.chain)
        pts = contour.points
    else:
        pts = contour
    p = as_points(pts, name="contour", min_points=1)
    if len(p) == 1:
        return 0.0
    d = np.roll(p, -1, axis=0) - p
    return float(np.hypot(d[:, 0], d[:, 1]).sum())


def length_filter(items, *, min_length: float = 0.0, max_length: float = np.inf) -> np.ndarray:
    """The paper's length filter: keep contours whose length lies within the bounds.

    Parameters
    ----------
    items : sequence of Contour or of (N, 2) point arrays, or array_like of shape (n,) of lengths
        What to filter. Contour lengths follow :func:`contour_length`.
    min_length, max_length : float
        Inclusive bounds in pixels; ``0 <= min_length <= max_length``.

    Returns
    -------
    ndarray of shape (n,), bool
        True for the items to keep.
    """
    lo, hi = float(min_length), float(max_length)
    if not np.isfinite(lo) or lo < 0:
        raise InputError(f"min_length must be a finite number >= 0, got {min_length!r}")
    if np.isnan(hi) or hi < lo:
        raise InputError(f"max_length must be >= min_length ({lo:g}), got {max_length!r}")
    if isinstance(items, np.ndarray) and items.ndim == 1:
        lengths = items.astype(np.float64)
    else:
        items = list(items)
        if items and all(isinstance(v, (int, float, np.number)) for v in items):
            lengths = np.asarray(items, dtype=np.float64)
        else:
            lengths = np.fromiter((contour_length(c) for c in items), np.float64, len(items))
    if np.isnan(lengths).any():
        raise InputError("length_filter: lengths contain NaN")
    return (lengths >= lo) & (lengths <= hi)


# -- centre of area, equation (1) ----------------------------------------------------------------

def _edge_integrals(p: np.ndarray, q: np.ndarray):
    """Closed forms of the three edge integrals of equation (1) along the edges p -> q (y linear in x).

    Returns (int y dx, int x*y dx, int y^2 dx), each of shape (E,).
    """
    x0, y0, x1, y1 = p[:, 0], p[:, 1], q[:, 0], q[:, 1]
    dx = x1 - x0
    f = dx * (y0 + y1) / 2.0
    fx = dx * (x0 * (2.0 * y0 + y1) + x1 * (y0 + 2.0 * y1)) / 6.0
    fy = dx * (y0 * y0 + y0 * y1 + y1 * y1) / 3.0
    return f, fx, fy


def centroid(points) -> tuple[float, float]:
    """Centre of area of a polygon by the paper's equation (1).

    ``X_c = (1/F) sum_i int_{x_i}^{x_i+1} x y dx`` and ``Y_c = (1/(2F)) sum_i int y^2 dx``, each
    integral taken in closed form along edge i (on which y is linear in x), and
    ``F = sum_i int y dx``, the enclosed area carrying the same orientation sign as the integrals,
    so the result does not depend on the traversal direction. Equal to the shoelace centroid.

    Parameters
    ----------
    points : array_like of shape (N, 2)
        Vertices ``(x, y)``, N >= 3.

    Returns
    -------
    (x, y) : tuple of float

    Raises
    ------
    ContourError
        For fewer than 3 points, NaN or infinite values, or a zero enclosed area.
    """
    p = as_points(points)
    origin = p.mean(axis=0)  # integrate about a nearby origin to avoid cancellation far from (0, 0)
    p = p - origin
    f, fx, fy = _edge_integrals(p, np.roll(p, -1, axis=0))
    area = f.sum()
    if not abs(area) > 1e-12 * max(1.0, float(np.abs(p).max()) ** 2):
        raise ContourError("points: the polygon encloses no area, so it has no centre of area")
    return float(fx.sum() / area + origin[0]), float(fy.sum() / (2.0 * area) + origin[1])


def centroids(polygons: Sequence[np.ndarray], *, on_zero_area: str = "raise", return_areas: bool = False):
    """:func:`centroid` of many polygons at once.

    Parameters
    ----------
    polygons : sequence of array_like of shape (N_i, 2)
    on_zero_area : {"raise", "nan"}
        What to do for a polygon that encloses no area: raise ContourError naming it, or give NaN.
    return_areas : bool
        Also return the enclosed areas, which equation (1) computes on the way.

    Returns
    -------
    centres : ndarray of shape (m, 2), float64, columns ``(x, y)``.
    areas : ndarray of shape (m,), float64
        Only with ``return_areas``: the unsigned areas (``abs(signed_areas(polygons))``).
    """
    if on_zero_area not in ("raise", "nan"):
        raise InputError(f"on_zero_area must be 'raise' or 'nan', got {on_zero_area!r}")
    pts, starts, counts = pack(polygons)
    if len(starts) == 0:
        return (np.zeros((0, 2)), np.zeros(0)) if return_areas else np.zeros((0, 2))
    out = np.empty((len(starts), 2))
    size = np.empty(len(starts))
    # (one compiled loop over the points: the numpy expressions cost a dozen calls per batch)
    _compiled().centres_of_area(np.ascontiguousarray(pts), starts, counts, out, size)
    if on_zero_area == "raise":
        bad = np.isnan(out[:, 0])
        if bad.any():
            raise ContourError(f"polygons[{int(np.flatnonzero(bad)[0])}]: the polygon encloses no area, "
                               "so it has no centre of area")
    return (out, size) if return_areas else out


# -- arc-length resampling -----------------------------------------------------------------------

def resample_many(polygons: Sequence[np.ndarray], n: int) -> np.ndarray:
    """Resample many closed outlines at ``n`` points each, equally spaced by arc length.

    Sample ``j`` of an outline lies at arc length ``j * L / n`` from its first point along the
    closed polygon (L its perimeter), so sample 0 is the first point.

    Parameters
    ----------
    polygons : sequence of array_like of shape (N_i, 2)
        Closed outlines ``(x, y)``, N_i >= 3.
    n : int
        Samples per outline, >= 3.

    Returns
    -------
    ndarray of shape (m, n, 2), float64, ``(x, y)``.

    Raises
    ------
    ContourError
        An outline with a zero perimeter (all points equal), fewer than 3 points or bad values.
    """
    x, y = resample_xy(polygons, n)
    return np.stack([x, y], axis=-1)


def resample_xy(polygons: Sequence[np.ndarray], n: int) -> tuple[np.ndarray, np.ndarray]:
    """:func:`resample_many` returning the x and y coordinates as two arrays of shape (m, n).

    They are the real and imaginary parts of :func:`resample_complex` (views, not copies). For a
    :class:`PolygonBatch` the result is remembered with the batch and read-only: a later call for
    ``n`` or a divisor of it costs nothing.
    """
    w = resample_complex(polygons, n)
    return w.real, w.imag


def resample_complex(polygons: Sequence[np.ndarray], n: int) -> np.ndarray:
    """:func:`resample_many` as complex numbers ``x + i y``, shape (m, n), complex128.

    The descriptors' FFT takes this form directly, and one interpolation of complex values costs
    little more than one of real values. Remembered with a :class:`PolygonBatch` like
    :func:`resample_xy`.
    """
    n = _check_samples(n)
    if isinstance(polygons, PolygonBatch):
        cached = polygons._cached_resample(n)
        if cached is None:
            cached = polygons._resampled[n] = _read_only(_resample_complex(polygons, n))
        return cached
    return _resample_complex(polygons, n)


def _resample_complex(polygons: Sequence[np.ndarray], n: int) -> np.ndarray:
    pts, starts, counts = pack(polygons)
    m = len(starts)
    if m == 0:
        return np.zeros((0, n), np.complex128)
    out = np.empty((m, n, 2))
    zero = _compiled().resample_closed(np.ascontiguousarray(pts), starts, counts, _fractions(n), out)
    if zero >= 0:
        raise ContourError(f"polygons[{zero}]: all points coincide (zero perimeter)")
    # (x, y) rows of a C-contiguous float64 array are complex128 numbers x + iy in memory
    return out.view(np.complex128).reshape(m, n)


@functools.cache
def _compiled():
    """The compiled loops (:mod:`sbplan._kernels`), imported on first use: numba takes a moment."""
    from . import _kernels
    return _kernels


@functools.lru_cache(maxsize=16)
def _fractions(n: int) -> np.ndarray:
    """``j / n`` for j = 0..n-1, read-only (the arc-length positions of the samples)."""
    return _read_only(np.arange(n) / n)


def resample_closed(points, n: int) -> np.ndarray:
    """Resample one closed outline (N, 2) at ``n`` points equally spaced by arc length: (n, 2).

    See :func:`resample_many`.
    """
    return resample_many([as_points(points)], n)[0]


def _check_samples(n) -> int:
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 3:
        raise InputError(f"n (number of samples) must be an integer >= 3, got {n!r}")
    return int(n)


def apply_homography(matrix: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """``xy`` (..., 2) mapped by the 3x3 ``matrix`` (projective division when its last row is not
    ``(0, 0, 1)``): camera movements, the renderer's views, the grid's homography."""
    xy = np.asarray(xy, dtype=np.float64)
    matrix = np.asarray(matrix, dtype=np.float64)
    # (plain floats: a numpy scalar's truth value costs more than this whole function's arithmetic)
    projective = bool(float(matrix[2, 0]) or float(matrix[2, 1]))
    if xy.size and xy.shape[-1] == 2:
        # OpenCV's point transforms: 3 us for a frame's few thousand outline points, where numpy's
        # (N, 2) @ (2, 2) product takes 35 (the same values to 1e-13 px)
        pts = xy.reshape(-1, 1, 2)
        if not projective:
            return cv2.transform(pts, matrix[:2]).reshape(xy.shape)
        # (x w, y w, w), divided here: cv2.perspectiveTransform gives (0, 0) where w is near zero
        # or the point is NaN, where the division gives inf or NaN as the plain arithmetic does
        t = cv2.transform(pts, matrix).reshape(-1, 3)
        return (t[:, :2] / t[:, 2:]).reshape(xy.shape)
    out = xy @ matrix[:2, :2].T + matrix[:2, 2]
    if projective:
        w = xy @ matrix[2, :2] + matrix[2, 2]
        out /= w[..., None]
    return out
