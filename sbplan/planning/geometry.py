"""Input preparation for the planners: point and polygon validation, enlargement.

All points are world coordinates ``(x, y)`` (metres, or pixels with a scale), y up.
"""

from __future__ import annotations

import math
from typing import Any, Iterable, Sequence

import numpy as np
import shapely
from shapely.geometry import MultiPolygon, Polygon
from shapely.geometry.polygon import orient

from ..errors import InputError

#: Mitre joins keep an enlarged rectangle a rectangle (its four corners are the auxiliary
#: corners). A limit of 4 bevels only very sharp spikes; the result always contains the round
#: buffer, so routes around it keep at least the requested clearance.
MITRE_LIMIT = 4.0

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
            if not p.is_valid:
                p = shapely.make_valid(p)
                parts2 = [g for g in getattr(p, "geoms", [p]) if isinstance(g, Polygon)]
                out.extend(g for g in parts2 if g.area > 0)
                continue
            if p.area > 0:
                out.append(p)
    return out


def enlarge(polygons: Sequence[Polygon], distance: float) -> list[Polygon]:
    """Enlarge each polygon by ``distance`` with mitre joins; orient CCW (holes CW), drop
    collinear vertices. Overlaps are kept (not merged): the planner tests against all of them."""
    out = []
    for p in polygons:
        q = p.buffer(distance, join_style="mitre", mitre_limit=MITRE_LIMIT) if distance > 0 else p
        for g in getattr(q, "geoms", [q]):
            if isinstance(g, Polygon) and not g.is_empty and g.area > 0:
                out.append(orient(g.simplify(0.0), 1.0))
    return out
