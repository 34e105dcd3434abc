"""KKA: the paper's contour approximation on the Freeman chain (section 2.1, after Nabout 1993).

The paper names three steps and no details; this module implements them as follows.

1. **Digital straight pieces** (:func:`straight_pieces`). The chain is cut into maximal pieces,
   greedily from a sharp corner, each of which satisfies this level-1 straightness criterion
   (Freeman's chord properties, without recursing into the run lengths of the run lengths):

   a. the piece uses one Freeman code, or two codes that are adjacent (differ by 1 modulo 8);
   b. one of the two codes, the *singular* one, only occurs in runs of length 1;
   c. the runs of the other, *principal* code that are enclosed by singular codes (the interior
      runs) have lengths L or L + 1 for one L; the first and last run of the piece, which may be
      cut short by the piece's ends, are at most ``L + 1`` long (any length when there is no
      interior run yet).

   A run of a code is split between two pieces when only part of it fits the criterion.
2. **Noise chains**: pieces with fewer than ``noise_length`` chain steps are merged into the
   neighbour for which the merged piece stays closer to its chord (shortest noise piece first).
3. **Sorting and curved parts**: the boundaries between consecutive pieces are ranked by the
   largest distance of the merged piece's pixels from its chord; the cheapest boundary is removed
   first while that distance stays within ``max_deviation``. Runs of short pieces with slowly
   turning direction (curved contour parts) collapse into chords of bounded deviation, and nearly
   collinear straight pieces (a long digitized edge that level-1 straightness splits) into one
   segment; real corners are kept because removing them would move the outline further.

The output vertices are the contour pixels at the remaining piece boundaries, in traversal order.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from sbplan.contracts import ContourApproximator, option
from sbplan.errors import ContourError, InputError

from ._common import contour_chain, contour_points, three_vertices

__all__ = ["KKA", "straight_pieces", "is_digital_straight"]

_INF = 1 << 62


def _max_last(codes: list[int], lens: list[int]) -> int:
    """How long the last run of the piece ``codes``/``lens`` may be (the last length is ignored).

    0 when the piece is not straight even with a last run of length 1.
    """
    m = len(codes)
    if m == 1:
        return _INF
    a, b = codes[0], codes[1]
    if (a - b) % 8 not in (1, 7) or any(c != a and c != b for c in codes):
        return 0
    best = 0
    for s, p in ((a, b), (b, a)):
        if any(ln != 1 for c, ln in zip(codes[:-1], lens[:-1]) if c == s):
            continue
        interior = [lens[i] for i in range(1, m - 1) if codes[i] == p]
        cap = _INF
        if interior:
            lo, hi = min(interior), max(interior)
            if hi - lo > 1:
                continue
            cap = lo + 1
            if codes[0] == p and lens[0] > cap:
                continue
        best = max(best, 1 if codes[-1] == s else cap)
    return best


def is_digital_straight(chain) -> bool:
    """Whether a (not closed) Freeman chain satisfies the level-1 straightness criterion of this
    module's docstring."""
    c = np.asarray(chain, dtype=np.int64)
    if c.size == 0:
        return True
    codes, lens = _runs(c)
    for i in range(1, len(codes) + 1):
        if _max_last(codes[:i], lens[:i]) < lens[i - 1]:
            return False
    return True


def _runs(c: np.ndarray) -> tuple[list[int], list[int]]:
    """Run-length encoding of a 1-D code array: codes and lengths as lists."""
    cut = np.flatnonzero(c[1:] != c[:-1]) + 1
    starts = np.concatenate([[0], cut])
    lens = np.diff(np.concatenate([starts, [len(c)]]))
    return c[starts].tolist(), lens.tolist()


def straight_pieces(chain) -> np.ndarray:
    """Cut a closed Freeman chain into maximal digital straight pieces.

    Parameters
    ----------
    chain : array_like of shape (N,), int
        Freeman codes of a closed contour (``sbplan.contours.FREEMAN_STEPS``), N >= 1.

    Returns
    -------
    ndarray of shape (P,), int64
        Sorted chain indices where the pieces start; piece i covers steps ``starts[i]`` up to
        ``starts[i+1] - 1`` (the last piece wraps around to ``starts[0]``). Point ``starts[i]`` of
        the contour is the vertex between pieces i - 1 and i.
    """
    c = np.asarray(chain, dtype=np.int64)
    if c.ndim != 1 or c.size == 0:
        raise ContourError(f"chain: expected a non-empty 1-D array of Freeman codes, got shape {c.shape}")
    if ((c < 0) | (c > 7)).any():
        raise ContourError("chain: Freeman codes must lie in 0..7")
    n = len(c)
    turn = (c - np.roll(c, 1)) % 8
    sharp = np.flatnonzero((turn >= 2) & (turn <= 6))
    change = np.flatnonzero(turn != 0)
    # Start at a sharp corner, where a piece must end anyway, so the wrap-around does not cut a
    # straight piece in two; failing that, at a change of code.
    start = int(sharp[0]) if sharp.size else (int(change[0]) if change.size else 0)
    codes, lens = _runs(np.roll(c, -start))

    cuts = [0]
    cur_c: list[int] = []
    cur_l: list[int] = []
    pos = 0
    r = 0
    rem = lens[0]
    while r < len(codes):
        code = codes[r]
        if not cur_c:
            cur_c, cur_l = [code], [rem]
            pos += rem
            r += 1
            rem = lens[r] if r < len(codes) else 0
            continue
        allowed = _max_last(cur_c + [code], cur_l + [1])
        if allowed == 0:
            cuts.append(pos)
            cur_c, cur_l = [], []
            continue
        take = min(rem, allowed)
        cur_c.append(code)
        cur_l.append(take)
        pos += take
        if take < rem:
            rem -= take
            cuts.append(pos)
            cur_c, cur_l = [], []
        else:
            r += 1
            rem = lens[r] if r < len(codes) else 0
    return np.sort((np.asarray(cuts, dtype=np.int64) + start) % n)


def _span_costs(points: np.ndarray, first, last) -> np.ndarray:
    """For each span, the largest distance of the contour points first..last (cyclic, inclusive)
    from the chord first-last; all spans in one vectorized pass. Shape (S,)."""
    n = len(points)
    first = np.asarray(first, dtype=np.int64)
    last = np.asarray(last, dtype=np.int64)
    counts = (last - first) % n
    counts[counts == 0] = n
    counts += 1
    starts = np.zeros(len(first), np.int64)
    np.cumsum(counts[:-1], out=starts[1:])
    idx = (np.arange(counts.sum()) - np.repeat(starts - first, counts)) % n
    a = np.repeat(points[first], counts, axis=0)
    ab = np.repeat(points[last] - points[first], counts, axis=0)
    ap = points[idx] - a
    den = np.einsum("ij,ij->i", ab, ab)
    t = np.clip(np.einsum("ij,ij->i", ap, ab) / np.where(den > 0, den, 1.0), 0.0, 1.0)
    d = ap - t[:, None] * ab
    return np.maximum.reduceat(np.einsum("ij,ij->i", d, d), starts) ** 0.5


@dataclass(kw_only=True, frozen=True)
class KKA(ContourApproximator):
    """The paper's KKA approximation: digital straight pieces of the Freeman chain, noise chains
    merged into their neighbours, curved parts replaced by chords of bounded deviation.

    The exact criteria are in the module docstring of :mod:`sbplan_approximators.kka`. Contours
    without a chain (plain point arrays) get one derived from their points, which must then be an
    8-connected pixel path.
    """

    name: ClassVar[str] = "kka"
    description: ClassVar[str] = "the paper's KKA: digital straight pieces, noise chains merged, curves by chords"

    noise_length: int = option(3, "pieces with fewer chain steps than this are noise, merged into a neighbour")
    max_deviation: float = option(1.0, "largest distance (pixels) of a contour pixel from a merged chord")

    def __post_init__(self) -> None:
        if isinstance(self.noise_length, bool) or not isinstance(self.noise_length, (int, np.integer)) \
                or self.noise_length < 0:
            raise InputError(f"option noise_length: expected an integer >= 0, got {self.noise_length!r}")
        v = self.max_deviation
        if isinstance(v, bool) or not isinstance(v, (int, float, np.number)) or not np.isfinite(v) or v < 0:
            raise InputError(f"option max_deviation: expected a finite number >= 0 pixels, got {v!r}")

    def approximate(self, contour) -> np.ndarray:
        pts = contour_points(contour)
        chain = contour_chain(contour, pts)
        n = len(pts)
        verts = straight_pieces(chain).tolist()

        # Step 2: noise chains, the shortest first.
        while len(verts) > 3:
            k = len(verts)
            lengths = [(verts[(i + 1) % k] - verts[i]) % n or n for i in range(k)]
            i = int(np.argmin(lengths))
            if lengths[i] >= self.noise_length:
                break
            prev_v, nxt_v, nxt2_v = verts[i - 1], verts[(i + 1) % k], verts[(i + 2) % k]
            # cost of dropping vertex i (merge into the previous piece) or i + 1 (into the next)
            into_prev, into_next = _span_costs(pts, [prev_v, verts[i]], [nxt_v, nxt2_v])
            del verts[i if into_prev <= into_next else (i + 1) % k]

        # Step 3: remove the cheapest boundary while the merged piece stays within max_deviation.
        k = len(verts)
        if k > 3:
            v = np.asarray(verts)
            cost = _span_costs(pts, np.roll(v, 1), np.roll(v, -1)).tolist()
            while len(verts) > 3:
                i = int(np.argmin(cost))
                if cost[i] > self.max_deviation:
                    break
                del verts[i]
                del cost[i]
                k = len(verts)
                js = [(i - 1) % k, i % k]
                new = _span_costs(pts, [verts[j - 1] for j in js], [verts[(j + 1) % k] for j in js])
                cost[js[0]], cost[js[1]] = float(new[0]), float(new[1])
        if len(verts) < 3:
            return three_vertices(pts)
        return pts[np.asarray(verts)].copy()
