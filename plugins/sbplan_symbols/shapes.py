"""Parametric candidate symbols.

Every builder returns a shapely polygon in arbitrary units; :func:`normalize` scales it into the
unit box (the longer side spans [0, 1], the shorter side is centred), y down, and orients it: the
outline runs counter-clockwise *as displayed* (negative shoelace area in y-down coordinates), holes
clockwise. The result is ``[outline, *holes]``, each an ``(N, 2)`` float64 array of ``(x, y)``
vertices, not closed.
"""

from __future__ import annotations

import numpy as np
from shapely import affinity
from shapely.geometry import Point, Polygon, box
from shapely.geometry.base import BaseGeometry
from shapely.geometry.polygon import orient
from shapely.ops import unary_union


def normalize(shape: BaseGeometry) -> list[np.ndarray]:
    """Scale ``shape`` (one polygon) into the unit box and return ``[outline, *holes]`` (see module doc)."""
    poly = shape.simplify(0.0)  # drops collinear vertices left by unions
    if not isinstance(poly, Polygon):
        raise ValueError(f"a symbol is one polygon, got a {poly.geom_type}")
    x0, y0, x1, y1 = poly.bounds
    s = 1.0 / max(x1 - x0, y1 - y0)
    w, h = (x1 - x0) * s, (y1 - y0) * s
    scaled = affinity.affine_transform(poly, [s, 0, 0, s, -x0 * s + (1 - w) / 2, -y0 * s + (1 - h) / 2])
    assert isinstance(scaled, Polygon)  # an affine map keeps a polygon a polygon
    # shapely's sign=-1 gives a clockwise exterior in y-up terms = counter-clockwise as displayed.
    oriented = orient(scaled, sign=-1.0)
    rings = [oriented.exterior, *oriented.interiors]
    return [np.asarray(r.coords, dtype=np.float64)[:-1] for r in rings]


def boxes(*rects: tuple[float, float, float, float]) -> BaseGeometry:
    """Union of axis-aligned rectangles ``(x0, y0, x1, y1)``."""
    return unary_union([box(*r) for r in rects])


def poly(*pts: tuple[float, float]) -> Polygon:
    return Polygon(pts)


def star(n: int, inner: float) -> Polygon:
    a = np.arange(2 * n) * np.pi / n - np.pi / 2
    r = np.where(np.arange(2 * n) % 2 == 0, 1.0, inner)
    return Polygon(np.c_[r * np.cos(a), r * np.sin(a)])


def circle(r: float = 1.0, n: int = 96) -> Polygon:
    return Point(0, 0).buffer(r, quad_segs=n // 4)


def regular(n: int, phase: float = 0.0) -> Polygon:
    a = np.arange(n) * 2 * np.pi / n + phase
    return Polygon(np.c_[np.cos(a), np.sin(a)])


def _builders() -> dict[str, tuple[str, BaseGeometry]]:
    t = 0.28  # stroke width of the block letters and crosses
    c = circle()
    return {
        # -- asymmetric, partially regular: the good candidates --------------------------------
        "flag": ("pole with a swallow-tailed flag on its upper right (paper figure 1 style, default)",
                 poly((0, 0), (1, 0), (0.7, 0.24), (0.86, 0.52), (0.3, 0.52), (0.3, 1.0), (0, 1.0))),
        "pennant": ("pole with a triangular pennant",
                    poly((0, 0), (1, 0.28), (0.3, 0.56), (0.3, 1), (0, 1))),
        "flag-square": ("pole with a rectangular flag",
                        boxes((0, 0, 0.3, 1), (0.3, 0, 1, 0.5))),
        "letter-f": ("block letter F", boxes((0, 0, t, 1), (t, 0, 0.85, t), (t, 0.4, 0.65, 0.4 + t))),
        "letter-e": ("block letter E", boxes((0, 0, t, 1), (t, 0, 0.8, 0.24), (t, 0.38, 0.68, 0.62),
                                              (t, 0.76, 0.8, 1))),
        "letter-l": ("block letter L", boxes((0, 0, t, 1), (t, 1 - t, 0.7, 1))),
        "letter-t": ("block letter T", boxes((0, 0, 1, t), (0.5 - t / 2, t, 0.5 + t / 2, 1))),
        "letter-h": ("block letter H", boxes((0, 0, t, 1), (1 - t, 0, 1, 1), (t, 0.36, 1 - t, 0.64))),
        "letter-z": ("block letter Z", poly((0, 0), (1, 0), (1, 0.22), (0.36, 0.78), (1, 0.78), (1, 1),
                                            (0, 1), (0, 0.78), (0.64, 0.22), (0, 0.22))),
        "letter-n": ("block letter N", poly((0, 0), (0.26, 0), (0.74, 0.6), (0.74, 0), (1, 0), (1, 1),
                                            (0.74, 1), (0.26, 0.4), (0.26, 1), (0, 1))),
        "letter-k": ("block letter K", poly((0, 0), (0.26, 0), (0.26, 0.4), (0.66, 0), (0.98, 0),
                                            (0.5, 0.48), (1, 1), (0.68, 1), (0.26, 0.58), (0.26, 1), (0, 1))),
        "letter-y": ("block letter Y", poly((0, 0), (0.3, 0), (0.5, 0.3), (0.7, 0), (1, 0), (0.64, 0.5),
                                            (0.64, 1), (0.36, 1), (0.36, 0.5))),
        "letter-p": ("block letter P (one hole)",
                     boxes((0, 0, t, 1), (0, 0, 0.8, 0.6)).difference(box(t, 0.18, 0.58, 0.42))),
        "letter-a": ("block letter A with its triangular hole",
                     poly((0.38, 0), (0.62, 0), (1, 1), (0.74, 1), (0.64, 0.72), (0.36, 0.72), (0.26, 1),
                          (0, 1)).difference(poly((0.5, 0.24), (0.58, 0.52), (0.42, 0.52)))),
        "cross": ("plus-shaped cross (4-fold symmetric)", boxes((0.5 - t / 2, 0, 0.5 + t / 2, 1),
                                                                 (0, 0.5 - t / 2, 1, 0.5 + t / 2))),
        "cross-x": ("diagonal cross X", affinity.rotate(boxes((0.5 - t / 2, 0, 0.5 + t / 2, 1),
                                                              (0, 0.5 - t / 2, 1, 0.5 + t / 2)), 45)),
        "cross-latin": ("latin cross (long lower arm)", boxes((0.5 - t / 2, 0, 0.5 + t / 2, 1),
                                                               (0.1, 0.22, 0.9, 0.22 + t))),
        "arrow": ("arrow pointing right", poly((0, 0.35), (0.55, 0.35), (0.55, 0.05), (1, 0.5), (0.55, 0.95),
                                               (0.55, 0.65), (0, 0.65))),
        "arrow-bent": ("arrow with a bent shaft (L-shaped)",
                       poly((0, 1), (0, 0.3), (0.55, 0.3), (0.55, 0.05), (1, 0.42), (0.55, 0.8), (0.55, 0.55),
                            (0.27, 0.55), (0.27, 1))),
        "arrow-double": ("double-headed arrow", poly((0, 0.5), (0.3, 0.1), (0.3, 0.36), (0.7, 0.36), (0.7, 0.1),
                                                     (1, 0.5), (0.7, 0.9), (0.7, 0.64), (0.3, 0.64), (0.3, 0.9))),
        "chevron": ("chevron pointing right", poly((0, 0), (0.4, 0), (1, 0.5), (0.4, 1), (0, 1), (0.6, 0.5))),
        "lightning": ("lightning bolt zig-zag", poly((0.35, 0), (0.85, 0), (0.62, 0.38), (0.95, 0.38), (0.25, 1),
                                                      (0.42, 0.55), (0.1, 0.55))),
        "stairs": ("three steps", boxes((0, 0.66, 1, 1), (0.33, 0.33, 1, 0.67), (0.66, 0, 1, 0.34))),
        "hook": ("hook / letter J", boxes((0.62, 0, 0.9, 1), (0.05, 0.74, 0.62, 1), (0.05, 0.52, 0.3, 0.74))),
        "notched-square": ("square with one corner notch", boxes((0, 0, 1, 1)).difference(box(0.6, 0, 1, 0.4))),
        "notched-square-2": ("square with two notches on adjacent corners",
                             boxes((0, 0, 1, 1)).difference(box(0.6, 0, 1, 0.35)).difference(box(0, 0.7, 0.3, 1))),
        "slotted-square": ("square with a slot cut into one side",
                           boxes((0, 0, 1, 1)).difference(box(0.38, 0.45, 0.62, 1))),
        "trapezoid": ("right trapezoid", poly((0, 0), (0.55, 0), (1, 1), (0, 1))),
        "triangle": ("equilateral triangle", regular(3, -np.pi / 2)),
        "square": ("square (4-fold symmetric, confusable with boxes)", box(0, 0, 1, 1)),
        "hexagon": ("regular hexagon", regular(6)),
        "star-4": ("four-pointed star", star(4, 0.38)),
        "star-5": ("five-pointed star", star(5, 0.45)),
        "star-6": ("six-pointed star", star(6, 0.55)),
        "circle": ("circle (bad: lighting errors make round contours)", c),
        "ellipse": ("ellipse 2:1 (bad: round)", affinity.scale(c, 1.0, 0.5)),
        "ring": ("ring: disc with a round hole (bad: round)", c.difference(circle(0.55))),
        "rounded-square": ("square with rounded corners (bad: nearly round)", box(-0.6, -0.6, 0.6, 0.6).buffer(0.4)),
        "half-disc": ("half disc, D shape", c.intersection(box(0, -1, 1, 1))),
        "crescent": ("crescent moon", c.difference(Point(0.45, -0.1).buffer(0.85, quad_segs=24))),
    }


def catalogue() -> dict[str, tuple[str, list[np.ndarray]]]:
    """Every built-in symbol: name -> (description, ``[outline, *holes]`` in the unit box)."""
    return {name: (desc, normalize(p)) for name, (desc, p) in _builders().items()}
