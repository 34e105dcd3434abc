"""Detection's compiled inner loops (numba).

Every frame runs a few per-pixel reductions over small windows (a symbol's square, two dozen of
them per frame). As numpy expressions each is a chain of whole-array passes and temporaries; the
frame's budget (issue 14: 2.5 ms at 1280x960 on one core) has no room for that. Here each is one
loop that reads every pixel once.

Imported on first use only (numba takes a moment to import, and a kernel to compile the first time
a machine runs it; ``cache=True`` keeps the compiled code beside this file, or in the user's cache
when that is not writable), so that commands that do not detect stay quick to start.

The callers validate their inputs; the kernels trust them: C-contiguous arrays of the dtypes
named, finite coordinates.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

# The sums below may be reordered (fastmath): they are sums of finite float32 terms, and the order
# changes their last bits only. That is what lets the inner loop run four or eight pixels at a time.


@njit(cache=True, nogil=True, fastmath=True)
def grey_centres(gray, corners, side, floor_share, out):  # pragma: no cover - compiled
    """The centre of darkness of the ``side`` x ``side`` squares at ``corners`` (n, 2) int64 ``(x, y)``
    of ``gray`` (H, W) uint8, written to ``out`` (n, 2) float64 (NaN where the square has no
    darkness). See :func:`sbplan.detection.registration.grey_centres` for the model; the arithmetic
    is its, in float32 as there, with the moments summed per row."""
    half = np.float32((side - 1) / 2)
    across = np.float32(1.0 / (side - 1))
    zero = np.float32(0.0)
    for k in range(corners.shape[0]):
        x0 = corners[k, 0]
        y0 = corners[k, 1]
        x1 = x0 + side - 1
        y1 = y0 + side - 1
        # the floor's plane: through the means of the square's four sides
        top = zero
        bottom = zero
        left = zero
        right = zero
        for j in range(side):
            top += np.float32(gray[y0, x0 + j])
            bottom += np.float32(gray[y1, x0 + j])
            left += np.float32(gray[y0 + j, x0])
            right += np.float32(gray[y0 + j, x1])
        n_side = np.float32(side)
        top /= n_side
        bottom /= n_side
        left /= n_side
        right /= n_side
        middle = (top + bottom + left + right) * np.float32(0.25)
        if not middle > 0:
            out[k, 0] = np.nan
            out[k, 1] = np.nan
            continue
        slope_x = (right - left) * across
        slope_y = (bottom - top) * across
        # Sensor noise takes floor pixels below a fixed allowance here and there: they would weigh
        # a little everywhere in the window and pull the centre towards its middle, the same way
        # on every symbol (a whole frame's movement off by 0.21 px at 1920x1080 under the suite's
        # noise). The allowance is three standard deviations of the ring about the plane (from its
        # mean absolute deviation), at least floor_share of the floor's level.
        deviation = zero
        for j in range(side):
            d = np.float32(j) - half
            deviation += abs(np.float32(gray[y0, x0 + j]) - (middle - slope_y * half + slope_x * d))
            deviation += abs(np.float32(gray[y1, x0 + j]) - (middle + slope_y * half + slope_x * d))
            deviation += abs(np.float32(gray[y0 + j, x0]) - (middle - slope_x * half + slope_y * d))
            deviation += abs(np.float32(gray[y0 + j, x1]) - (middle + slope_x * half + slope_y * d))
        deviation /= np.float32(4 * side)
        allowance = max(np.float32(3 * 1.2533) * deviation, np.float32(floor_share) * middle)
        base = middle - allowance
        # every moment up to the second of the weights (how far below the plane less the allowance)
        s0 = 0.0
        sx = 0.0
        sy = 0.0
        sxx = 0.0
        sxy = 0.0
        syy = 0.0
        for r in range(side):
            dy = np.float32(r) - half
            level = base + slope_y * dy
            w0 = zero
            w1 = zero
            w2 = zero
            # (a row slice: indices from 0 need no negative-index wrap check, so the loop runs
            # in vector registers: 2.3 times faster)
            row = gray[y0 + r, x0:x0 + side]
            for c in range(side):
                dx = np.float32(c) - half
                wt = max(level - (np.float32(row[c]) - slope_x * dx), zero)
                w0 += wt
                w1 += wt * dx
                w2 += wt * dx * dx
            s0 += w0
            sx += w1
            sxx += w2
            sy += w0 * dy
            sxy += w1 * dy
            syy += w0 * dy * dy
        # ... each relative to the floor's level there: light multiplies, so under a gradient the
        # ink on the brighter side lies further below its floor and would weigh more (a flat
        # level: 0.18 px off at 1920x1080 on the suite's gradient; a plane without this: 0.34).
        # With e = (slope . d) / middle, 1 / plane = (1 - e) / middle to first order: the
        # relative moments follow from the plain ones up to the second.
        gx = slope_x / middle
        gy = slope_y / middle
        total = s0 - gx * sx - gy * sy
        if total > 0:
            out[k, 0] = x0 + (side - 1) / 2 + (sx - gx * sxx - gy * sxy) / total
            out[k, 1] = y0 + (side - 1) / 2 + (sy - gx * sxy - gy * syy) / total
        else:
            out[k, 0] = np.nan
            out[k, 1] = np.nan


@njit(cache=True, nogil=True)
def _similarity(src, dst, keep, matrix):  # pragma: no cover - compiled
    """The least-squares similarity ``dst ~ s R src + t`` of the pairs ``keep`` marks, into ``matrix``."""
    n = 0
    msx = 0.0
    msy = 0.0
    mdx = 0.0
    mdy = 0.0
    for i in range(src.shape[0]):
        if keep[i]:
            n += 1
            msx += src[i, 0]
            msy += src[i, 1]
            mdx += dst[i, 0]
            mdy += dst[i, 1]
    msx /= n
    msy /= n
    mdx /= n
    mdy /= n
    sxx = 0.0
    sa = 0.0
    sb = 0.0
    for i in range(src.shape[0]):
        if keep[i]:
            xs = src[i, 0] - msx
            ys = src[i, 1] - msy
            xd = dst[i, 0] - mdx
            yd = dst[i, 1] - mdy
            sxx += xs * xs + ys * ys
            sa += xs * xd + ys * yd
            sb += xs * yd - ys * xd
    sxx = max(sxx, 1e-12)
    a = sa / sxx
    b = sb / sxx
    matrix[0, 0] = a
    matrix[0, 1] = -b
    matrix[0, 2] = mdx - a * msx + b * msy
    matrix[1, 0] = b
    matrix[1, 1] = a
    matrix[1, 2] = mdy - b * msx - a * msy
    matrix[2, 0] = 0.0
    matrix[2, 1] = 0.0
    matrix[2, 2] = 1.0


@njit(cache=True, nogil=True)
def _residuals(src, dst, keep, matrix, resid):  # pragma: no cover - compiled
    """Distances of the pairs ``keep`` marks from ``matrix``'s (affine) map, packed into the
    front of ``resid``; returns how many."""
    m = 0
    for i in range(src.shape[0]):
        if keep[i]:
            dx = matrix[0, 0] * src[i, 0] + matrix[0, 1] * src[i, 1] + matrix[0, 2] - dst[i, 0]
            dy = matrix[1, 0] * src[i, 0] + matrix[1, 1] * src[i, 1] + matrix[1, 2] - dst[i, 1]
            resid[m] = math.sqrt(dx * dx + dy * dy)
            m += 1
    return m


@njit(cache=True, nogil=True)
def trimmed_similarity(src, dst, floor_px, sigmas, min_keep, matrix, keep):  # pragma: no cover - compiled
    """:func:`sbplan.detection.registration._trimmed_fit` in one call: the least-squares similarity
    of the pairs ``src`` -> ``dst`` (n, 2), refitted without the pairs whose residual exceeds
    ``max(floor_px, sigmas * 1.4826 * median)`` when at least ``min_keep`` remain. Writes the
    matrix (3, 3) and the mask of the pairs kept (n,) bool; returns their RMS residual."""
    n = src.shape[0]
    for i in range(n):
        keep[i] = True
    _similarity(src, dst, keep, matrix)
    resid = np.empty(n)
    _residuals(src, dst, keep, matrix, resid)
    ordered = np.sort(resid)
    mid = ordered[n // 2] if n % 2 else 0.5 * (ordered[n // 2 - 1] + ordered[n // 2])
    limit = max(floor_px, sigmas * 1.4826 * mid)
    kept = 0
    for i in range(n):
        keep[i] = resid[i] <= limit
        kept += keep[i]
    if min_keep <= kept < n:
        _similarity(src, dst, keep, matrix)
        m = _residuals(src, dst, keep, matrix, resid)
    else:
        for i in range(n):
            keep[i] = True
        m = n
    total = 0.0
    for i in range(m):
        total += resid[i] * resid[i]
    return math.sqrt(total / m)


@njit(cache=True, nogil=True)
def pair_cells(centres, to_calibration, to_cell, cell_centres, rows, cols, max_d2, out):  # pragma: no cover - compiled
    """:func:`sbplan.detection.registration._pair` in one call: each centre (n, 2) mapped by
    ``to_calibration`` (3, 3), then to grid coordinates by ``to_cell`` (3, 3, the grid's inverse
    homography) and rounded to a cell; ``out`` (n,) gets the cell's flat index when the cell is on
    the grid and its centre (``cell_centres`` (rows * cols, 2)) lies within ``sqrt(max_d2)`` of the
    mapped centre, else -1."""
    for i in range(centres.shape[0]):
        x, y = centres[i, 0], centres[i, 1]
        w = to_calibration[2, 0] * x + to_calibration[2, 1] * y + to_calibration[2, 2]
        gx = (to_calibration[0, 0] * x + to_calibration[0, 1] * y + to_calibration[0, 2]) / w
        gy = (to_calibration[1, 0] * x + to_calibration[1, 1] * y + to_calibration[1, 2]) / w
        w = to_cell[2, 0] * gx + to_cell[2, 1] * gy + to_cell[2, 2]
        cx = (to_cell[0, 0] * gx + to_cell[0, 1] * gy + to_cell[0, 2]) / w
        cy = (to_cell[1, 0] * gx + to_cell[1, 1] * gy + to_cell[1, 2]) / w
        out[i] = -1
        if not (abs(cx) < 1e9 and abs(cy) < 1e9):
            continue
        col = np.int64(np.rint(cx))
        row = np.int64(np.rint(cy))
        if 0 <= row < rows and 0 <= col < cols:
            flat = row * cols + col
            dx = cell_centres[flat, 0] - gx
            dy = cell_centres[flat, 1] - gy
            if dx * dx + dy * dy <= max_d2:
                out[i] = flat


@njit(cache=True, nogil=True)
def short_breaks(kept, probed, rows, limit, gap, max_breaks, intact):  # pragma: no cover - compiled
    """For each outline ``i`` of ``rows``: do the runs of its broken points (``~kept[i]`` (S,), counted
    over the ``probed[i]`` points only) around the closed outline make at most ``max_breaks`` breaks
    of at most ``limit[i]`` points each, runs at most ``gap[i]`` kept points apart counting as one
    break? Written to ``intact[i]``. (:func:`sbplan.detection.outline_checks.intact_edges`.)"""
    broken = np.empty(kept.shape[1], np.bool_)
    for i in rows:
        n = 0
        for k in range(kept.shape[1]):
            if probed[i, k]:
                broken[n] = not kept[i, k]
                n += 1
        start = -1
        for k in range(n):
            if not broken[k]:
                start = k
                break
        if start < 0:
            intact[i] = False  # broken all round (or nothing probed)
            continue
        breaks = 0
        first = 0
        last = 0  # end (exclusive) of the last break
        longest = 0
        for k in range(n):
            if not broken[(start + k) % n]:
                continue
            if breaks and k - last <= gap[i]:
                last = k + 1
            else:
                if breaks:
                    longest = max(longest, last - first)
                breaks += 1
                first = k
                last = k + 1
        if breaks:
            longest = max(longest, last - first)
        intact[i] = breaks <= max_breaks and longest <= limit[i]


@njit(cache=True, nogil=True)
def largest_shift(matrix, points):  # pragma: no cover - compiled
    """The largest distance any of ``points`` (n, 2) moves under the 3x3 ``matrix``."""
    out = 0.0
    for i in range(points.shape[0]):
        x, y = points[i, 0], points[i, 1]
        w = matrix[2, 0] * x + matrix[2, 1] * y + matrix[2, 2]
        dx = (matrix[0, 0] * x + matrix[0, 1] * y + matrix[0, 2]) / w - x
        dy = (matrix[1, 0] * x + matrix[1, 1] * y + matrix[1, 2]) / w - y
        out = max(out, math.sqrt(dx * dx + dy * dy))
    return out


@njit(cache=True, nogil=True)
def _finite_rows(xy, k):  # pragma: no cover - compiled
    """The least and the largest y of outline ``k`` of ``xy`` (K, N, 2), and whether all are finite."""
    lo = np.inf
    hi = -np.inf
    for j in range(xy.shape[1]):
        v = xy[k, j, 1]
        if not math.isfinite(v):
            return lo, hi, False
        lo = min(lo, v)
        hi = max(hi, v)
    return lo, hi, True


@njit(cache=True, nogil=True)
def outlines_to_full(xy, shift, split):  # pragma: no cover - compiled
    """:meth:`sbplan.detection.bands.RowBands.to_full_outlines`'s whole outlines, in place: each
    outline of ``xy`` (K, N, 2) whose top and bottom rows take the same ``shift`` (per stacked row)
    moves by it; ``split[k]`` is set for the others (not all finite, or across bands)."""
    last = shift.shape[0] - 1
    for k in range(xy.shape[0]):
        lo, hi, finite = _finite_rows(xy, k)
        if not finite:
            split[k] = True
            continue
        top = shift[min(max(int(math.floor(lo + 0.5)), 0), last)]
        if top != shift[min(max(int(math.floor(hi + 0.5)), 0), last)]:
            split[k] = True
            continue
        for j in range(xy.shape[1]):
            xy[k, j, 1] += top


@njit(cache=True, nogil=True)
def outlines_to_stacked(xy, starts, stops, offsets, split):  # pragma: no cover - compiled
    """:meth:`sbplan.detection.bands.RowBands.to_stacked_outlines`'s whole outlines, in place: each
    outline of ``xy`` (K, N, 2) lying in one band moves by that band's shift; ``split[k]`` is set
    for the others (not all finite, across bands, or past a band's end)."""
    for k in range(xy.shape[0]):
        lo, hi, finite = _finite_rows(xy, k)
        if not finite:
            split[k] = True
            continue
        # the band of a row: the last that starts at or above it (numpy's searchsorted, 'right')
        top = math.floor(lo + 0.5)
        bottom = math.floor(hi + 0.5)
        band = 0
        last = 0
        for b in range(starts.shape[0]):
            if starts[b] <= top:
                band = b
            if starts[b] <= bottom:
                last = b
        shift = float(starts[band] - offsets[band])
        if band != last or not hi - shift <= float(offsets[band] + stops[band] - starts[band]):
            split[k] = True
            continue
        for j in range(xy.shape[1]):
            xy[k, j, 1] -= shift
