"""What both extractors share: input validation and the conversion of concatenated boundary
pixels into :class:`sbplan.contours.Contour` objects."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np

from sbplan.contours import FREEMAN_STEPS, Contour
from sbplan.contracts import ContourExtractor, option
from sbplan.errors import ImageError, InputError

# Freeman code of a step (dx, dy), indexed by (dx + 1) * 3 + (dy + 1); 255 marks "not a step".
_STEP_CODE = np.full(9, 255, np.uint8)
for _code, (_dx, _dy) in enumerate(FREEMAN_STEPS):
    _STEP_CODE[(_dx + 1) * 3 + (_dy + 1)] = _code


def as_mask(binary: Any, *, name: str = "binary") -> np.ndarray:
    """Validate a foreground mask and return it as a C-contiguous uint8 array, nonzero = foreground.

    Parameters
    ----------
    binary : ndarray of shape (H, W), bool, or uint8 holding only 0, 1 and 255
        The mask, indexed ``(row, col)``.

    Returns
    -------
    ndarray of shape (H, W), uint8
        A zero-copy view where possible (bool input is viewed, not copied); values are only
        guaranteed to be zero or nonzero.

    Raises
    ------
    ImageError
        If ``binary`` is not a 2-D non-empty bool or uint8 array, or a uint8 array holds
        values other than 0, 1 and 255.
    """
    if not isinstance(binary, np.ndarray):
        raise ImageError(f"{name}: expected a numpy array (bool or uint8 mask), got {type(binary).__name__}")
    if binary.dtype != np.bool_ and binary.dtype != np.uint8:
        raise ImageError(f"{name}: expected a bool or uint8 mask, got dtype {binary.dtype}")
    if binary.ndim != 2:
        raise ImageError(f"{name}: expected a 2-D (H, W) mask, got shape {binary.shape}")
    if binary.size == 0:
        raise ImageError(f"{name}: empty mask (shape {binary.shape})")
    mask = np.ascontiguousarray(binary)
    if mask.dtype == np.bool_:
        return mask.view(np.uint8)
    # inRange + countNonZero: a full-frame check that costs a fraction of what numpy's would.
    if cv2.countNonZero(cv2.inRange(mask, 2, 254)):
        raise ImageError(f"{name}: a uint8 mask may only hold 0, 1 and 255 (nonzero = foreground)")
    return mask


def chain_codes(points: np.ndarray, starts: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    """Freeman codes of many closed contours stored back to back.

    Parameters
    ----------
    points : ndarray of shape (T, 2), int64
        All contours' pixels ``(x, y)``, contour ``k`` at ``points[starts[k]:starts[k] + lengths[k]]``.
    starts, lengths : ndarray of shape (C,), int64

    Returns
    -------
    ndarray of shape (T,), uint8
        ``codes[i]`` is the step from point ``i`` to the next point of its contour (cyclically).
        Entries of one-point contours are meaningless (callers give those an empty chain).
    """
    total = len(points)
    nxt = np.arange(1, total + 1, dtype=np.int64)
    ends = starts + lengths - 1
    nxt[ends] = starts
    d = points[nxt] - points
    return _STEP_CODE[(d[:, 0] + 1) * 3 + (d[:, 1] + 1)]


def build_contours(points: np.ndarray, lengths: np.ndarray, is_hole: np.ndarray, parent: np.ndarray,
                   *, chains: bool = True) -> list[Contour]:
    """Cut concatenated boundary pixels into Contour objects.

    ``points`` (T, 2) int64 ``(x, y)`` holds the contours back to back in traversal order (outer
    boundaries counter-clockwise as displayed, holes clockwise); ``lengths``, ``is_hole`` and
    ``parent`` have one entry per contour. With ``chains=False`` every chain is left empty.
    """
    lengths = np.asarray(lengths, dtype=np.int64)
    ends = np.cumsum(lengths)
    starts = ends - lengths
    empty = np.zeros(0, np.uint8)
    holes = np.asarray(is_hole, bool).tolist()
    parents = np.asarray(parent, np.int64).tolist()
    s_list, e_list = starts.tolist(), ends.tolist()
    if chains and len(points):
        codes = chain_codes(points, starts, lengths)
        return [Contour(points[s:e], is_hole=h, orientation=-1 if h else 1,
                        chain=codes[s:e] if e - s > 1 else empty, parent=p)
                for s, e, h, p in zip(s_list, e_list, holes, parents)]
    return [Contour(points[s:e], is_hole=h, orientation=-1 if h else 1, chain=empty, parent=p)
            for s, e, h, p in zip(s_list, e_list, holes, parents)]


@dataclass(kw_only=True, frozen=True)
class BoundaryExtractor(ContourExtractor):
    """Options both extractors take; a base class, not a stage of its own (it has no name)."""

    chains: bool = option(True, "compute Freeman chain codes (False leaves every chain empty)")

    def __post_init__(self) -> None:
        if not isinstance(self.chains, (bool, np.bool_)):
            raise InputError(f"option chains: expected True or False, got {self.chains!r}")
