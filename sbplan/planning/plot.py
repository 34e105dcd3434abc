"""Drawing a route with OpenCV: obstacles, their enlargement, start, goal and route."""

from __future__ import annotations

from typing import Sequence

import cv2
import numpy as np


def draw_route(obstacles: Sequence, enlarged: Sequence, bounds: Sequence[float], *, route=None, start=None,
               goal=None, size: int = 800) -> np.ndarray:
    """Render a planning scene.

    Parameters
    ----------
    obstacles, enlarged : sequences of shapely Polygon, world ``(x, y)``, y up.
    bounds : (xmin, ymin, xmax, ymax), the area drawn.
    route : (M, 2) array ``(x, y)``, optional.
    size : int, the longer image side in pixels.

    Returns
    -------
    ndarray of shape (H, W, 3), uint8, BGR; y is flipped so that up is up.
    """
    x0, y0, x1, y1 = (float(v) for v in bounds)
    s = size / max(x1 - x0, y1 - y0)
    w, h = max(int(round((x1 - x0) * s)), 1), max(int(round((y1 - y0) * s)), 1)
    img = np.full((h, w, 3), 255, np.uint8)

    def px(pts):
        pts = np.asarray(pts, float)
        return np.round(np.c_[(pts[:, 0] - x0) * s, (y1 - pts[:, 1]) * s] * 16).astype(np.int32)

    def fill(polys, colour):
        for p in polys:
            cv2.fillPoly(img, [px(p.exterior.coords)], colour, cv2.LINE_AA, shift=4)
            for hole in p.interiors:
                cv2.fillPoly(img, [px(hole.coords)], (255, 255, 255), cv2.LINE_AA, shift=4)

    fill(enlarged, (200, 215, 245))  # light orange-ish: the clearance zone
    for p in enlarged:
        cv2.polylines(img, [px(p.exterior.coords)], True, (120, 150, 230), 1, cv2.LINE_AA, shift=4)
    fill(obstacles, (60, 60, 60))
    if route is not None and len(route) >= 2:
        cv2.polylines(img, [px(route)], False, (200, 80, 0), 2, cv2.LINE_AA, shift=4)
        for q in px(route)[1:-1]:
            cv2.circle(img, tuple(int(v) for v in q), 3 * 16, (200, 80, 0), -1, cv2.LINE_AA, shift=4)
    for pt, colour in ((start, (0, 170, 0)), (goal, (0, 0, 220))):
        if pt is not None:
            q = px(np.asarray(pt, float)[None])[0]
            cv2.circle(img, (int(q[0]), int(q[1])), 6 * 16, colour, -1, cv2.LINE_AA, shift=4)
    return img
