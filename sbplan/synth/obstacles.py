"""Obstacle outlines, their surface textures, and antialiased polygon coverage."""

from __future__ import annotations

import math

import cv2
import numpy as np

#: Supersampling factor of polygon coverage (antialiasing).
SS = 4


def coverage(polys: list[list[np.ndarray]], x0: int, y0: int, w: int, h: int, *, ss: int = SS) -> np.ndarray:
    """Antialiased coverage of polygons (each ``[outline, *holes]``) over a pixel window.

    Parameters
    ----------
    polys : list of list of ndarray (N, 2)
        Polygons in image pixels ``(x, y)``; pixel ``(col, row)`` covers ``[col - 0.5, col + 0.5]``.
    x0, y0, w, h : int
        The window: columns ``x0 .. x0 + w - 1``, rows ``y0 .. y0 + h - 1``.

    Returns
    -------
    ndarray (h, w) float32 in [0, 1]
        Fraction of each pixel inside the polygons (ss x ss supersampling; holes by even-odd fill).
    """
    canvas = np.zeros((h * ss, w * ss), np.uint8)
    shift = 4
    for rings in polys:
        pts = [np.round((((r - (x0, y0)) + 0.5) * ss - 0.5) * (1 << shift)).astype(np.int32) for r in rings]
        cv2.fillPoly(canvas, pts, 255, lineType=cv2.LINE_8, shift=shift)
    small = cv2.resize(canvas, (w, h), interpolation=cv2.INTER_AREA)
    return small.astype(np.float32) / 255.0


def window(points: np.ndarray, width: int, height: int, pad: int = 2) -> tuple[int, int, int, int] | None:
    """Integer pixel window ``(x0, y0, w, h)`` holding ``points`` (clipped to the image), or None."""
    x0 = max(int(math.floor(points[:, 0].min())) - pad, 0)
    y0 = max(int(math.floor(points[:, 1].min())) - pad, 0)
    x1 = min(int(math.ceil(points[:, 0].max())) + pad + 1, width)
    y1 = min(int(math.ceil(points[:, 1].max())) + pad + 1, height)
    if x1 <= x0 or y1 <= y0:
        return None
    return x0, y0, x1 - x0, y1 - y0


def outline(kind: str, centre: np.ndarray, size: float, rng: np.random.Generator) -> np.ndarray:
    """A random obstacle outline ``(K, 2)`` ``(x, y)``, counter-clockwise as displayed.

    ``box``: rotated rectangle with longer side ``size``; ``cylinder``: disc of diameter ``size``
    (a cylinder seen from above); ``blob``: star-shaped irregular outline of mean diameter ``size``.
    """
    if kind == "box":
        w, h = size, size * rng.uniform(0.45, 1.0)
        a = rng.uniform(0, math.pi)
        pts = np.array([[-w, -h], [-w, h], [w, h], [w, -h]]) / 2.0
    elif kind == "cylinder":
        t = np.linspace(0, 2 * math.pi, 72, endpoint=False)
        pts, a = np.c_[np.cos(t), -np.sin(t)] * size / 2.0, 0.0
    else:
        t = np.linspace(0, 2 * math.pi, 60, endpoint=False)
        r = np.ones_like(t)
        for k in (2, 3, 4, 5):
            r += rng.uniform(0, 0.32 / k) * np.cos(k * t + rng.uniform(0, 2 * math.pi))
        pts, a = np.c_[r * np.cos(t), -r * np.sin(t)] * size / 2.0, 0.0
    rot = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
    return pts @ rot.T + centre


def texture(kind: str, name: str, shape: tuple[int, int], centre_xy: np.ndarray, size: float,
            rng: np.random.Generator, *, contrast: float = 1.0) -> np.ndarray:
    """A surface texture (grey levels, float32, shape ``(h, w)``) for an obstacle's window.

    ``centre_xy`` is the obstacle's centre in window coordinates. Textures are noise, stripes,
    gradients or printed-label-like rectangles with text bars: nothing shaped like a symbol.
    """
    h, w = shape
    base = rng.uniform(55, 215)
    amp = 22.0 * contrast
    ys, xs = np.mgrid[0:h, 0:w].astype(np.float32)
    out = np.full((h, w), base, np.float32)
    if name == "noise":
        small = rng.standard_normal((max(h // 12, 2), max(w // 12, 2))).astype(np.float32)
        out += amp * 0.8 * cv2.resize(small, (w, h), interpolation=cv2.INTER_CUBIC)
    elif name == "stripes":
        a = rng.uniform(0, math.pi)
        period = rng.uniform(5, 16)
        phase = (xs * math.cos(a) + ys * math.sin(a)) * (2 * math.pi / period)
        out += amp * np.tanh(2.5 * np.sin(phase))
    elif name == "gradient":
        a = rng.uniform(0, 2 * math.pi)
        ramp = ((xs - centre_xy[0]) * math.cos(a) + (ys - centre_xy[1]) * math.sin(a)) / max(size / 2, 1)
        out += 1.6 * amp * np.clip(ramp, -1, 1)
    else:  # labels: lighter rectangles with rows of dark "text" bars
        for _ in range(int(rng.integers(1, 3))):
            lw, lh = size * rng.uniform(0.25, 0.45), size * rng.uniform(0.15, 0.3)
            cx = centre_xy[0] + rng.uniform(-0.2, 0.2) * size
            cy = centre_xy[1] + rng.uniform(-0.2, 0.2) * size
            lx0, ly0 = int(cx - lw / 2), int(cy - lh / 2)
            lx1, ly1 = int(cx + lw / 2), int(cy + lh / 2)
            label = min(base + 2.5 * amp, 245)
            cv2.rectangle(out, (lx0, ly0), (lx1, ly1), float(label), -1, cv2.LINE_AA)
            y = ly0 + 4
            while y + 2 < ly1 - 2:
                bar = lx0 + 3 + int((lx1 - lx0 - 6) * rng.uniform(0.4, 0.95))
                cv2.line(out, (lx0 + 3, y), (bar, y), float(max(label - 3 * amp, 10)), 2, cv2.LINE_AA)
                y += 6
    if kind == "cylinder":
        # a lid seen from above: darker toward the rim, with a rim line
        r = np.hypot(xs - centre_xy[0], ys - centre_xy[1]) / max(size / 2, 1)
        out *= (1.0 - 0.25 * np.clip(r, 0, 1) ** 2)
        out -= 0.8 * amp * np.exp(-((r - 0.85) * size / 3.0) ** 2)
    out += rng.standard_normal((h, w), dtype=np.float32) * 2.0
    return np.clip(out, 5, 250)
