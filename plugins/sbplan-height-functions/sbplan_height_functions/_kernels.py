"""The compiled inner loops: point-to-point costs and the optimal circular alignment.

Imported on first use only (numba takes a moment to import and to compile), so that loading the
plugin, as every ``sbplan`` command does, stays cheap.

The alignment of two closed outlines of N points each is a shortest path in a grid: rows
``i = 0..N`` read A from its point 0, columns ``c = 0..2N`` read B laid out twice (column ``c``
has passed B's points ``0 .. c-1``, taken mod N). A step down leaves A's point unmatched, a step
right leaves B's point unmatched (both free here: the caller adds their cost), a diagonal step
into ``(i + 1, c + 1)`` matches A's point ``i`` with B's point ``c mod N`` for
``cost[i, c] - reward``. Reading B once round from its point ``s`` is a path from ``(0, s)`` to
``(N, s + N)``; the optimal circular alignment is the best of these N paths.

Trying every start costs N times one alignment. Maes' divide and conquer (M. Maes, "On a cyclic
string-to-string correction problem", Information Processing Letters 35, 1990) needs about
log2(N) times one: optimal paths for two starts ``lo < hi`` can be taken not to cross, so the
optimal path for a start between them lies between their paths. The path for start 0 is computed
in the whole strip, the path for start N is the same path moved N columns, and each start
between is computed in the band its two neighbours leave, halving the range each time.
"""

from __future__ import annotations

import numpy as np
from numba import njit

INF = np.inf


@njit(cache=True, nogil=True)
def point_costs(a, bt, out):
    """L1 distances between the rows of ``a`` (N, M) and the columns of ``bt`` (M, N), written
    twice side by side into ``out`` (N, 2N): ``out[i, j] = out[i, j + N] = |a[i] - bt[:, j]|_1``.

    The inner loop runs along a row of ``bt`` (contiguous) so that it vectorizes.
    """
    n, m = a.shape
    for i in range(n):
        for j in range(n):
            out[i, j] = 0.0
        for q in range(m):
            aq = a[i, q]
            for j in range(n):
                out[i, j] += abs(aq - bt[q, j])
        for j in range(n):
            out[i, j + n] = out[i, j]


@njit(cache=True, nogil=True)
def band_dp(cost2, reward, start, end_lo, end_hi, lo, hi, table):
    """Shortest paths from row 0 at column ``start`` or right of it to row N at a column in
    ``end_lo .. end_hi``, through the band whose row ``i`` holds columns ``lo[i] .. hi[i]``
    (both non-decreasing). Returns the shortest length (the sum of ``cost - reward`` over its
    matches); ``table`` (N + 1, 2N + 2) keeps the values, grid column ``c`` at ``table[:, c + 1]``.

    With ``end_lo = end_hi = start + N`` this is the alignment that reads B once round from its
    point ``start``; with a range of ends it is a lower bound of every start in ``start ..
    end_hi - N`` (moving right along row 0 is free, so starting further right is included).
    """
    n = cost2.shape[0]
    a0 = start
    b0 = min(hi[0], end_hi)
    table[0, a0] = INF  # a wall left of the first column
    for c in range(a0, b0 + 1):
        table[0, c + 1] = 0.0
    pa, pb = a0, b0
    # 2-D indexing throughout: a row view would cost a reference count per row
    for i in range(1, n + 1):
        a = max(lo[i], start)
        b = min(hi[i], end_hi)
        # what row i reads of row i - 1 outside its band is a wall
        table[i - 1, pa] = INF
        for c in range(pb + 1, b + 1):
            table[i - 1, c + 1] = INF
        left = INF
        first = a
        if a == 0:  # column 0 has no diagonal into it
            left = table[i - 1, 1]
            table[i, 1] = left
            first = 1
        # branch-free: both selects become minsd (a branch here mispredicts half the time)
        for c in range(first, b + 1):
            v = table[i - 1, c + 1]
            d = table[i - 1, c] + (cost2[i - 1, c - 1] - reward)
            v = d if d < v else v
            v = left if left < v else v
            table[i, c + 1] = v
            left = v
        pa, pb = a, b
    best = INF
    for c in range(max(end_lo, pa), end_hi + 1):
        v = table[n, c + 1]
        best = v if v < best else best
    return best


@njit(cache=True, nogil=True)
def band_path(cost2, reward, start, lo, hi, table, left_out, right_out):
    """The alignment reading B once round from its point ``start`` (:func:`band_dp`), and its
    path: the leftmost and rightmost column in every row, into ``left_out`` and ``right_out``."""
    n = cost2.shape[0]
    end = start + n
    total = band_dp(cost2, reward, start, end, end, lo, hi, table)
    # Walk back; each row's columns are met right to left.
    i, c = n, end
    right_out[n] = end
    while i > 0:
        v = table[i, c + 1]
        if c - 1 >= max(lo[i], start) and table[i, c] == v:
            c -= 1
            continue
        left_out[i] = c
        if c > 0 and table[i - 1, c] + (cost2[i - 1, c - 1] - reward) == v:
            c -= 1
        i -= 1
        right_out[i] = c
    left_out[0] = start
    return total


@njit(cache=True, nogil=True)
def circular_alignment(cost2, reward, step, table, lefts, rights, lo, hi, stack):
    """The least total of ``cost - reward`` over order-keeping one-to-one matchings of A's N
    points to B's, B read once round from any start (see the module docstring): exact.

    Starts ``0, step, 2 step, ...`` are aligned first, each in the band its left neighbour and
    the path of start 0 moved N columns leave. Then every range of starts between two aligned
    ones is bounded from below by one pass through their band with a free start and end
    (:func:`band_dp`); a range whose bound is no better than the best alignment so far is
    dropped, any other is split at its middle start, which is aligned, as in Maes' method.

    ``cost2`` is (N, 2N): ``cost2[i, j]`` matches A's point i with B's point ``j mod N``.
    Scratch: ``table`` (N + 1, 2N + 2), ``lefts`` and ``rights`` (N + 1, N + 1) int64, ``lo`` and
    ``hi`` (N + 1,) int64, ``stack`` (2 (N + 2),) int64.
    """
    n = cost2.shape[0]
    for i in range(n + 1):
        lo[i] = 0
        hi[i] = n
    best = band_path(cost2, reward, 0, lo, hi, table, lefts[0], rights[0])
    for i in range(n + 1):
        lefts[n, i] = lefts[0, i] + n
        rights[n, i] = rights[0, i] + n
    top = 0
    prev = 0
    s = step
    while prev < n:
        s = min(s, n)
        if s < n:
            v = band_path(cost2, reward, s, lefts[prev], rights[n], table, lefts[s], rights[s])
            best = v if v < best else best
        if s - prev >= 2:
            stack[top] = prev
            stack[top + 1] = s
            top += 2
        prev = s
        s += step
    while top > 0:
        top -= 2
        s0 = stack[top]
        s1 = stack[top + 1]
        bound = band_dp(cost2, reward, s0 + 1, s0 + 1 + n, s1 - 1 + n, lefts[s0], rights[s1], table)
        if bound >= best:
            continue
        mid = (s0 + s1) // 2
        v = band_path(cost2, reward, mid, lefts[s0], rights[s1], table, lefts[mid], rights[mid])
        best = v if v < best else best
        if mid - s0 >= 2:
            stack[top] = s0
            stack[top + 1] = mid
            top += 2
        if s1 - mid >= 2:
            stack[top] = mid
            stack[top + 1] = s1
            top += 2
    return best


@njit(cache=True, nogil=True)
def shifted_alignment(cost2, reward, start, table, left_out, right_out, lo, hi):
    """The alignment with B read from its point ``start`` only, in the whole strip (for tests)."""
    n = cost2.shape[0]
    for i in range(n + 1):
        lo[i] = 0
        hi[i] = 2 * n
    return band_path(cost2, reward, start, lo, hi, table, left_out, right_out)


@njit(cache=True, nogil=True)
def pair_distances(desc, desc_t, mirror_t, first, second, skip_cost, use_mirror, step, out):
    """Aligned matching cost of the descriptor pairs ``(first[p], second[p])``, into ``out[p]``.

    ``desc`` is (S, N, M); ``desc_t`` the same transposed to (S, M, N) and ``mirror_t`` the mirror
    images' descriptors, transposed. The first shape of a pair is read from its point 0, the
    second from every start (and mirrored, if ``use_mirror``). The result is the sum of the
    matched points' costs plus ``skip_cost`` for every point left unmatched, on both shapes,
    divided by N: 0 for identical descriptors, at most ``2 * skip_cost``.
    """
    n = desc.shape[1]
    cost2 = np.empty((n, 2 * n))
    table = np.empty((n + 1, 2 * n + 2))
    lefts = np.empty((n + 1, n + 1), np.int64)
    rights = np.empty((n + 1, n + 1), np.int64)
    lo = np.empty(n + 1, np.int64)
    hi = np.empty(n + 1, np.int64)
    stack = np.empty(2 * (n + 2), np.int64)
    reward = 2.0 * skip_cost
    for p in range(first.shape[0]):
        a = desc[first[p]]
        point_costs(a, desc_t[second[p]], cost2)
        best = circular_alignment(cost2, reward, step, table, lefts, rights, lo, hi, stack)
        if use_mirror:
            point_costs(a, mirror_t[second[p]], cost2)
            best = min(best, circular_alignment(cost2, reward, step, table, lefts, rights, lo, hi, stack))
        out[p] = max(0.0, (2.0 * n * skip_cost + best) / n)
