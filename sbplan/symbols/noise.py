"""The noise set: contours the camera may see that are not symbols.

The paper argues (section 3, condition 3) that a symbol must not be confusable with noise such as
the round blobs lighting errors make. sbplan measures it: every candidate's descriptor is compared
with the descriptors of these shapes, rendered through the same camera model and stages.

Families (all shapes are ``[outline, *holes]`` polygons in a unit box, y down, like the symbols):

``blobs``
    Lighting blobs: smooth random star-shaped outlines ``r(t) = 1 + sum_k a_k cos(k t + p_k)``,
    k = 2..5, the glare and shadow patches a binarizer cuts out of uneven light.
``circles``
    Circles (polygons of 96 vertices): the paper's own example of a bad symbol's confusion.
``ellipses``
    Ellipses with axis ratios from 1.1 to 4, the circles seen obliquely or stretched highlights.
``occluded``
    Partly hidden copies of the candidate itself: the candidate minus a random rectangle or
    half-plane that hides about 10 % to 45 % of its area (8-50 % accepted) (what an obstacle's edge leaves visible). Only
    drawn when a candidate is given.
``edges``
    Obstacle-edge fragments: pieces of dark boxes cut by the image of a lighter floor, i.e. box
    corners (a rectangle clipped by a half-plane), thin strips along an edge, and L-shaped bands.
"""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np
from shapely import affinity
from shapely.geometry import MultiPolygon, Point, Polygon, box
from shapely.geometry.base import BaseGeometry
from shapely.geometry.polygon import orient

from ..errors import InputError

#: The noise families, in the order they are drawn.
NOISE_FAMILIES = ("blobs", "circles", "ellipses", "occluded", "edges")


def parse_families(spec: str | Sequence[str] | None) -> tuple[str, ...]:
    """Validate a family list (``"blobs,circles"``, a sequence, or None for all)."""
    if spec is None:
        return NOISE_FAMILIES
    items = [s.strip() for s in spec.split(",")] if isinstance(spec, str) else [str(s).strip() for s in spec]
    items = [s for s in items if s]
    if "all" in items:
        return NOISE_FAMILIES
    bad = [s for s in items if s not in NOISE_FAMILIES]
    if bad or not items:
        raise InputError(f"noise_set: unknown noise families {bad or '(none given)'}; "
                         f"known: {', '.join(NOISE_FAMILIES)} (or all)")
    return tuple(dict.fromkeys(items))


def _rings(shape: BaseGeometry) -> list[np.ndarray] | None:
    """The rings of the polygon (of a multipolygon's largest part) in the unit box (longer side 1,
    centred), or None when degenerate or not a polygon."""
    if isinstance(shape, MultiPolygon):
        shape = max(shape.geoms, key=lambda g: g.area)
    if not isinstance(shape, Polygon) or shape.is_empty or shape.area <= 0:
        return None
    poly = shape.simplify(0.0)
    x0, y0, x1, y1 = poly.bounds
    side = max(x1 - x0, y1 - y0)
    if side <= 0 or poly.area < 0.002 * side * side:
        return None
    moved = affinity.affine_transform(poly, [1 / side, 0, 0, 1 / side, -x0 / side, -y0 / side])
    assert isinstance(moved, Polygon)  # simplifying and scaling keep a polygon a polygon
    oriented = orient(moved, sign=-1.0)
    return [np.asarray(r.coords, np.float64)[:-1] for r in (oriented.exterior, *oriented.interiors)]


def _blob(rng: np.random.Generator) -> Polygon:
    t = np.linspace(0, 2 * np.pi, 120, endpoint=False)
    k = np.arange(2, 6)
    amp = rng.uniform(0, 0.16, len(k)) / np.sqrt(k - 1)
    phase = rng.uniform(0, 2 * np.pi, len(k))
    r = 1 + (amp[:, None] * np.cos(k[:, None] * t[None, :] + phase[:, None])).sum(axis=0)
    aspect = rng.uniform(1.0, 1.6)
    return Polygon(np.c_[aspect * r * np.cos(t), r * np.sin(t)])


def _occluded(rings: Sequence[np.ndarray], rng: np.random.Generator) -> Polygon | None:
    sym = Polygon(rings[0], list(rings[1:])).buffer(0)
    x0, y0, x1, y1 = sym.bounds
    cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
    span = max(x1 - x0, y1 - y0)
    for _ in range(30):
        want = rng.uniform(0.10, 0.45)
        angle = rng.uniform(0, 360)
        if rng.random() < 0.5:
            # a half-plane: an obstacle's straight edge across the symbol
            u = np.array([math.cos(math.radians(angle)), math.sin(math.radians(angle))])
            proj = np.asarray(sym.exterior.coords) @ u
            lo, hi = proj.min(), proj.max()
            cut = lo + (hi - lo) * (1 - want)
            far = 4 * span
            c = np.array([cx, cy]) + u * (cut - np.array([cx, cy]) @ u)
            n = np.array([-u[1], u[0]])
            hider = Polygon([c + n * far, c + n * far + u * far, c - n * far + u * far, c - n * far])
        else:
            # a box corner poking into the symbol
            w, h = rng.uniform(0.3, 0.8, 2) * span
            px, py = rng.uniform(x0, x1), rng.uniform(y0, y1)
            hider = affinity.rotate(box(px - w / 2, py - h / 2, px + w / 2, py + h / 2), angle)
        left = sym.difference(hider)
        if isinstance(left, MultiPolygon):
            left = max(left.geoms, key=lambda g: g.area)
        hidden = 1 - left.area / sym.area
        if 0.08 <= hidden <= 0.5 and isinstance(left, Polygon):
            return left
    return None


def _edge_fragment(rng: np.random.Generator) -> BaseGeometry:
    kind = rng.integers(3)
    aspect = rng.uniform(1.0, 3.0)
    rect = box(0, 0, aspect, 1)
    if kind == 0:
        # a box's corner: the rectangle clipped by a random half-plane through it
        angle = rng.uniform(0, 180)
        far = box(-10, 0, 10, 20)
        hider = affinity.rotate(affinity.translate(far, rng.uniform(0.2, 0.8) * aspect, rng.uniform(0.2, 0.8)),
                                angle, origin=(rng.uniform(0, aspect), rng.uniform(0, 1)))
        piece = rect.difference(hider)
        return piece if not piece.is_empty else rect
    if kind == 1:
        # a thin strip along an obstacle edge, slightly ragged
        length = rng.uniform(4, 12)
        xs = np.linspace(0, length, 9)
        top = rng.normal(0, 0.06, len(xs))
        bottom = 1 + rng.normal(0, 0.06, len(xs))
        return Polygon(np.r_[np.c_[xs, top], np.c_[xs[::-1], bottom[::-1]]]).buffer(0)
    # an L-shaped band: the rim of a box corner
    band = rng.uniform(0.1, 0.3)
    outer = box(0, 0, aspect, 1)
    return outer.difference(box(band, band, aspect + 1, 2))


def noise_set(symbol_rings: Sequence[np.ndarray] | None = None, *, families: str | Sequence[str] | None = None,
              per_family: int = 12, seed: int = 0) -> list[tuple[str, list[np.ndarray]]]:
    """Draw the noise shapes.

    Parameters
    ----------
    symbol_rings : list of ndarray (N, 2), optional
        The candidate's ``[outline, *holes]`` in a unit box; needed for the ``occluded`` family
        (skipped without it).
    families : str or sequence of str, optional
        Which of :data:`NOISE_FAMILIES` to draw (comma-separated string allowed); default all.
    per_family : int
        Shapes per family (>= 1).
    seed : int
        Seed of every random choice; the same seed gives the same set.

    Returns
    -------
    list of (family, rings)
        ``rings`` is ``[outline, *holes]`` in a unit box, y down, outline counter-clockwise as
        displayed.
    """
    fams = parse_families(families)
    if isinstance(per_family, bool) or not isinstance(per_family, (int, np.integer)) or per_family < 1:
        raise InputError(f"per_family: expected an integer >= 1, got {per_family!r}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise InputError(f"seed: expected an integer >= 0, got {seed!r}")
    out: list[tuple[str, list[np.ndarray]]] = []
    for fi, fam in enumerate(NOISE_FAMILIES):
        if fam not in fams:
            continue
        # One stream per family so that dropping a family does not change the others' shapes.
        rng = np.random.default_rng(np.random.SeedSequence([int(seed), 0x7015E, fi]))
        for i in range(per_family):
            poly: BaseGeometry | None
            if fam == "blobs":
                poly = _blob(rng)
            elif fam == "circles":
                poly = Point(0, 0).buffer(1.0, quad_segs=24)
            elif fam == "ellipses":
                ratio = 1.1 * (4.0 / 1.1) ** (i / max(per_family - 1, 1))
                poly = affinity.scale(Point(0, 0).buffer(1.0, quad_segs=24), ratio, 1.0)
            elif fam == "occluded":
                if symbol_rings is None:
                    break
                poly = _occluded(symbol_rings, rng)
                if poly is None:
                    continue
            else:
                poly = _edge_fragment(rng)
            rings = _rings(poly)
            if rings is not None:
                out.append((fam, rings))
    return out
