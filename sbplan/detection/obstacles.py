"""Obstacles from the occupancy image: connected black regions, their outlines and MARs.

Paper section 4.1: the occupancy image's black areas are the obstacles; their contours are
described as polygons and each gets its minimum-area rectangle (MAR).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Callable

import cv2
import numpy as np
import shapely

from ..contours import as_points

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
            "centre_px": [round(v, 3) for v in self.centre_px],
            "size_px": [round(length, 3), round(width, 3)],
            "angle_px_deg": round(angle, 3),
        }
        if self.mar_m is not None and self.outline_m is not None:
            length_m, width_m, angle_m = self._size_angle(self.mar_m)
            out.update({
                "outline_m": np.round(self.outline_m, 6).tolist(),
                "mar_m": np.round(self.mar_m, 6).tolist(),
                "centre_m": np.round(self.mar_m.mean(axis=0), 6).tolist(),
                "size_m": [round(length_m, 6), round(width_m, 6)],
                "angle_m_deg": round(angle_m, 3),
            })
        return out


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
    pts = as_points(points, name="points", min_points=1).astype(np.float32)
    return cv2.boxPoints(cv2.minAreaRect(pts)).astype(np.float64)


def mar_shapely(points: np.ndarray) -> np.ndarray:
    """Minimum-area rectangle by shapely (``minimum_rotated_rectangle``): corners (4, 2)."""
    pts = as_points(points, name="points", min_points=1)
    rect = shapely.minimum_rotated_rectangle(shapely.MultiPoint(pts))
    coords = np.asarray(rect.exterior.coords)[:-1] if isinstance(rect, shapely.Polygon) else np.asarray(rect.coords)
    if len(coords) < 4:  # degenerate (a segment): repeat points to keep the (4, 2) shape
        coords = np.resize(coords, (4, 2))
    return coords


def _black_regions(occupancy: np.ndarray, occupied: np.ndarray, grid: Grid) -> list[np.ndarray]:
    """The outer contours of the occupancy image's black regions (OpenCV's, in image pixels).

    The black regions lie around the occupied cells: each group of touching occupied cells is
    traced in its own box (the group's cells a cell wider all round), not the whole image (on a 4K
    frame, tracing the whole image cost ten times the rest of the step). A mapper may draw past
    its cells (blocks): where black reaches the border of a box, the whole image is traced.
    """
    h, w = occupancy.shape
    if not occupied.any():
        return []
    n, labels = cv2.connectedComponents(occupied.astype(np.uint8), connectivity=8)
    corners = grid.cell_corners_px()
    contours: list[np.ndarray] = []
    for label in range(1, n):
        rows, cols = np.nonzero(labels == label)
        r0, r1 = max(int(rows.min()) - 1, 0), min(int(rows.max()) + 2, grid.rows)
        c0, c1 = max(int(cols.min()) - 1, 0), min(int(cols.max()) + 2, grid.cols)
        pts = corners[r0:r1 + 1, c0:c1 + 1].reshape(-1, 2)
        x0, y0 = (max(int(v), 0) for v in np.floor(pts.min(axis=0)) - 2)
        x1, y1 = int(min(np.ceil(pts[:, 0].max()) + 3, w)), int(min(np.ceil(pts[:, 1].max()) + 3, h))
        mask = (occupancy[y0:y1, x0:x1] == 0).astype(np.uint8)
        edge = (x0 > 0 and mask[:, 0].any()) or (y0 > 0 and mask[0].any()) or \
               (x1 < w and mask[:, -1].any()) or (y1 < h and mask[-1].any())
        if edge:
            break
        found, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE, offset=(x0, y0))
        contours.extend(found)
    else:
        return contours
    mask = (occupancy == 0).astype(np.uint8)
    return list(cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)[0])


def find_obstacles(occupancy: np.ndarray, occupied: np.ndarray, grid: Grid, *,
                   to_world: Callable[[np.ndarray], np.ndarray] | None = None) -> list[Obstacle]:
    """The connected black regions of an occupancy image as obstacles.

    Parameters
    ----------
    occupancy : ndarray of shape (H, W), uint8
        0 where occupied, 255 elsewhere.
    occupied : ndarray of shape (rows, cols), bool
        The occupied cells (to list each obstacle's cells).
    grid : sbplan.detection.grid.Grid
    to_world : callable, optional
        Maps pixel points (N, 2) to world metres (N, 2); when given, metric outlines and MARs are
        added (the metric MAR is fitted to the metric outline, so it is a true rectangle on the floor
        even under perspective).

    Returns
    -------
    list of Obstacle, numbered from 1 in reading order of their top-left cell.
    """
    h, w = occupancy.shape
    contours = _black_regions(occupancy, occupied, grid)
    if not contours:
        return []
    rows, cols = np.nonzero(occupied)
    centres = grid.centres_px[rows, cols].astype(np.float32)
    unclaimed = np.ones(len(rows), bool)
    found = []
    for contour in contours:
        outline = contour[:, 0, :].astype(np.float64)
        # an occupied cell belongs to the region whose outline encloses its centre; a few point
        # tests are far cheaper than labelling every pixel of the image
        mine = [i for i in np.flatnonzero(unclaimed)
                if cv2.pointPolygonTest(contour, (float(centres[i, 0]), float(centres[i, 1])), False) >= 0]
        unclaimed[mine] = False
        cells = sorted((int(rows[i]), int(cols[i])) for i in mine)
        mar = mar_opencv(outline)
        outline_m = mar_m = None
        if to_world is not None:
            outline_m = to_world(outline)
            mar_m = mar_opencv(outline_m)
        found.append((cells[0] if cells else (h, w), cells, outline, mar, outline_m, mar_m))
    found.sort(key=lambda t: t[0])
    return [Obstacle(i + 1, cells, outline, mar, om, mm) for i, (_, cells, outline, mar, om, mm) in enumerate(found)]
