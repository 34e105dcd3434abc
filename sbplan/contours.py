"""Data shared between stages.

Coordinates: image points are ``(x, y)`` pixels, origin at the top-left pixel's centre, x to the
right, y down. Arrays of points have shape ``(N, 2)`` with columns ``(x, y)``; grid cells are
``(row, col)``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Iterable

import numpy as np

from .errors import ContourError

#: Freeman directions 0..7 as ``(dx, dy)`` in image coordinates: 0 = east, counting
#: counter-clockwise as displayed, so 2 = up (dy = -1) and 6 = down.
FREEMAN_STEPS = np.array(
    [(1, 0), (1, -1), (0, -1), (-1, -1), (-1, 0), (-1, 1), (0, 1), (1, 1)], dtype=np.int64
)


@dataclass(frozen=True, eq=False)
class Contour:
    """One closed boundary of a connected region of a binary image.

    Attributes
    ----------
    points : ndarray of shape (N, 2), integer
        The boundary pixels ``(x, y)`` in traversal order; the contour closes from the last point
        back to the first (the first point is not repeated). int64 from the extractors'
        ``extract``; ``extract_outer``, on detection's hot path, may hand out OpenCV's own int32
        arrays instead of converting them.
    is_hole : bool
        False for the outer boundary of a foreground (True) region, True for the boundary of a
        hole inside one.
    orientation : int
        +1 when the traversal runs counter-clockwise as displayed, -1 clockwise.
    chain : ndarray of shape (N,), uint8
        Freeman codes: ``points[i + 1] - points[i] == FREEMAN_STEPS[chain[i]]`` (indices mod N).
        A one-pixel contour has ``N == 1`` and an empty chain.
    parent : int
        Index of the enclosing contour in the extractor's output, or -1.
    """

    points: np.ndarray
    is_hole: bool = False
    orientation: int = 1
    chain: np.ndarray = field(default_factory=lambda: np.zeros(0, np.uint8))
    parent: int = -1

    @classmethod
    def outers_unchecked(cls, points: "Iterable[np.ndarray]", chain: np.ndarray) -> "list[Contour]":
        """Outer boundaries (``is_hole`` False, orientation +1, parent -1), one per point array,
        sharing one ``chain``, made without the dataclass constructor: an extractor's hot path
        makes dozens per frame, and a frozen dataclass's ``__init__`` costs about three times as
        much as copying one prepared attribute dict. Nothing is checked."""
        new = object.__new__
        base = {"is_hole": False, "orientation": 1, "chain": chain, "parent": -1}
        out = []
        for p in points:
            obj = new(cls)
            d = obj.__dict__
            d.update(base)
            d["points"] = p
            out.append(obj)
        return out

    @property
    def start(self) -> tuple[int, int]:
        """The start point ``(x, y)`` of the Freeman chain."""
        x, y = self.points[0]
        return int(x), int(y)

    def __len__(self) -> int:
        return len(self.points)


def as_points(points, *, name: str = "points", min_points: int = 3) -> np.ndarray:
    """Validate a closed contour or polygon and return it as a float64 ``(N, 2)`` array.

    Raises
    ------
    ContourError
        If ``points`` is not an ``(N, 2)`` array of finite numbers with ``N >= min_points``.
    """
    try:
        arr = np.asarray(points, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ContourError(f"{name}: not an array of numbers ({exc})") from None
    if arr.ndim == 3 and arr.shape[1] == 1:  # OpenCV's (N, 1, 2)
        arr = arr[:, 0, :]
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise ContourError(f"{name}: expected shape (N, 2) of (x, y) points, got {arr.shape}")
    if len(arr) < min_points:
        raise ContourError(f"{name}: a closed contour needs at least {min_points} points, got {len(arr)}")
    if not np.isfinite(arr).all():
        raise ContourError(f"{name}: contains NaN or infinite coordinates")
    return arr
