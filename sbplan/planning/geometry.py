"""Input preparation for the planners: point and polygon validation, enlargement.

All points are world coordinates ``(x, y)`` (metres, or pixels with a scale), y up.
"""

from __future__ import annotations

import math
from typing import Any, Iterable, Sequence, cast

import numpy as np
import shapely
from shapely.geometry import MultiPolygon, Polygon
from shapely.geometry.polygon import orient

from ..errors import InputError

#: Mitre joins keep an enlarged rectangle a rectangle (its four corners are the auxiliary
#: corners). A limit of 4 bevels only very sharp spikes; the result always contains the round
#: buffer, so routes around it keep at least the requested clearance.
MITRE_LIMIT = 4.0
#: Largest coordinate (map units) an obstacle may have: squares of coordinates stay finite and a
#: map's tolerance (1e-6 of its size) stays above double precision's rounding.
MAX_COORDINATE = 1e12

_F64 = np.dtype(float)


def as_point(p: Any, name: str) -> tuple[np.ndarray, float, float]:
    """Validate a point; return it as a float array of shape (2,) ``(x, y)`` and as two floats.

    Raises InputError naming ``name`` unless ``p`` is a finite point ``(x, y)``.
    """
    if type(p) is np.ndarray and p.dtype is _F64 and p.shape == (2,):
        a = p  # the common case, without asarray's and isfinite's call overhead
    else:
        try:
            a = np.asarray(p, dtype=float).reshape(-1)
        except (TypeError, ValueError):
            raise InputError(f"{name}: expected a point (x, y), got {p!r}") from None
        if a.shape != (2,):
            raise InputError(f"{name}: expected a finite point (x, y), got {p!r}")
    x, y = a.tolist()
    if not (math.isfinite(x) and math.isfinite(y)):
        raise InputError(f"{name}: expected a finite point (x, y), got {p!r}")
    return a, x, y


def nonneg(v: Any, name: str) -> float:
    """Validate a finite number >= 0 (a radius, a margin, a time limit); InputError naming ``name``."""
    try:
        f = float(v)
    except (TypeError, ValueError):
        raise InputError(f"{name}: expected a number, got {v!r}") from None
    if not math.isfinite(f) or f < 0:
        raise InputError(f"{name}: must be a finite number >= 0, got {v!r}")
    return f


def as_polygons(obstacles: Iterable, *, name: str = "obstacles") -> list[Polygon]:
    """Validate obstacles and return them as a list of valid shapely polygons.

    Parameters
    ----------
    obstacles : iterable of shapely Polygon / MultiPolygon or array_like of shape (M, 2)
        Each an obstacle outline ``(x, y)``; multipolygons are split into their parts.
    """
    out: list[Polygon] = []
    if isinstance(obstacles, (str, bytes)) or not hasattr(obstacles, "__iter__"):
        raise InputError(f"{name}: expected a list of polygons or (M, 2) point arrays, got {type(obstacles).__name__}")
    for i, ob in enumerate(obstacles):
        if isinstance(ob, MultiPolygon):
            parts = list(ob.geoms)
        elif isinstance(ob, Polygon):
            parts = [ob]
        else:
            try:
                pts = np.asarray(ob, dtype=float)
            except (TypeError, ValueError):
                raise InputError(f"{name}[{i}]: not a polygon or an (M, 2) array of points") from None
            if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) < 3:
                raise InputError(f"{name}[{i}]: expected an (M, 2) array with M >= 3, got shape {pts.shape}")
            parts = [Polygon(pts)]
        for p in parts:
            if p.is_empty:
                continue
            coords = np.asarray(p.exterior.coords)
            if not np.isfinite(coords).all():
                raise InputError(f"{name}[{i}]: coordinates must be finite")
            # beyond this the planner's products of coordinates overflow or lose the tolerance
            if np.abs(coords).max() > MAX_COORDINATE or not np.isfinite(p.area):
                raise InputError(f"{name}[{i}]: coordinates reach {np.abs(coords).max():.3g}, beyond the "
                                 f"{MAX_COORDINATE:g} the planner's arithmetic holds; clip obstacles to the workspace")
            if not p.is_valid:
                valid = shapely.make_valid(p)
                parts2 = [g for g in getattr(valid, "geoms", [valid]) if isinstance(g, Polygon)]
                out.extend(g for g in parts2 if _has_area(g))
                continue
            if _has_area(p):
                out.append(p)
    return out


#: A polygon whose area is below this fraction of its bounding box's square has no area the
#: planner can use: GEOS's buffer of a triangle 1e-200 thick misses points within the radius.
DEGENERATE_AREA = 1e-100


def _has_area(p: Polygon) -> bool:
    """An area the planner's arithmetic can see (zero-area and underflowing slivers are dropped)."""
    x0, y0, x1, y1 = p.bounds
    return p.area > DEGENERATE_AREA * max(x1 - x0, y1 - y0) ** 2


def enlarge(polygons: Sequence[Polygon], distance: float) -> list[Polygon]:
    """Enlarge each polygon by ``distance`` with mitre joins; orient CCW (holes CW), drop
    collinear vertices. Overlaps are kept (not merged): the planner tests against all of them."""
    out = []
    for p in polygons:
        q = p.buffer(distance, join_style="mitre", mitre_limit=MITRE_LIMIT) if distance > 0 else p
        for g in getattr(q, "geoms", [q]):
            if isinstance(g, Polygon) and not g.is_empty and g.area > 0:
                out.append(orient(cast(Polygon, g.simplify(0.0)), 1.0))  # simplify(0) keeps a polygon
    return out


def check_size(polygons: list[Polygon]) -> None:
    """The obstacle_vertices limit (:mod:`sbplan.limits`): the visibility cache grows with the
    square of the obstacles' vertices. Raises LimitError."""
    from .. import limits

    n = int(shapely.get_num_coordinates(polygons).sum()) if polygons else 0
    limits.check("obstacle_vertices", n, f"obstacles with {n:,} vertices",
                 "simplify the obstacles (or clean a noisy occupancy image)")


#: Obstacles may reach this many workspace sizes from its centre: farther, the rounding of their
#: coordinates (2.2e-16 of them) nears the map's tolerance (1e-6 of its size).
MAX_REACH = 1e9


def check_extent(polygons: list[Polygon], bounds: Sequence[float]) -> None:
    """Refuse obstacles reaching farther from the workspace than double precision holds for it
    (InputError)."""
    if not polygons:
        return
    size = max(bounds[2] - bounds[0], bounds[3] - bounds[1])
    cx, cy = (bounds[0] + bounds[2]) / 2, (bounds[1] + bounds[3]) / 2
    reach = float(np.max(np.abs(shapely.bounds(polygons) - [cx, cy, cx, cy])))
    if not reach <= MAX_REACH * size:
        raise InputError(f"obstacles: reach {reach:.3g} from the workspace's centre, more than {MAX_REACH:g} times "
                         f"its size {size:.3g}: beyond double precision for this map; clip them to the workspace")
