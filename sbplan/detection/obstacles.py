"""Obstacles from their outlines: cells, outline polygons, MARs, parts, and the obstacle models.

Paper section 4.1: the occupancy image's black areas are the obstacles; their contours are
described as polygons and each gets its minimum-area rectangle (MAR). The outlines come from the
footprint stage (:mod:`sbplan.detection.footprints`): the cells' regions, or each obstacle's
outline refined from the pixels.

What the planner avoids is one of three **obstacle models**, named the same everywhere (CLI
``--obstacle-model``, the API, the TUI, GeoJSON, nav2 and the overlay):

- ``mar``: each obstacle's minimum-area rectangle (the paper's; four auxiliary corners each);
- ``parts`` (the default): the MAR where it covers at most :data:`PARTS_RATIO` times the outline's
  area, otherwise the rectangles of the parts the outline is cut into until each does
  (:func:`split_parts`): two obstacles touching at a corner, an L or a ring never become one giant
  rectangle over free floor;
- ``outline``: the outline polygon itself.

All three contain the outline, so each keeps the robot off everything the footprint holds;
``parts`` keeps routes nearly as short as ``outline`` with a few corners per obstacle.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Callable, Sequence

import cv2
import numpy as np
import shapely
import shapely.affinity
from shapely.geometry import Polygon

from ..contours import as_points
from ..errors import InputError

#: The obstacle models, and the default (see the module's description).
OBSTACLE_MODELS = ("mar", "parts", "outline")
DEFAULT_OBSTACLE_MODEL = "parts"
#: A part's rectangle covers at most this many times the part's area (the ``parts`` model).
PARTS_RATIO = 1.3
#: Parts are not cut further once they are smaller than this share of their obstacle, nor beyond
#: this many parts: what is left keeps its MAR (see :func:`split_parts`).
PARTS_MIN_SHARE = 0.02
PARTS_MAX = 16
#: Cut positions tried along each direction (equally spaced, ends excluded).
PARTS_CUTS = 15


def check_obstacle_model(model: Any) -> str:
    """``model`` if it names an obstacle model; InputError otherwise."""
    if model not in OBSTACLE_MODELS:
        raise InputError(f"obstacle_model: expected one of {', '.join(OBSTACLE_MODELS)}, got {model!r}")
    return model

if TYPE_CHECKING:
    from .grid import Grid


@dataclass(frozen=True, eq=False)
class Obstacle:
    """One obstacle. Pixel arrays are ``(x, y)``; metric ones world ``(x, y)`` metres, y up."""

    id: int
    cells: list[tuple[int, int]]
    outline_px: np.ndarray  # (K, 2)
    mar_px: np.ndarray  # (4, 2)
    outline_m: np.ndarray | None = None
    mar_m: np.ndarray | None = None
    #: the ``parts`` model's rectangles, (4, 2) each: fitted in metres when there is a world frame
    #: (the planner's geometry) and drawn in pixels through it
    parts_px: list[np.ndarray] = field(default_factory=list)
    parts_m: list[np.ndarray] | None = None

    def polygons_m(self, model: str = DEFAULT_OBSTACLE_MODEL) -> list[np.ndarray]:
        """The polygons (K, 2) world metres that stand for this obstacle under ``model``."""
        check_obstacle_model(model)
        if self.outline_m is None:
            raise InputError(f"obstacle {self.id}: no world frame (metric outlines) to plan on")
        if model == "mar" and self.mar_m is not None:
            return [self.mar_m]
        if model == "outline":
            return [self.outline_m]
        if model == "parts" and self.parts_m is not None:
            return list(self.parts_m)
        raise InputError(f"obstacle {self.id}: no {model} polygons in the world frame to plan on")

    def polygons_px(self, model: str = DEFAULT_OBSTACLE_MODEL) -> list[np.ndarray]:
        """The same in image pixels (the metric ones drawn through the grid, when there are some)."""
        check_obstacle_model(model)
        if model == "mar":
            return [self.mar_px]
        if model == "outline":
            return [self.outline_px]
        return list(self.parts_px)

    @property
    def centre_px(self) -> tuple[float, float]:
        c = self.mar_px.mean(axis=0)
        return float(c[0]), float(c[1])

    @staticmethod
    def _size_angle(rect: np.ndarray) -> tuple[float, float, float]:
        e1, e2 = rect[1] - rect[0], rect[2] - rect[1]
        l1, l2 = float(np.hypot(*e1)), float(np.hypot(*e2))
        long_edge = e1 if l1 >= l2 else e2
        angle = float(np.degrees(np.arctan2(long_edge[1], long_edge[0])))
        return max(l1, l2), min(l1, l2), axis_angle(angle, 3)

    def to_json(self) -> dict:
        length, width, angle = self._size_angle(self.mar_px)
        out = {
            "id": self.id,
            "cells": [list(c) for c in self.cells],
            "outline_px": np.round(self.outline_px, 3).tolist(),
            "mar_px": np.round(self.mar_px, 3).tolist(),
            "parts_px": [np.round(p, 3).tolist() for p in self.parts_px],
            "centre_px": [round(v, 3) for v in self.centre_px],
            "size_px": [round(length, 3), round(width, 3)],
            "angle_px_deg": round(angle, 3),
        }
        if self.mar_m is not None and self.outline_m is not None:
            length_m, width_m, angle_m = self._size_angle(self.mar_m)
            out.update({
                "outline_m": np.round(self.outline_m, 6).tolist(),
                "mar_m": np.round(self.mar_m, 6).tolist(),
                "parts_m": [np.round(p, 6).tolist() for p in (self.parts_m or [])],
                "centre_m": np.round(self.mar_m.mean(axis=0), 6).tolist(),
                "size_m": [round(length_m, 6), round(width_m, 6)],
                "angle_m_deg": round(angle_m, 3),
            })
        return out


def json_polygons_m(obstacle: dict, model: str) -> list[np.ndarray]:
    """The polygons (K, 2) metres of one obstacle of a detection result's JSON (``obstacles[i]``)
    under ``model``: its ``mar_m``, ``outline_m`` or ``parts_m`` (results written before parts
    existed: cut from ``outline_m`` here, as detection would have). KeyError when a key is missing."""
    check_obstacle_model(model)
    if model == "mar":
        return [np.asarray(obstacle["mar_m"], dtype=np.float64)]
    if model == "outline":
        return [np.asarray(obstacle["outline_m"], dtype=np.float64)]
    if "parts_m" in obstacle:
        return [np.asarray(p, dtype=np.float64) for p in obstacle["parts_m"]]
    return split_parts(np.asarray(obstacle["outline_m"], dtype=np.float64))


def axis_angle(degrees: float, decimals: int) -> float:
    """A direction without sense, in (-90, 90] degrees, rounded: a vertical side is always 90,
    never -90, and never -0.0."""
    angle = round(float(degrees), decimals)
    return 90.0 - (90.0 - angle) % 180.0 + 0.0


def mar_opencv(points: np.ndarray) -> np.ndarray:
    """Minimum-area rectangle of a point set by OpenCV: its 4 corners (4, 2), in boundary order.

    Built from ``cv2.boxPoints`` (not from the angle, whose range and width/height swap depend on
    OpenCV's version and the orientation).
    """
    return _box_points(as_points(points, name="points", min_points=1).astype(np.float32))


def _box_points(pts: np.ndarray) -> np.ndarray:
    """mar_opencv on checked points, float32 (K, 2)."""
    return cv2.boxPoints(cv2.minAreaRect(pts)).astype(np.float64)


def mar_shapely(points: np.ndarray) -> np.ndarray:
    """Minimum-area rectangle by shapely (``minimum_rotated_rectangle``): corners (4, 2)."""
    pts = as_points(points, name="points", min_points=1)
    rect = shapely.minimum_rotated_rectangle(shapely.MultiPoint(pts))
    coords = np.asarray(rect.exterior.coords)[:-1] if isinstance(rect, shapely.Polygon) else np.asarray(rect.coords)
    if len(coords) < 4:  # degenerate (a segment): repeat points to keep the (4, 2) shape
        coords = np.resize(coords, (4, 2))
    return coords


def find_obstacles(occupancy: np.ndarray, occupied: np.ndarray, grid, *, to_world=None,
                   to_pixels=None) -> list[Obstacle]:
    """The connected black regions of an occupancy image as obstacles (the ``cells`` footprint):
    :func:`obstacles_from_outlines` of :func:`~sbplan.detection.footprints.cell_outlines`.

    Parameters
    ----------
    occupancy : ndarray of shape (H, W), uint8
        0 where occupied, 255 elsewhere.
    occupied, grid, to_world, to_pixels : as :func:`obstacles_from_outlines`.
    """
    from .footprints import cell_outlines

    return obstacles_from_outlines(cell_outlines(occupancy, occupied, grid), occupied, grid, to_world=to_world,
                                   to_pixels=to_pixels)


def obstacles_from_outlines(outlines: Sequence[np.ndarray], occupied: np.ndarray, grid, *,
                            to_world: Callable | None = None, to_pixels: Callable | None = None) -> list[Obstacle]:
    """Obstacles from their outlines: each gets the occupied cells it holds, its MAR and its parts.

    An occupied cell belongs to the outline that holds its centre, or comes nearest to it within
    half a pitch (a refined outline may cover only the part of a cell its obstacle hides). An
    occupied cell no outline reaches becomes an obstacle of its own, outlined by its cell
    (merged with any outline it overlaps): the cells stay the decision of where obstacles are.

    Parameters
    ----------
    outlines : sequence of ndarray (K, 2)
        Closed outlines ``(x, y)`` in image pixels.
    occupied : ndarray of shape (rows, cols), bool
        The occupied cells (to list each obstacle's cells).
    grid : sbplan.detection.grid.Grid
    to_world : callable, optional
        Maps pixel points (N, 2) to world metres (N, 2); when given, metric outlines, MARs and
        parts are added (the metric MAR is fitted to the metric outline, so it is a true rectangle
        on the floor even under perspective; the parts are cut in metres, where the planner works).
    to_pixels : callable, optional
        The inverse of ``to_world``: the metric parts drawn in pixels. Without it (or without
        ``to_world``) the parts are cut in pixels.

    Returns
    -------
    list of Obstacle, numbered from 1 in reading order of their top-left cell.
    """
    rows, cols = np.nonzero(occupied)
    outlines = [as_points(o, name=f"outlines[{i}]", min_points=3) for i, o in enumerate(outlines)]
    centres = grid.centres_px[rows, cols].astype(np.float32)
    reach = 0.5 * float(min(grid.pitch_px))
    owner = np.full(len(rows), -1, np.int64)
    if outlines and len(rows):
        contours = [np.ascontiguousarray(o, dtype=np.float32).reshape(-1, 1, 2) for o in outlines]
        # signed distances of every occupied cell's centre to every outline (inside positive);
        # a few point tests are far cheaper than labelling every pixel of the image
        dist = np.array([[cv2.pointPolygonTest(c, (float(x), float(y)), True) for c in contours]
                         for x, y in centres]).reshape(len(rows), len(contours))
        best = dist.argmax(axis=1)
        owner = np.where(dist[np.arange(len(rows)), best] >= -reach, best, -1)
    if (owner < 0).any():
        outlines, owner = _with_cells(outlines, owner, rows, cols, grid)
    found = []
    h = w = 1 << 30
    for k, outline in enumerate(outlines):
        cells = sorted((int(rows[i]), int(cols[i])) for i in np.flatnonzero(owner == k))
        mar = mar_opencv(outline)
        outline_m = mar_m = parts_m = None
        if to_world is not None:
            outline_m = to_world(outline)
            mar_m = mar_opencv(outline_m)
            parts_m = split_parts(outline_m)
            parts_px = [to_pixels(p) for p in parts_m] if to_pixels is not None else split_parts(outline)
        else:
            parts_px = split_parts(outline)
        found.append((cells[0] if cells else (h, w), cells, outline, mar, outline_m, mar_m, parts_px, parts_m))
    found.sort(key=lambda t: t[0])
    return [Obstacle(i + 1, cells, outline, mar, om, mm, pp, pm)
            for i, (_, cells, outline, mar, om, mm, pp, pm) in enumerate(found)]


def _with_cells(outlines: list[np.ndarray], owner: np.ndarray, rows: np.ndarray, cols: np.ndarray,
                grid) -> tuple[list[np.ndarray], np.ndarray]:
    """``outlines`` with the cells of the occupied cells no outline reached (``owner`` -1) added,
    merged with whatever they overlap; the cells' owners again."""
    corners = grid.cell_corners_px()
    lonely = np.flatnonzero(owner < 0)
    quads = [Polygon(np.array([corners[r, c], corners[r, c + 1], corners[r + 1, c + 1], corners[r + 1, c]]))
             for r, c in zip(rows[lonely], cols[lonely])]
    union = shapely.union_all([Polygon(o).buffer(0) for o in outlines] + quads)
    parts = [g for g in getattr(union, "geoms", [union]) if isinstance(g, Polygon) and g.area > 0]
    merged = [np.asarray(g.exterior.coords)[:-1] for g in parts]
    shapely.prepare(parts)
    new_owner = np.full(len(rows), -1, np.int64)
    for i, (r, c) in enumerate(zip(rows, cols)):
        # the cell's own centre, or the one piece that covers it most
        centre = shapely.Point(grid.centres_px[r, c])
        hit = [k for k, g in enumerate(parts) if g.covers(centre)]
        if not hit:
            q = Polygon(np.array([corners[r, c], corners[r, c + 1], corners[r + 1, c + 1], corners[r + 1, c]]))
            hit = [int(np.argmax([g.intersection(q).area for g in parts]))]
        new_owner[i] = hit[0]
    return merged, new_owner


def split_parts(outline: np.ndarray, *, ratio: float = PARTS_RATIO, min_share: float = PARTS_MIN_SHARE,
                max_parts: int = PARTS_MAX) -> list[np.ndarray]:
    """The ``parts`` model of one outline: rectangles, each within ``ratio`` of its part's area.

    The outline's MAR when it covers at most ``ratio`` times the outline's area; otherwise the
    outline is cut by the straight line (across its MAR's sides or the axes, at one of
    :data:`PARTS_CUTS` positions) that makes its pieces' MARs smallest, and each piece is treated
    the same way. A piece smaller than ``min_share`` of the outline, or the pieces left once
    ``max_parts`` are made, keep their MARs whatever the ratio. Every rectangle holds its piece, so
    the rectangles together hold the outline.

    Parameters
    ----------
    outline : ndarray (K, 2)
        A closed outline ``(x, y)`` (metres or pixels).

    Returns
    -------
    list of ndarray (4, 2)
        Rectangles' corners, in boundary order.
    """
    pts = as_points(outline, name="outline", min_points=3)
    poly = shapely.make_valid(Polygon(pts))
    pieces = [g for g in _polygons(poly) if g.area > 0]
    total = sum(g.area for g in pieces)
    if total <= 0:
        return [mar_opencv(pts)]
    done: list[np.ndarray] = []
    todo = list(pieces)
    while todo:
        p = todo.pop()
        coords = np.asarray(p.exterior.coords)[:-1]
        rect = mar_opencv(coords)
        fits = _area(rect) <= ratio * p.area
        if fits or p.area < min_share * total or len(done) + len(todo) + 2 > max_parts:
            done.append(rect)
            continue
        cut = _best_cut(p, rect)
        if cut is None:
            done.append(rect)
        else:
            todo.extend(cut)
    return done


def _polygons(geom) -> list[Polygon]:
    return [g for g in getattr(geom, "geoms", [geom]) if isinstance(g, Polygon)] if not isinstance(geom, Polygon) \
        else [geom]


def _area(rect: np.ndarray) -> float:
    """A polygon's area (shoelace) from its corners (K, 2): plain Python, since the cut search
    takes it of a few hundred 4-corner rectangles per outline (two np.roll each cost more than
    the MARs)."""
    pts = rect.tolist()
    total = 0.0
    for (xa, ya), (xb, yb) in zip(pts, pts[1:] + pts[:1]):
        total += xa * yb - ya * xb
    return 0.5 * abs(total)


#: shapely's clip_by_rect ufunc (its compiled module's), which broadcasts the bounds; None where
#: a shapely version does not have it
_CLIP_UFUNC = getattr(getattr(shapely, "lib", None), "clip_by_rect", None)


def _clip_all(q: Polygon, xmin, ymin, xmax, ymax) -> np.ndarray:
    """``shapely.clip_by_rect`` of ``q`` by every rectangle the bounds give (one of them an array,
    the others numbers): an array of geometries. Shapely's ufunc takes arrays of bounds in one
    call (the cut search makes 30 clips per direction: 3 us each that way, 6 through the scalar
    wrapper, whose own checks refuse arrays, shapely issue #1331); the wrapper per rectangle where
    the ufunc is not there."""
    if _CLIP_UFUNC is not None:
        try:
            return np.asarray(_CLIP_UFUNC(q, xmin, ymin, xmax, ymax), dtype=object)
        except TypeError:
            pass
    bounds = np.broadcast_arrays(*(np.asarray(v, np.float64) for v in (xmin, ymin, xmax, ymax)))
    out = np.empty(bounds[0].shape, dtype=object)
    for k, b in enumerate(zip(*bounds)):
        out[k] = shapely.clip_by_rect(q, *map(float, b))
    return out


def _cuts(q: Polygon) -> list[tuple[list[Polygon], float]]:
    """Every vertical cut of ``q`` at :data:`PARTS_CUTS` abscissas equally spaced across it (ends
    excluded): its pieces of non-zero area (the left side's, then the right side's, each in the
    order their collection lists them) and the sum of their MARs' areas (:func:`mar_opencv`'s
    rectangles, :func:`_area`'s shoelace), in that order. A few shapely calls per direction, not a
    few per piece."""
    x0, y0, x1, y1 = q.bounds
    pad = 1.0 + (x1 - x0) + (y1 - y0)
    ts = np.linspace(x0, x1, PARTS_CUTS + 2)[1:-1]
    n = len(ts)
    sides = np.concatenate([_clip_all(q, x0 - pad, y0 - pad, ts, y1 + pad),
                            _clip_all(q, ts, y0 - pad, x1 + pad, y1 + pad)])
    parts, owner = shapely.get_parts(sides, return_index=True)
    keep = (shapely.get_type_id(parts) == shapely.GeometryType.POLYGON) & (shapely.area(parts) > 0)
    parts, owner = parts[keep], owner[keep]
    coords, ring = shapely.get_coordinates(shapely.get_exterior_ring(parts), return_index=True)
    ends = np.searchsorted(ring, np.arange(1, len(parts) + 1))
    starts = np.r_[0, ends[:-1]]
    # each piece's MAR (its ring's points less the closing one), and their areas in one go: the
    # shoelace over 4 corners sums in the order _area does, so the areas are _area's
    points = coords.astype(np.float32)
    boxes = np.array([cv2.boxPoints(cv2.minAreaRect(points[a:b - 1]))
                      for a, b in zip(starts.tolist(), ends.tolist())], np.float64).reshape(-1, 4, 2)
    x, y = boxes[..., 0], boxes[..., 1]
    areas = (0.5 * np.abs((x * np.roll(y, -1, axis=1) - y * np.roll(x, -1, axis=1)).sum(axis=1))).tolist()
    # the pieces of cut k: those of side k (left), then of side n + k (right); get_parts keeps
    # the sides' order
    by_side: list[list[int]] = [[] for _ in range(2 * n)]
    for i, side in enumerate(owner.tolist()):
        by_side[side].append(i)
    out = []
    for k in range(n):
        idx = by_side[k] + by_side[n + k]
        out.append(([parts[i] for i in idx], sum(areas[i] for i in idx)))
    return out


def _best_cut(p: Polygon, rect: np.ndarray) -> list[Polygon] | None:
    """The straight cut of ``p`` whose pieces' MARs cover the least area, if it beats ``rect``:
    cuts across the MAR's sides and across the axes, at :data:`PARTS_CUTS` positions each."""
    e = rect[1] - rect[0]
    side = float(np.degrees(np.arctan2(e[1], e[0]))) % 90.0
    best, best_cost, best_angle = None, _area(rect), 0.0
    for angle in dict.fromkeys((side, 0.0)):  # MAR sides first; the axes when they differ
        # turn the cut's direction onto the y axis and cut with vertical lines (both sides of the
        # rectangle: x and y after turning by angle and angle + 90)
        for turn in (angle, angle + 90.0):
            for pieces, cost in _cuts(shapely.affinity.rotate(p, -turn, origin=(0, 0))):
                if len(pieces) < 2:
                    continue
                if cost < best_cost * (1 - 1e-9):
                    best, best_cost, best_angle = pieces, cost, turn
        if best is not None and best_cost <= PARTS_RATIO * p.area:
            break  # a cut across the MAR's sides that does it: the axes are not needed
    if best is None:
        return None
    return [shapely.affinity.rotate(g, best_angle, origin=(0, 0)) for g in best]
