"""Row bands: the image rows where a fixed camera can see symbols, stacked into a smaller image.

The camera does not move between calibration and detection, so every symbol appears in the rows
where the reference showed it, give or take a few pixels of defocus. The rows between two rows of
symbols hold floor, obstacles and shadows, none of which decides a cell: a cell is occupied when
its symbol is not found. Detection therefore thresholds, opens and traces contours only in the
bands around the symbol rows, stacked one under the other with an empty row between consecutive
bands, so that no region of one band touches one of the next. On the 10 x 5 grid of the benchmark
that is about half the frame. The floor level a binarizer compares against is still estimated on
the whole frame (:meth:`sbplan.contracts.Binarizer.binarize_bands`), so a shadow edge between two
symbol rows is seen where it is.

Coordinates: a stacked image has the full image's columns; row ``r`` of it is row
``r + shift[r]`` of the full image (:meth:`RowBands.to_full`).
"""

from __future__ import annotations

import functools
from typing import Sequence

import numpy as np

from ..errors import InputError

__all__ = ["RowBands"]


class RowBands:
    """Half-open row ranges ``[start, stop)`` of an image of ``shape``, stacked top to bottom.

    Parameters
    ----------
    ranges : sequence of (start, stop)
        Disjoint, increasing, each non-empty, inside ``0..shape[0]``, with at least one row
        between consecutive ranges (touching ranges are merged by :meth:`around`).
    shape : (H, W)
        The full image's shape.

    Attributes
    ----------
    starts, stops : ndarray of shape (k,), int64
        Rows of the full image.
    offsets : ndarray of shape (k,), int64
        First row of each band in the stacked image; band ``i`` is followed by one empty row.
    stacked_shape : (H_s, W)
    """

    __slots__ = ("starts", "stops", "offsets", "shape", "stacked_shape", "_shift")

    def __init__(self, ranges: Sequence[Sequence[int]], shape: tuple[int, int]):
        r = np.asarray(ranges, dtype=np.int64).reshape(-1, 2)
        h, w = int(shape[0]), int(shape[1])
        if not len(r) or (r[:, 0] < 0).any() or (r[:, 1] > h).any() or (r[:, 1] <= r[:, 0]).any() \
                or (r[1:, 0] <= r[:-1, 1]).any():
            raise InputError(f"row bands: expected increasing, disjoint, non-empty ranges inside 0..{h}, "
                             f"got {r.tolist()}")
        self.starts, self.stops = r[:, 0].copy(), r[:, 1].copy()
        self.shape = (h, w)
        heights = self.stops - self.starts
        self.offsets = np.concatenate([[0], np.cumsum(heights + 1)[:-1]])
        self.stacked_shape = (int(heights.sum() + len(heights)), w)
        # shift[r]: full row minus stacked row, for every stacked row (separator rows: the next row)
        self._shift = np.repeat(self.starts - self.offsets, heights + 1).astype(np.float64)

    @classmethod
    def around(cls, polygons: Sequence[np.ndarray] | np.ndarray, shape: tuple[int, int], *, margin: float,
               even: bool = True) -> "RowBands":
        """The bands covering every polygon's rows plus ``margin`` rows above and below (``polygons``
        (N, 2) arrays of ``(x, y)`` points, or one (K, N, 2) array of K polygons).

        Overlapping or touching bands are merged. With ``even`` (the default) every band starts and
        ends on an even row (or the image's last row), so a binarizer working on a half-size image
        can compare each band's two row phases against whole rows of it.
        """
        if not len(polygons):
            raise InputError("row bands: no polygons to put bands around")
        h = int(shape[0])
        if isinstance(polygons, np.ndarray) and polygons.ndim == 3:
            # polygons of one point count (a detector's symbols' boxes, every frame the camera moves)
            lo, hi = polygons[..., 1].min(axis=1) - margin, polygons[..., 1].max(axis=1) + margin
        else:
            lo = np.array([np.min(p[:, 1]) for p in polygons]) - margin
            hi = np.array([np.max(p[:, 1]) for p in polygons]) + margin
        order = np.argsort(lo)
        lo = np.clip(np.floor(lo[order]), 0, h).astype(np.int64)
        hi = np.clip(np.ceil(hi[order]) + 1, 0, h).astype(np.int64)
        if even:
            lo -= lo % 2
            hi = np.minimum(hi + hi % 2, h)
        merged: list[list[int]] = []
        for a, b in zip(lo.tolist(), hi.tolist()):
            if merged and a <= merged[-1][1] + 1:
                merged[-1][1] = max(merged[-1][1], b)
            else:
                merged.append([a, b])
        return cls(merged, shape)

    @property
    def fraction(self) -> float:
        """Rows of the stacked image over rows of the full image."""
        return self.stacked_shape[0] / self.shape[0]

    def stack(self, image: np.ndarray, *, fill=0) -> np.ndarray:
        """The band rows of ``image`` (the full shape, any dtype and channels) stacked, separator
        rows set to ``fill``."""
        image = np.asarray(image)
        if image.shape[:2] != self.shape:
            raise InputError(f"row bands: image is {image.shape[:2]}, the bands are for {self.shape}")
        out = np.full(self.stacked_shape + image.shape[2:], fill, dtype=image.dtype)
        for a, b, o in zip(self.starts.tolist(), self.stops.tolist(), self.offsets.tolist()):
            out[o:o + b - a] = image[a:b]
        return out

    def to_full(self, xy: np.ndarray) -> np.ndarray:
        """Points ``(x, y)`` (N, 2) of the stacked image mapped to the full image."""
        xy = np.array(xy, dtype=np.float64).reshape(-1, 2)
        if len(xy):
            # np.clip's dispatch costs more than the two ufuncs (this runs on every frame)
            rows = np.minimum(np.maximum(np.floor(xy[:, 1] + 0.5).astype(np.int64), 0), len(self._shift) - 1)
            xy[:, 1] += self._shift[rows]
        return xy

    def to_stacked(self, xy: np.ndarray) -> np.ndarray:
        """Points ``(x, y)`` (N, 2) of the full image mapped to the stacked image.

        Points between bands go to the separator row after the band above them (or, above the
        first band, to row 0 minus their distance); a point inside a band maps exactly.
        """
        xy = np.array(xy, dtype=np.float64).reshape(-1, 2)
        if len(xy):
            band = np.clip(np.searchsorted(self.starts, np.floor(xy[:, 1] + 0.5), side="right") - 1, 0, None)
            xy[:, 1] -= (self.starts - self.offsets)[band]
            beyond = xy[:, 1] > (self.offsets + self.stops - self.starts)[band]
            xy[beyond, 1] = (self.offsets + self.stops - self.starts)[band[beyond]]
        return xy

    def to_full_outlines(self, outlines: np.ndarray) -> np.ndarray:
        """:meth:`to_full` of outlines ``(K, N, 2)``, the same values: an outline whose rows all
        lie in one band (every outline traced in the stacked image) moves by that band's shift as
        a whole; any other goes point by point."""
        xy = np.array(outlines, dtype=np.float64)
        if xy.ndim != 3 or not xy.size or xy.shape[-1] != 2:
            return self.to_full(xy.reshape(-1, 2)).reshape(xy.shape)
        # (a point's row is monotonic in y, and the shift is monotonic in the row: an outline
        # whose top and bottom rows move alike moves alike everywhere; one with a point that is
        # not finite goes point by point)
        split = np.zeros(len(xy), bool)
        _compiled().outlines_to_full(xy, self._shift, split)
        if split.any():
            xy[split] = self.to_full(np.asarray(outlines, np.float64)[split].reshape(-1, 2)).reshape(xy[split].shape)
        return xy

    def to_stacked_outlines(self, outlines: np.ndarray) -> np.ndarray:
        """:meth:`to_stacked` of outlines ``(K, N, 2)``, the same values: an outline whose points
        all lie in one band moves by that band's shift as a whole (a few calls on K values where
        :meth:`to_stacked` searches K x N); any other goes point by point."""
        xy = np.array(outlines, dtype=np.float64)
        if xy.ndim != 3 or not xy.size or xy.shape[-1] != 2:
            return self.to_stacked(xy.reshape(-1, 2)).reshape(xy.shape)
        split = np.zeros(len(xy), bool)
        _compiled().outlines_to_stacked(xy, self.starts, self.stops, self.offsets, split)
        if split.any():
            xy[split] = self.to_stacked(np.asarray(outlines, np.float64)[split].reshape(-1, 2)).reshape(xy[split].shape)
        return xy

    def __repr__(self) -> str:
        bands = ", ".join(f"{a}:{b}" for a, b in zip(self.starts.tolist(), self.stops.tolist()))
        return f"RowBands([{bands}] of {self.shape[0]} rows, {self.fraction:.0%})"


@functools.cache
def _compiled():
    """The compiled kernels, imported on first use (see :mod:`sbplan.detection._kernels`)."""
    from . import _kernels
    return _kernels
