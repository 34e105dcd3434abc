"""Douglas–Peucker over a whole frame's contours in one compiled loop (numba).

A frame has a few dozen symbol contours of ~200 pixels; ``cv2.approxPolyDP`` on each costs a
Python call and an output array apiece, more than the approximation itself. This kernel takes the
same steps as OpenCV's closed-curve approximation on integer points, in the same order and with
the same comparisons (the farthest-point start found in three passes, the split stack, the
final pass that drops near-collinear vertices), so it returns OpenCV's vertices: the tests
compare the two on real and random contours. Imported on first use (numba takes a moment; see
``sbplan.detection._kernels``).
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def _squared_lengths(xs, ys, sx, sy, best):  # pragma: no cover - compiled
    """The largest squared distance of the points (xs, ys) from (sx, sy), and the first point at
    that distance, or -1 when none lies beyond ``best``. (Two passes: the first, a plain maximum
    over slices indexed from 0, runs in vector registers.)"""
    m = best
    for t in range(xs.shape[0]):
        dx = xs[t] - sx
        dy = ys[t] - sy
        m = max(m, dx * dx + dy * dy)
    if m <= best:
        return best, -1
    for t in range(xs.shape[0]):
        dx = xs[t] - sx
        dy = ys[t] - sy
        if dx * dx + dy * dy == m:
            return m, t
    return best, -1


@njit(cache=True, nogil=True)
def _segment_distances(xs, ys, ax, ay, dx, dy, seg, best):  # pragma: no cover - compiled
    """The largest squared distance of the points (xs, ys) from the segment from (ax, ay) by
    (dx, dy), times its squared length ``seg`` (whole numbers, exact), and the first point at that
    distance, or -1 when none lies beyond ``best``."""
    m = best
    for t in range(xs.shape[0]):
        m = max(m, _to_segment(xs[t] - ax, ys[t] - ay, dx, dy, seg))
    if m <= best:
        return best, -1
    for t in range(xs.shape[0]):
        if _to_segment(xs[t] - ax, ys[t] - ay, dx, dy, seg) == m:
            return m, t
    return best, -1


@njit(inline="always")
def _to_segment(px, py, dx, dy, seg):  # pragma: no cover - compiled
    along = px * dx + py * dy
    if along <= 0:
        return (px * px + py * py) * seg
    if along >= seg:
        qx = px - dx
        qy = py - dy
        return (qx * qx + qy * qy) * seg
    c = py * dx - px * dy
    return c * c


@njit(cache=True, nogil=True)
def _closed(xs, ys, eps2, out, stack):  # pragma: no cover - compiled
    """Approximate the closed contour (xs, ys) (int64) into ``out`` (int32 (n, 2)); returns the
    vertex count. ``eps2`` is the tolerance squared; ``stack`` holds ``2 * n`` ints. Distances
    are compared as exact whole numbers (squared, and times the chord's squared length), as
    OpenCV's doubles hold them exactly at image coordinates; the first point of the largest
    distance in the contour's order is taken, as OpenCV takes it."""
    n = xs.shape[0]
    # 1. about the two farthest points: the farthest from point 0, then the farthest from that
    #    one, then from that one again (OpenCV's three passes)
    start = 0
    far = 0
    max_d = 0
    for _ in range(3):
        start += far
        if start >= n:
            start -= n
        sx, sy = xs[start], ys[start]
        # the points after ``start`` in the contour's order, then the ones before it
        max_d, t = _squared_lengths(xs[start + 1:], ys[start + 1:], sx, sy, 0)
        far = t + 1 if t >= 0 else 0
        max_d, t = _squared_lengths(xs[:start], ys[:start], sx, sy, max_d)
        if t >= 0:
            far = n - start + t
    written = 0
    top = 0
    if float(max_d) <= eps2:
        out[0, 0], out[0, 1] = xs[start], ys[start]
        written = 1
    else:
        end = far + start
        if end >= n:
            end -= n
        # the second half is pushed first, so the first half (start -> end) is split first
        stack[0], stack[1] = end, start
        stack[2], stack[3] = start, end
        top = 2
    # 2. split each slice at its point farthest from the chord until all lie within eps
    while top > 0:
        top -= 1
        a, b = stack[2 * top], stack[2 * top + 1]
        ax, ay = xs[a], ys[a]
        dx, dy = xs[b] - ax, ys[b] - ay
        seg = dx * dx + dy * dy
        split = -1
        if a < b:
            max_d, t = _segment_distances(xs[a + 1:b], ys[a + 1:b], ax, ay, dx, dy, seg, 0)
            if t >= 0:
                split = a + 1 + t
        else:
            max_d, t = _segment_distances(xs[a + 1:], ys[a + 1:], ax, ay, dx, dy, seg, 0)
            if t >= 0:
                split = a + 1 + t
            max_d, t = _segment_distances(xs[:b], ys[:b], ax, ay, dx, dy, seg, max_d)
            if t >= 0:
                split = t
        if split < 0 or float(max_d) <= eps2 * float(seg):
            out[written, 0], out[written, 1] = ax, ay
            written += 1
        else:
            stack[2 * top], stack[2 * top + 1] = split, b
            stack[2 * top + 2], stack[2 * top + 3] = a, split
            top += 2
    # 3. drop vertices on [almost] straight lines, in place, as OpenCV's last pass does (its
    #    reads wrap around the list it is rewriting, so the order of reads and writes matters)
    count = written
    kept = written
    sx, sy = out[count - 1, 0], out[count - 1, 1]
    wpos = 0
    px, py = out[0, 0], out[0, 1]
    rpos = 1 % count
    i = 0
    while i < count and kept > 2:
        ex, ey = out[rpos, 0], out[rpos, 1]
        rpos = rpos + 1 if rpos + 1 < count else 0
        fdx = float(ex - sx)
        fdy = float(ey - sy)
        d = abs(float(px - sx) * fdy - float(py - sy) * fdx)
        inner = float(px - sx) * float(ex - px) + float(py - sy) * float(ey - py)
        if d * d <= 0.5 * eps2 * (fdx * fdx + fdy * fdy) and fdx != 0 and fdy != 0 and inner >= 0:
            kept -= 1
            out[wpos, 0], out[wpos, 1] = ex, ey
            sx, sy = ex, ey
            wpos = wpos + 1 if wpos + 1 < count else 0
            px, py = out[rpos, 0], out[rpos, 1]
            rpos = rpos + 1 if rpos + 1 < count else 0
            i += 2
            continue
        out[wpos, 0], out[wpos, 1] = px, py
        sx, sy = px, py
        wpos = wpos + 1 if wpos + 1 < count else 0
        px, py = ex, ey
        i += 1
    return kept


@njit(cache=True, nogil=True)
def douglas_peucker(pts, starts, eps2):  # pragma: no cover - compiled
    """Approximate every closed contour ``pts[starts[k]:starts[k + 1]]`` (int32 (N, 2), (x, y)).

    Returns ``(vertices, counts)``: the polygons' vertices packed in order, int32 (V, 2), and the
    vertex count of each contour, int64 (K,)."""
    k_all = starts.shape[0] - 1
    out = np.empty_like(pts)
    counts = np.zeros(k_all, np.int64)
    # the coordinates apart and wide: the distance loops read contiguous whole numbers
    xs = np.empty(pts.shape[0], np.int64)
    ys = np.empty(pts.shape[0], np.int64)
    for i in range(pts.shape[0]):
        xs[i] = pts[i, 0]
        ys[i] = pts[i, 1]
    longest = 1
    for k in range(k_all):
        longest = max(longest, starts[k + 1] - starts[k])
    stack = np.empty(2 * longest + 4, np.int64)
    total = 0
    for k in range(k_all):
        lo, hi = starts[k], starts[k + 1]
        if hi == lo:
            continue
        c = _closed(xs[lo:hi], ys[lo:hi], eps2, out[total:], stack)
        counts[k] = c
        total += c
    return out[:total], counts
