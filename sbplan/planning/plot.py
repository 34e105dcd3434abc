"""Drawing a route with OpenCV: obstacles, their enlargement, start, goal and route, with axes in
map units, a scale bar and a legend."""

from __future__ import annotations

import math
from typing import Sequence

import cv2
import numpy as np

# BGR
_OBSTACLE = (60, 60, 60)
_CLEARANCE = (200, 215, 245)
_CLEARANCE_EDGE = (120, 150, 230)
_ROUTE = (200, 80, 0)
_START = (0, 170, 0)
_GOAL = (0, 0, 220)
_INK = (40, 40, 40)
_FRAME = (150, 150, 150)
_GRID = (232, 232, 232)
_FONT = cv2.FONT_HERSHEY_SIMPLEX
#: Margins around the plot (pixels): tick labels at the left and below, the legend at the right.
_LEFT, _TOP, _BOTTOM, _LEGEND = 64, 34, 46, 176


def nice_step(span: float, *, target: int = 6) -> float:
    """A round tick step (1, 2 or 5 times a power of ten) giving about ``target`` ticks over ``span``."""
    if not span > 0:
        return 1.0
    raw = span / target
    power = 10 ** math.floor(math.log10(raw))
    return min((m * power for m in (1, 2, 5, 10)), key=lambda s: abs(math.log(s / raw)))


def _label(step: float, value: float) -> str:
    decimals = max(0, -math.floor(math.log10(step) + 1e-9))
    return f"{value:.{decimals}f}"


def _text(img: np.ndarray, text: str, org: tuple[int, int], *, scale: float = 0.45, colour=_INK,
          anchor: str = "left", halo: bool = False) -> None:
    """Text with its baseline at ``org``; ``anchor`` left, centre or right of ``org``; ``halo`` draws
    a white outline first, so that the text reads over any fill."""
    (tw, _), _ = cv2.getTextSize(text, _FONT, scale, 1)
    x = org[0] - (tw if anchor == "right" else tw // 2 if anchor == "centre" else 0)
    if halo:
        cv2.putText(img, text, (x, org[1]), _FONT, scale, (255, 255, 255), 4, cv2.LINE_AA)
    cv2.putText(img, text, (x, org[1]), _FONT, scale, colour, 1, cv2.LINE_AA)


def draw_route(obstacles: Sequence, enlarged: Sequence, bounds: Sequence[float], *, route=None, start=None,
               goal=None, size: int = 800, units: str = "m") -> np.ndarray:
    """Render a planning scene, with axes, a scale bar and a legend.

    Parameters
    ----------
    obstacles, enlarged : sequences of shapely Polygon, world ``(x, y)``, y up.
    bounds : (xmin, ymin, xmax, ymax), the area drawn.
    route : (M, 2) array ``(x, y)``, optional.
    start, goal : (x, y), optional; drawn as discs labelled "start" and "goal".
    size : int, the longer side of the plot area in pixels (the margins come on top).
    units : str, the map's unit, written on the axes and the scale bar ("m", or "px" for an
        occupancy image read without a resolution).

    Returns
    -------
    ndarray of shape (H, W, 3), uint8, BGR; y is flipped so that up is up. The plot area is
    ``size`` pixels on its longer side; axes with tick labels are at its left and below it, the
    legend and the scale bar at its right.
    """
    x0, y0, x1, y1 = (float(v) for v in bounds)
    s = size / max(x1 - x0, y1 - y0)
    w, h = max(int(round((x1 - x0) * s)), 1), max(int(round((y1 - y0) * s)), 1)
    img = np.full((_TOP + h + _BOTTOM, _LEFT + w + _LEGEND, 3), 255, np.uint8)
    ox, oy = _LEFT, _TOP  # the plot area's top-left corner in the image
    # drawn into a view of the plot area: what lies outside the bounds (clearance) is cut at its edge
    area = img[oy:oy + h + 1, ox:ox + w + 1]

    def px(pts):
        """World (x, y) -> plot-area pixels, 4 fractional bits."""
        pts = np.asarray(pts, float).reshape(-1, 2)
        return np.round(np.c_[(pts[:, 0] - x0) * s, (y1 - pts[:, 1]) * s] * 16).astype(np.int32)

    def fill(polys, colour):
        for p in polys:
            cv2.fillPoly(area, [px(p.exterior.coords)], colour, cv2.LINE_AA, shift=4)
            for hole in p.interiors:
                cv2.fillPoly(area, [px(hole.coords)], (255, 255, 255), cv2.LINE_AA, shift=4)

    # axes: light grid lines at round steps, tick labels in map units
    step = nice_step(max(x1 - x0, y1 - y0))
    xticks = np.arange(math.ceil(x0 / step) * step, x1 + 1e-9 * step, step)
    yticks = np.arange(math.ceil(y0 / step) * step, y1 + 1e-9 * step, step)
    for v in xticks:
        c = int(round(ox + (v - x0) * s))
        cv2.line(img, (c, oy), (c, oy + h), _GRID, 1)
    for v in yticks:
        r = int(round(oy + (y1 - v) * s))
        cv2.line(img, (ox, r), (ox + w, r), _GRID, 1)

    fill(enlarged, _CLEARANCE)
    for p in enlarged:
        cv2.polylines(area, [px(p.exterior.coords)], True, _CLEARANCE_EDGE, 1, cv2.LINE_AA, shift=4)
    fill(obstacles, _OBSTACLE)
    if route is not None and len(route) >= 2:
        cv2.polylines(area, [px(route)], False, _ROUTE, 2, cv2.LINE_AA, shift=4)
        for q in px(route)[1:-1]:
            cv2.circle(area, tuple(int(v) for v in q), 3 * 16, _ROUTE, -1, cv2.LINE_AA, shift=4)
    for pt, colour, name in ((start, _START, "start"), (goal, _GOAL, "goal")):
        if pt is not None:
            q = px(np.asarray(pt, float))[0]
            cv2.circle(area, (int(q[0]), int(q[1])), 6 * 16, colour, -1, cv2.LINE_AA, shift=4)
            c, r = ox + int(round(q[0] / 16)), oy + int(round(q[1] / 16))
            # the label on the side with more room
            right = c < ox + w - 60
            _text(img, name, (c + 10 if right else c - 10, r - 8), colour=colour, anchor="left" if right else "right",
                  scale=0.5, halo=True)

    # the frame and the ticks over everything drawn in the plot area
    cv2.rectangle(img, (ox, oy), (ox + w, oy + h), _FRAME, 1)
    for v in xticks:
        c = int(round(ox + (v - x0) * s))
        cv2.line(img, (c, oy + h), (c, oy + h + 5), _INK, 1)
        _text(img, _label(step, v), (c, oy + h + 20), anchor="centre")
    for v in yticks:
        r = int(round(oy + (y1 - v) * s))
        cv2.line(img, (ox - 5, r), (ox, r), _INK, 1)
        _text(img, _label(step, v), (ox - 8, r + 5), anchor="right")
    _text(img, f"x ({units})", (ox + w, oy + h + 40), anchor="right")
    _text(img, f"y ({units})", (ox - 8, oy - 12), anchor="right")

    # legend and scale bar at the right
    lx, ly = ox + w + 20, oy + 6
    entries = (("obstacle", "fill", _OBSTACLE), ("clearance (radius)", "clearance", _CLEARANCE),
               ("route", "line", _ROUTE), ("start", "disc", _START), ("goal", "disc", _GOAL))
    for k, (name, kind, colour) in enumerate(entries):
        cy = ly + 24 * k + 8
        if kind == "fill":
            cv2.rectangle(img, (lx, cy - 7), (lx + 22, cy + 7), colour, -1)
        elif kind == "clearance":
            cv2.rectangle(img, (lx, cy - 7), (lx + 22, cy + 7), colour, -1)
            cv2.rectangle(img, (lx, cy - 7), (lx + 22, cy + 7), _CLEARANCE_EDGE, 1)
        elif kind == "line":
            cv2.line(img, (lx, cy), (lx + 22, cy), colour, 2, cv2.LINE_AA)
            cv2.circle(img, (lx + 11, cy), 3, colour, -1, cv2.LINE_AA)
        else:
            cv2.circle(img, (lx + 11, cy), 6, colour, -1, cv2.LINE_AA)
        _text(img, name, (lx + 32, cy + 5))
    # the scale bar: the longest round length that fits the legend's width
    room = (_LEGEND - 40) / s
    length = 10 ** math.floor(math.log10(room))
    length = max((m * length for m in (1, 2, 5) if m * length <= room), default=length)
    bar = int(round(length * s))
    by = ly + 24 * len(entries) + 24
    cv2.line(img, (lx, by), (lx + bar, by), _INK, 2)
    for end in (lx, lx + bar):
        cv2.line(img, (end, by - 5), (end, by + 5), _INK, 1)
    _text(img, f"{_label(length, length)} {units}", (lx, by + 20))
    return img
