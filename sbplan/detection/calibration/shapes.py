"""The outer contours of an image as polygons with their areas, centres and descriptors: what
calibration measures on the reference and on its degraded copies."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ...contracts import array_of, call_stage, describe_value, descriptors_of, stage_failure
from ...polygons import centroids, length_filter, signed_areas
from ..working import WorkScale


def _is_list(v) -> str | None:
    return None if isinstance(v, (list, tuple)) else f"{describe_value(v)}, expected a list of Contours"


def _is_points(v) -> str | None:
    if isinstance(v, np.ndarray) and v.ndim == 2 and v.shape[1] == 2 and v.dtype.kind in "iuf" \
            and np.isfinite(v).all():
        return None
    return f"{describe_value(v)}, expected finite (M, 2) points"


@dataclass(frozen=True, eq=False)
class Shapes:
    """The outer contours of one image that passed the length filter, as polygons."""

    polygons: list[np.ndarray]
    points: np.ndarray  # number of boundary pixels of each contour
    areas: np.ndarray
    centres: np.ndarray  # (n, 2) centre of area (x, y)
    descriptors: np.ndarray  # (n, K)
    n_contours: int  # before the length filter
    #: each polygon's holes (a letter A's triangle, a P's counter) as polygons, in the same pixels;
    #: holes of fewer than MIN_HOLE_POINTS boundary pixels (specks in the ink) are left out
    holes: list[list[np.ndarray]] = field(default_factory=list)


#: A hole in a symbol's ink is kept when its boundary has at least this many pixels: a 2 x 2 speck
#: of floor in the ink has 4, the smallest counter of a printed letter dozens.
MIN_HOLE_POINTS = 12


def extract_shapes(gray: np.ndarray, *, binarizer, extractor, approximator, matcher,
                   points_range: tuple[int, int], work: WorkScale | None = None) -> Shapes:
    """Binarize, extract, length-filter, approximate and describe the outer contours of an image.

    With ``work`` (:class:`~sbplan.detection.working.WorkScale`) the image is reduced first and
    the polygons mapped back to its pixels (areas and centres with them); ``points`` and
    ``points_range`` count the reduced image's boundary pixels.

    Every stage is called through :func:`sbplan.contracts.call_stage`: a stage that raises or
    returns what its contract does not allow is a StageError naming it.
    """
    if work is not None:
        gray = work.reduce(gray)
    binary = call_stage(binarizer, "binarize", gray, returns=array_of(gray.shape, kinds="bui"))
    found = call_stage(extractor, "extract", binary, returns=_is_list)
    try:
        outer = [i for i, c in enumerate(found) if not c.is_hole]
        contours = [found[i] for i in outer]
        kept_at = [outer[i] for i in np.flatnonzero(length_filter_steps(contours, points_range))]
        holes_of: dict[int, list] = {}
        for c in found:
            if c.is_hole and len(c.points) >= MIN_HOLE_POINTS:
                holes_of.setdefault(int(c.parent), []).append(c)
    except (AttributeError, TypeError):
        raise stage_failure(extractor, "broke its contract: extract() returned items that are not Contours") from None
    kept = [found[i] for i in kept_at]
    approximated = [call_stage(approximator, "approximate", c, returns=_is_points) for c in kept]
    keep = [i for i, p in enumerate(approximated) if len(p) >= 3]
    polygons = [np.asarray(approximated[i], np.float64) for i in keep]
    holes = [[_hole_polygon(approximator, h) for h in holes_of.get(kept_at[i], [])] for i in keep]
    if work is not None and not work.identity:
        polygons = [work.to_frame(p) for p in polygons]
        holes = [[work.to_frame(h) for h in hs] for hs in holes]
    n_points = [len(kept[i].points) for i in keep]
    areas = np.abs(signed_areas(polygons)) if polygons else np.zeros(0)
    nonzero = np.flatnonzero(areas > 0)
    polygons, n_points, areas = [polygons[i] for i in nonzero], [n_points[i] for i in nonzero], areas[nonzero]
    holes = [holes[i] for i in nonzero]
    if polygons:
        centres = centroids(polygons).reshape(-1, 2)
        descriptors = descriptors_of(matcher, polygons)
    else:
        areas, centres = np.zeros(0), np.zeros((0, 2))
        descriptors = call_stage(matcher, "describe_many", [], returns=array_of((0, None)))
    return Shapes(polygons, np.asarray(n_points, np.int64), areas, centres, descriptors, len(contours), holes)


def _hole_polygon(approximator, contour) -> np.ndarray:
    """A hole's outline: the approximator's polygon, or the hole's own boundary pixels where the
    approximation keeps fewer than three vertices (a small round counter)."""
    polygon = np.asarray(call_stage(approximator, "approximate", contour, returns=_is_points), np.float64)
    return polygon if len(polygon) >= 3 else np.asarray(contour.points, np.float64)


def length_filter_steps(contours: list, points_range: tuple[int, int]) -> np.ndarray:
    """The paper's length filter on contour lengths counted in boundary steps (pixels).

    Counting steps, not Euclidean length, needs no Freeman chain, which the hot path skips.
    """
    steps = np.fromiter((len(c.points) for c in contours), np.float64, len(contours))
    return length_filter(steps, min_length=points_range[0], max_length=points_range[1])
