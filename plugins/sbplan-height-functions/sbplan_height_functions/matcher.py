"""Height functions (Wang, Bai, You, Liu and Latecki 2012) with an optimal circular alignment.

Wang, J., Bai, X., You, X., Liu, W. and Latecki, L. J. (2012), "Shape matching and classification
using height functions", Pattern Recognition Letters 33(2), 134-143.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar, Sequence

import numpy as np

from sbplan.errors import ContourError, InputError, PluginError
from sbplan.polygons import resample_complex, signed_areas
from sbplan.contours import as_points
from sbplan.contracts import DescriptorMatcher, as_descriptors, option

__all__ = ["HeightFunctionsMatcher", "height_descriptors", "mirror_descriptors", "segment_weights", "shape_complexity"]

#: Each outline is first resampled this many times more finely than ``points``; the samples then
#: start at the dense sample farthest from the centroid.
_DENSE = 4


def height_descriptors(outlines: Sequence[np.ndarray], *, points: int = 50, segment: int = 5) -> np.ndarray:
    """Smoothed, locally normalized height functions of many closed outlines.

    Each outline is oriented counter-clockwise as displayed (y down) and resampled at ``points``
    points equally spaced by arc length, starting at the point farthest from the samples' centroid
    (so that copies of one shape in one orientation start alike; matching does not rely on it).
    For sample point ``i`` the tangent ``L_i`` runs from point ``i - 1`` to point ``i + 1``, and
    the height of point ``i + j`` is its signed distance to ``L_i`` (left of the tangent positive).
    The heights of point ``i`` for ``j = 0 .. points-1`` are averaged over ``segment`` consecutive
    offsets centred on ``j = 0, segment, 2 segment, ...`` (segment 0 holds the point and its
    nearest neighbours) and divided by the largest absolute height of point ``i``, so every entry
    lies in [-1, 1] and the descriptor does not depend on translation, rotation or scale.

    Parameters
    ----------
    outlines : sequence of array_like of shape (N_i, 2)
        Closed outlines ``(x, y)`` in pixels, N_i >= 3, not closed (first point not repeated).
    points : int
        Sample points per outline; a multiple of ``segment``.
    segment : int
        Heights averaged into one entry; odd, so that the segments are symmetric about the point.

    Returns
    -------
    ndarray of shape (m, points, points // segment), float64
        ``[s, i, q]``: outline ``s``, sample point ``i``, segment ``q`` (offsets around ``q * segment``).

    Raises
    ------
    ContourError
        An outline with fewer than 3 points, non-finite values or zero length.
    """
    m = len(outlines)
    n_seg = points // segment
    if m == 0:
        return np.zeros((0, points, n_seg))
    arrays = [as_points(p, name=f"outlines[{k}]") for k, p in enumerate(outlines)]
    # One traversal sense for all: a reversed vertex list, or a hole, reads like the outer boundary.
    clockwise = signed_areas(arrays) < 0
    arrays = [a[::-1] if cw else a for a, cw in zip(arrays, clockwise)]
    try:
        dense = resample_complex(arrays, _DENSE * points)  # (m, dense)
    except ContourError as exc:
        raise ContourError(f"{exc}: a zero-length outline has no height function") from None
    far = np.argmax(np.abs(dense - dense.mean(axis=1, keepdims=True)), axis=1)
    take = (far[:, None] + _DENSE * np.arange(points)[None, :]) % (_DENSE * points)
    z = np.take_along_axis(dense, take, axis=1)  # (m, points), starting at the far point
    tangent = np.roll(z, -1, axis=1) - np.roll(z, 1, axis=1)
    size = np.abs(tangent)
    # A spike whose two neighbours coincide has no tangent: any direction will do, its heights
    # are then those of a point on a straight line through it.
    tangent = np.where(size > 0, tangent / np.where(size > 0, size, 1.0), 1.0)
    idx = (np.arange(points)[:, None] + np.arange(points)[None, :]) % points
    rel = z[:, idx] - z[:, :, None]  # (m, i, j): point i + j seen from point i
    # Signed distance to the tangent: Im(conj(t) * d) is the cross product t x d. With y down a
    # counter-clockwise outline has its inside on the tangent's left (negative cross).
    heights = -(tangent.real[:, :, None] * rel.imag - tangent.imag[:, :, None] * rel.real)
    half = segment // 2
    order = (np.arange(points) - half) % points  # offsets -half .. points-1-half
    smooth = heights[:, :, order].reshape(m, points, n_seg, segment).mean(axis=3)
    scale = np.abs(heights).max(axis=2, keepdims=True)
    return smooth / np.where(scale > 0, scale, 1.0)


def shape_complexity(desc: np.ndarray) -> np.ndarray:
    """How much the height functions change along each outline, shape (m,), from (m, N, M).

    The mean absolute deviation of every descriptor entry from its mean over the N points: 0 for
    a circle (every point sees the same heights), 0.05 for a 2:1 ellipse, 0.12 for a square, 0.25
    to 0.3 for the flag and the L of ``sbplan.testing.sample_outlines``, 0.1 to 0.35 on MPEG-7.
    Wang et al. normalize the dissimilarity by a shape complexity (theirs is built from standard
    deviations of the heights): people, and matchers, tolerate more change in a complex shape
    than in a simple one. :class:`HeightFunctionsMatcher` divides by ``offset`` plus the larger
    complexity of the two shapes, which did best on the classes it was tuned on.
    """
    return np.abs(desc - desc.mean(axis=1, keepdims=True)).mean(axis=(1, 2))


def mirror_descriptors(desc: np.ndarray) -> np.ndarray:
    """The descriptors (m, N, M) of the outlines' mirror images: ``F'[i, q] = F[-i, -q]``.

    Mirroring reverses the traversal, which turns the offsets round and, with the reflection,
    leaves the heights' signs as they were.
    """
    n, k = desc.shape[1], desc.shape[2]
    return desc[:, (-np.arange(n)) % n][:, :, (-np.arange(k)) % k]


def segment_weights(points: int, segment: int, sigma: float) -> np.ndarray:
    """Weights of the segments, shape (points // segment,), summing to 1.

    A Gaussian of each segment's distance along the outline from the point it describes, as a
    fraction of the perimeter, with standard deviation ``sigma``: the parts of a shape near a
    point say more about that point than the far side does, and articulated parts far away
    change it most. ``sigma = inf`` weighs all segments alike.
    """
    n_seg = points // segment
    q = np.arange(n_seg)
    along = np.minimum(q, n_seg - q) * segment / points
    w = np.exp(-0.5 * (along / sigma) ** 2) if np.isfinite(sigma) else np.ones(n_seg)
    return w / w.sum()


@dataclass(kw_only=True, frozen=True)
class HeightFunctionsMatcher(DescriptorMatcher):
    """Height functions (Wang et al. 2012) compared under the best circular alignment, mirror included.

    Descriptor: ``points`` sample points, each with its smoothed, normalized height function (see
    :func:`height_descriptors`); the (points, points // segment) matrix flattened row by row,
    followed by the outline's :func:`shape_complexity`.

    Distance: the points of one shape are matched to those of the other in the same cyclic order,
    one to one, under the best of all start points of the other shape (and of its mirror image,
    with ``mirror``), found exactly by dynamic programming; a point may stay unmatched at
    ``skip_cost``. Matching point ``i`` with point ``j`` costs the weighted mean absolute
    difference of their height functions (weights :func:`segment_weights`). The least total is
    divided by ``points`` (so it lies between 0 for identical descriptors and ``2 * skip_cost``
    when nothing matches) and, with ``normalize``, by ``offset`` plus the larger of the two
    shapes' complexities.
    """

    name: ClassVar[str] = "height-functions"
    description: ClassVar[str] = ("height functions (Wang et al. 2012), exact circular dynamic-programming "
                                  "alignment with mirror images")
    default_threshold: ClassVar[float] = 0.35

    points: int = option(50, "sample points per outline (a multiple of segment)")
    segment: int = option(5, "heights averaged into one descriptor entry (odd)")
    sigma: float = option(0.2, "width of the segment weights, as a fraction of the perimeter (inf: equal weights)")
    skip_cost: float = option(0.2, "cost of leaving a point unmatched, in mean absolute height differences")
    mirror: bool = option(True, "also match each outline's mirror image and keep the better match")
    normalize: bool = option(True, "divide distances by offset + the larger shape complexity of the two")
    offset: float = option(0.15, "added to the shape complexity before dividing (with normalize)")

    def __post_init__(self) -> None:
        for key in ("points", "segment"):
            v = getattr(self, key)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)):
                raise InputError(f"option {key}: expected an integer, got {v!r}")
        if not 3 <= self.segment <= 99 or self.segment % 2 == 0:
            raise InputError(f"option segment: must be odd, between 3 and 99, got {self.segment}")
        if not 4 * self.segment <= self.points <= 1000 or self.points % self.segment:
            raise InputError(f"option points: must be a multiple of segment={self.segment} between "
                             f"{4 * self.segment} and 1000, got {self.points}")
        for key in ("sigma", "skip_cost", "offset"):
            v = getattr(self, key)
            if isinstance(v, bool) or not isinstance(v, (int, float, np.floating, np.integer)) or not v > 0 \
                    or (key != "sigma" and not np.isfinite(v)):
                raise InputError(f"option {key}: must be a positive number, got {v!r}")
        for key in ("mirror", "normalize"):
            if not isinstance(getattr(self, key), (bool, np.bool_)):
                raise InputError(f"option {key}: expected true or false, got {getattr(self, key)!r}")

    @property
    def size(self) -> int:
        """Descriptor length K = points * (points // segment) + 1."""
        return self.points * (self.points // self.segment) + 1

    def describe(self, points: np.ndarray) -> np.ndarray:
        return self.describe_many([as_points(points)])[0]

    def describe_many(self, outlines: Sequence[np.ndarray]) -> np.ndarray:
        desc = height_descriptors(outlines, points=self.points, segment=self.segment)
        return np.concatenate([desc.reshape(len(desc), self.size - 1), shape_complexity(desc)[:, None]], axis=1)

    def distance_matrix(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        a, b = as_descriptors(a, name="a"), as_descriptors(b, name="b")
        k = self.size
        if a.shape[1] != k or b.shape[1] != k:
            raise InputError(f"descriptor lengths: expected {k} for points={self.points}, segment={self.segment}, "
                             f"got {a.shape[1]} and {b.shape[1]}")
        n, m = len(a), len(b)
        out = np.zeros((n, m))
        if n == 0 or m == 0:
            return out
        same = a.shape == b.shape and (a is b or np.array_equal(a, b))
        stack = a if same else np.concatenate([a, b])
        if same:
            i, j = np.triu_indices(n, 1)
        else:
            i, j = (x.ravel() for x in np.meshgrid(np.arange(n), np.arange(n, n + m), indexing="ij"))
        first, second = _pair_order(stack, i, j)
        values = np.zeros(len(first))
        todo = np.flatnonzero(first != second)
        values[todo] = self._aligned(stack, first[todo], second[todo])
        if same:
            out[i, j] = values
            out[j, i] = values
        else:
            out[:] = values.reshape(n, m)
        return out

    def _aligned(self, stack: np.ndarray, first: np.ndarray, second: np.ndarray) -> np.ndarray:
        try:
            from . import _kernels
        except ImportError as exc:  # installed without its dependencies
            raise PluginError(f"matcher {self.name!r} needs numba to compare outlines ({exc}); "
                              "pip install numba") from None

        n_seg = self.points // self.segment
        desc = stack[:, :-1].reshape(len(stack), self.points, n_seg)
        desc = np.ascontiguousarray(desc * segment_weights(self.points, self.segment, self.sigma))
        desc_t = np.ascontiguousarray(desc.transpose(0, 2, 1))
        mirror_t = np.ascontiguousarray(mirror_descriptors(desc).transpose(0, 2, 1))
        out = np.empty(len(first))
        _kernels.pair_distances(desc, desc_t, mirror_t, first.astype(np.int64), second.astype(np.int64),
                                float(self.skip_cost), bool(self.mirror), _COARSE_STEP, out)
        if self.normalize:
            complexity = stack[:, -1]
            out /= self.offset + np.maximum(complexity[first], complexity[second])
        return out


#: Starts aligned first, every this many points, before the ranges between them are bounded
#: (see ``_kernels.circular_alignment``); 8 was the fastest of 3..50 on MPEG-7 silhouettes.
_COARSE_STEP = 8


def _pair_order(stack: np.ndarray, i: np.ndarray, j: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The pairs ``(i, j)`` of rows of ``stack`` as ``(first, second)``, the same way round in
    every call: the alignment reads the first shape from its point 0 and tries every start of the
    second, so d(x, y) is computed exactly as d(y, x) is. Equal rows come out as ``first ==
    second`` (their distance is 0)."""
    probe = np.random.default_rng(12345).standard_normal(stack.shape[1])
    keys = stack @ probe
    swap = keys[i] > keys[j]
    first, second = np.where(swap, j, i), np.where(swap, i, j)
    for p in np.flatnonzero(keys[first] == keys[second]):  # equal keys: equal rows, or a rare tie
        x, y = stack[first[p]], stack[second[p]]
        diff = np.flatnonzero(x != y)
        if not len(diff):
            second[p] = first[p]
        elif x[diff[0]] > y[diff[0]]:
            first[p], second[p] = second[p], first[p]
    return first, second
