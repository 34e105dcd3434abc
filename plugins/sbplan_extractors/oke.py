"""``oke``: the paper's contour extraction (section 2.1), vectorized with numpy.

The paper segments the image into overlapping 2x2 windows, turns each window's pattern into basic
contour elements through extraction rules, and sorts the elements into closed contours, each
described by a start point and a Freeman chain. This module does the same with whole-array
operations; there is no loop over pixels or contour elements.

Design
------
*Windows.* The mask is zero-padded by one pixel (pixels outside the image are background). Every
2x2 window ``[[a, b], [c, d]]`` of the padded image is centred on a pixel-grid vertex ``V``; its
pattern ``a | b << 1 | c << 2 | d << 3`` is computed for all windows at once.

*Basic contour elements* are directed crack edges (unit edges between a foreground and a
4-adjacent background pixel), oriented with the foreground on the left as displayed, so outer
boundaries run counter-clockwise and holes clockwise. Each crack is owned by the window at its
tail vertex; the rules are a lookup table from pattern to the cracks leaving ``V``: up when ``a``
and not ``b``, right when ``b`` and not ``d``, down when ``d`` and not ``c``, left when ``c`` and
not ``a``. Each crack also carries its foreground pixel (``a``, ``b``, ``d``, ``c`` respectively).
A second table gives, for a pattern and the direction a crack arrives in, the crack that leaves:
unique except at the two diagonal "saddle" patterns, where the rule joins the two foreground
pixels (8-connected foreground, 4-connected background, as OpenCV).

*Sorting.* Successor pointers come from the tables plus one ``searchsorted`` of the head window in
the sorted list of non-empty windows. Cycles are labelled by pointer jumping: each element keeps
the smallest element index seen in the ``2**k`` elements ahead of it and the distance to it,
until every cycle agrees on its minimum. Element indices follow the raster order of windows, so
a cycle's minimum is, for an outer boundary, the down crack at the top-left corner of the region's
first pixel in raster order, and for a hole the right crack at the top-left corner of the hole's
first pixel (which tells holes from outer boundaries). Positions along each cycle then follow
from the distances, and one scatter puts every element in place.

*Boundary pixels.* Walking a crack loop and writing down the foreground pixel of each crack,
without immediate repeats, gives the pixel sequence of Moore / Suzuki border following. Starts are
chosen as OpenCV does: an outer boundary starts at its region's first pixel, a hole at the
foreground pixel left of the hole's first pixel, so ``oke`` and ``opencv`` give identical
sequences.

*Nesting.* A hole's region is found by looking left along the hole's first row for the crack that
ends the foreground run: it belongs to the region's outer boundary or to another hole of the same
region, whose answer is taken in turn (pointer jumping again; each step moves strictly earlier in
raster order, so it ends). An outer boundary's parent is found the same way through the
background run to its left: a hole (the parent), another island in the same hole (same parent),
or the image border (no parent).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sbplan.contours import Contour

from ._common import BoundaryExtractor, as_mask, build_contours

# Crack directions (as displayed): up, right, down, left.
_N, _E, _S, _W = 0, 1, 2, 3
_A, _B, _C, _D = 1, 2, 4, 8  # window bits: a = top-left, b = top-right, c = bottom-left, d = bottom-right


def _tables() -> tuple[np.ndarray, ...]:
    nout = np.zeros(16, np.int64)
    out = np.full((16, 2), 255, np.int64)
    nxt = np.full((16, 4), 255, np.int64)
    for code in range(16):
        a, b, c, d = (bool(code & bit) for bit in (_A, _B, _C, _D))
        outs = [dr for dr, ok in ((_N, a and not b), (_E, b and not d), (_S, d and not c), (_W, c and not a)) if ok]
        nout[code] = len(outs)
        out[code, :len(outs)] = outs
        # The direction a crack arrives in tells which side of V it comes from.
        ins = [dr for dr, ok in ((_S, b and not a), (_N, c and not d), (_E, a and not c), (_W, d and not b)) if ok]
        if len(outs) == 1:
            nxt[code, ins[0]] = outs[0]
        elif code == _A | _D:  # saddle: join a (arriving along its bottom) to d, and d to a
            nxt[code, _E], nxt[code, _W] = _S, _N
        elif code == _B | _C:
            nxt[code, _S], nxt[code, _N] = _W, _E
    return nout, out, nxt


_NOUT, _OUT, _NEXT = _tables()


@dataclass(kw_only=True, frozen=True)
class OkeExtractor(BoundaryExtractor):
    """The paper's extractor: 2x2 windows, basic contour elements, sorted into closed contours."""

    name = "oke"
    description = "paper's OKE: 2x2 window patterns -> crack elements -> sorted closed contours (numpy)"

    def extract(self, binary: np.ndarray) -> list[Contour]:
        """Return every outer boundary and hole boundary of ``binary``.

        Parameters
        ----------
        binary : ndarray of shape (H, W), bool or uint8 (0/1/255)
            Foreground mask indexed ``(row, col)``; nonzero is foreground.

        Returns
        -------
        list of Contour
            Points are ``(x, y)`` int64, the same sequences as the ``opencv`` extractor gives;
            parents follow the nesting tree.
        """
        return find_contours_oke(binary, chains=self.chains)


def find_contours_oke(binary: np.ndarray, *, chains: bool = True) -> list[Contour]:
    """Functional form of :class:`OkeExtractor` (same parameters and result)."""
    mask = as_mask(binary, name="binary")
    h, w = mask.shape
    wp = w + 2  # padded width; windows are indexed on the same grid (window k has pixel k as a)
    nwin = (h + 1) * wp
    # Flat padded image with spare zeros at the end: each window then reads pixels k, k + 1,
    # k + wp and k + wp + 1 as contiguous shifted views. The windows of the last column mix
    # two rows' padding pixels, are empty (pattern 0) and drop out by themselves.
    padded = np.zeros((h + 2) * wp + 8, np.uint8)
    np.bitwise_and(mask, 1, out=padded[:(h + 2) * wp].reshape(h + 2, wp)[1:-1, 1:-1])  # 255 & 1 == 1

    # -- 2x2 window patterns: a + 2b + 4c + 8d, with uint8 adds (numpy's uint8 shifts are slow) --
    pairs = padded[1:nwin + wp + 1] + padded[1:nwin + wp + 1]
    pairs += padded[:nwin + wp]
    # Padded to whole 8-byte words so that empty (0) and full (15) windows are skipped eight
    # at a time before the per-window test.
    buf = np.empty(-(-nwin // 8) * 8, np.uint8)
    code = buf[:nwin]
    np.add(pairs[wp:], pairs[wp:], out=code)
    code += code
    code += pairs[:nwin]
    buf[nwin:] = 0
    words = buf.view(np.uint64)
    busy = np.flatnonzero((words != 0) & (words != np.uint64(0x0F0F0F0F0F0F0F0F)))
    windows = (busy[:, None] * 8 + np.arange(8)).ravel()
    windows = windows[(buf[windows] - np.uint8(1)) < 14]  # patterns 1..14 hold cracks
    if len(windows) == 0:
        return []
    wcode = code[windows].astype(np.int64)
    nout = _NOUT[wcode]
    first = np.cumsum(nout) - nout  # index of each window's first element

    # -- basic contour elements (one per crack, in window raster order) ----------------------
    ewin = np.repeat(windows, nout)
    ecode = np.repeat(wcode, nout)
    second = np.zeros(len(ewin), np.int64)
    second[first[nout == 2] + 1] = 1
    edir = _OUT[ecode, second]
    n = len(ewin)
    pix = ewin + np.array([0, 1, wp + 1, wp], np.int64)[edir]  # padded flat index of the pixel

    # -- successor pointers ------------------------------------------------------------------
    head = ewin + np.array([-wp, 1, wp, -1], np.int64)[edir]
    hcode = code[head].astype(np.int64)
    hdir = _NEXT[hcode, edir]
    hk = np.searchsorted(windows, head)
    succ = first[hk] + (hdir == _OUT[hcode, 1])

    # -- cycles: minimum element and distance to it, by pointer jumping -----------------------
    idx = np.arange(n, dtype=np.int64)
    best, dist, jump, step = idx.copy(), np.zeros(n, np.int64), succ.copy(), 1
    while True:
        ahead = best[jump]
        better = ahead < best
        best = np.where(better, ahead, best)
        dist = np.where(better, dist[jump] + step, dist)
        if np.array_equal(best[succ], best):
            break
        jump = jump[jump]
        step *= 2
    roots = np.flatnonzero(best == idx)
    ncyc = len(roots)
    label = np.empty(n, np.int64)
    label[roots] = np.arange(ncyc)
    cycle = label[best]
    length = dist[succ[roots]] + 1
    lc = length[cycle]
    pos = (lc - dist) % lc  # steps from the cycle's minimum
    is_hole = edir[roots] == _E
    # A hole starts at the right crack of the pixel left of its first pixel: the up crack
    # owned by the window one row below the minimum's window.
    shift = np.zeros(ncyc, np.int64)
    hole_ids = np.flatnonzero(is_hole)
    anchors = first[np.searchsorted(windows, ewin[roots[hole_ids]] + wp)]
    shift[hole_ids] = pos[anchors]
    pos = (pos - shift[cycle]) % lc
    base = np.cumsum(length) - length
    order = np.empty(n, np.int64)
    order[base[cycle] + pos] = idx

    # -- boundary pixels: crack pixels without immediate repeats -----------------------------
    opix, opos = pix[order], pos[order]
    ocyc = np.repeat(np.arange(ncyc), length)
    keep = np.empty(n, bool)
    keep[0] = True
    np.not_equal(opix[1:], opix[:-1], out=keep[1:])
    # Drop the run at a cycle's end that repeats its start pixel (it wraps onto the start).
    tail = np.maximum.reduceat(np.where(opix != opix[base][ocyc], opos, -1), base)
    keep &= opos <= tail[ocyc]
    keep[base] = True
    counts = np.add.reduceat(keep.astype(np.int64), base)
    flat = opix[keep]
    points = np.empty((len(flat), 2), np.int64)
    np.subtract(flat % wp, 1, out=points[:, 0])
    np.subtract(flat // wp, 1, out=points[:, 1])

    parent = _parents(edir, ewin, wp, cycle, roots, anchors, is_hole)
    return build_contours(points, counts, is_hole, parent, chains=chains)


def _parents(edir, ewin, wp, cycle, roots, anchors, is_hole) -> np.ndarray:
    """Nesting tree: a hole's parent is its region's outer boundary, an outer boundary's parent
    the hole around it (or -1)."""
    ncyc = len(roots)
    # Vertical cracks keyed by (row, edge column): an up crack at window (i, j) lies in padded
    # row i, a down crack in row i + 1, both on the edge left of column j + 1.
    vert = np.flatnonzero((edir == _N) | (edir == _S))
    # With windows on the padded pixel grid that key is simply window + 1 (+ wp for down).
    vkey = ewin[vert] + 1 + wp * (edir[vert] == _S)
    srt = np.argsort(vkey, kind="stable")
    vkey, vcyc = vkey[srt], cycle[vert][srt]

    # The crack where each cycle starts its search: holes at their anchor (an up crack), outer
    # boundaries at their minimum (the down crack left of the region's first pixel).
    start = roots.copy()
    start[is_hole] = anchors
    skey = ewin[start] + 1 + wp * (edir[start] == _S)
    left = np.searchsorted(vkey, skey) - 1
    found = left >= 0
    found[found] = vkey[left[found]] // wp == skey[found] // wp
    nxt = np.where(found, vcyc[np.maximum(left, 0)], -1)
    # Stop at the first cycle of the other kind (or at the border); otherwise inherit its answer.
    done = (nxt < 0) | (is_hole[np.maximum(nxt, 0)] != is_hole)
    result = np.where(done, nxt, -1)
    link = np.where(done, np.arange(ncyc), nxt)
    while True:
        hop = link[link]
        if np.array_equal(hop, link):
            break
        link = hop
    return result[link]
