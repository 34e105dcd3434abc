"""``opencv``: OpenCV's border following (Suzuki & Abe 1985) converted to sbplan's contour model.

``cv2.findContours(mask, RETR_TREE, CHAIN_APPROX_NONE)`` already follows sbplan's conventions:
8-connected foreground, 4-connected background, outer boundaries start at the region's first pixel
in raster order and run counter-clockwise as displayed, hole boundaries start at the foreground
pixel left of the hole's first pixel and run clockwise. So the conversion only concatenates the
point arrays, derives hole flags from the tree depth (odd depth = hole) and, vectorized over all
contours at once, the Freeman chains. This extractor is on the detection hot path; ``chains=False``
skips the chain codes for callers that only need the points.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from sbplan.contours import Contour

from ._common import BoundaryExtractor, as_mask, build_contours


@dataclass(kw_only=True, frozen=True)
class OpenCVExtractor(BoundaryExtractor):
    """Contours by OpenCV's border following."""

    name = "opencv"
    description = "OpenCV border following (findContours, RETR_TREE, CHAIN_APPROX_NONE)"

    def extract(self, binary: np.ndarray) -> list[Contour]:
        """Return every outer boundary and hole boundary of ``binary``.

        Parameters
        ----------
        binary : ndarray of shape (H, W), bool or uint8 (0/1/255)
            Foreground mask indexed ``(row, col)``; nonzero is foreground.

        Returns
        -------
        list of Contour
            Points are ``(x, y)`` int64; parents follow the nesting tree (a hole's parent is the
            outer boundary of its region, an island's parent is the hole around it).
        """
        return find_contours_opencv(binary, chains=self.chains)

    def extract_outer(self, binary: np.ndarray) -> list[Contour]:
        """Only the outer boundaries, as :meth:`extract` gives them (same points, same order of
        traversal), with ``parent`` -1. Without chains, the points are OpenCV's own int32 arrays.

        ``RETR_CCOMP`` puts every outer boundary, islands inside holes included, on the top level
        of its two-level hierarchy, so no nesting depth is needed and no hole is converted.
        """
        mask = as_mask(binary, name="binary")
        found, hierarchy = cv2.findContours(mask, cv2.RETR_CCOMP, cv2.CHAIN_APPROX_NONE)
        if not found:
            return []
        keep = np.flatnonzero(hierarchy[0, :, 3] < 0).tolist()
        if not self.chains:
            # no conversion: this runs once per frame on detection's hot path
            empty = np.zeros(0, np.uint8)
            return Contour.outers_unchecked([found[i].reshape(-1, 2) for i in keep], empty)
        found = [found[i] for i in keep]
        lengths = np.fromiter(map(len, found), dtype=np.int64, count=len(found))
        points = np.concatenate(found).reshape(-1, 2).astype(np.int64)
        n = len(found)
        return build_contours(points, lengths, np.zeros(n, bool), np.full(n, -1), chains=True)


def find_contours_opencv(binary: np.ndarray, *, chains: bool = True) -> list[Contour]:
    """Functional form of :class:`OpenCVExtractor` (same parameters and result)."""
    mask = as_mask(binary, name="binary")
    found, hierarchy = cv2.findContours(mask, cv2.RETR_TREE, cv2.CHAIN_APPROX_NONE)
    if not found:
        return []
    parent = hierarchy[0, :, 3].astype(np.int64)
    # Hole flag = odd depth in the tree; the loop runs once per nesting level, not per contour.
    is_hole = np.zeros(len(parent), bool)
    up = parent.copy()
    while True:
        inside = up >= 0
        if not inside.any():
            break
        is_hole ^= inside
        up = np.where(inside, parent[np.maximum(up, 0)], -1)
    lengths = np.fromiter(map(len, found), dtype=np.int64, count=len(found))
    points = np.concatenate(found).reshape(-1, 2).astype(np.int64)
    return build_contours(points, lengths, is_hole, parent, chains=chains)
