"""The exact auxiliary-corner search: a lazy visibility graph over the convex corners of the
enlarged obstacles, searched with A*, its visibility cache kept for later queries.

Coordinates are world ``(x, y)``, y up. Obstacles given here are already enlarged (robot radius +
margin + tolerance); a point is free when it is outside or on the boundary of every one of them.
"""

from __future__ import annotations

import copy
import heapq
import math
import threading
from dataclasses import dataclass, field
from typing import Literal, Sequence

import numpy as np
import shapely
from shapely.geometry import Polygon

from ..errors import NoRouteError

#: a point (x, y): a pair of numbers or an array of shape (2,)
XY = Sequence[float] | np.ndarray

_UNKNOWN, _FREE, _BLOCKED = 0, 1, 2
#: Above this many segment x edge pairs a fan of segments is pre-filtered by angle (_fan_pairs);
#: 10k measured best (rect-200 cold median 13 -> 8 ms, same elsewhere) with `sbplan bench plan`,
#: and again after the per-map arrays (3k and 30k: same or slower on rect-50/200 and the mazes).
_DENSE_LIMIT = 10_000
#: Row chunk of the general (non-fan) segment test: bounds its K x E temporaries to ~1M pairs.
_CHUNK_PAIRS = 1_000_000
#: Maps with at most this many edges answer one-segment tests (straight_check, segment_free: the
#: straight-line fast path, the search's first test, OMPL's motion checks) in plain Python over
#: per-map tuples with bounding boxes (_scan); larger maps use the numpy form (_segment). _scan
#: was faster on every bench world (straight_check 3.4-14 us against 26-39 us, rect-200 included),
#: but its tables cost ~20 us + 0.3 us per edge of build: they pay back within ~5 queries up to
#: the 524 edges of map:crowded, after ~35 on rect-200's 800.
_SCALAR_MAX_EDGES = 600
#: Consecutive edges of one polygon per bounding box in _scan's tables.
_SCAN_EDGES = 8
#: prepare_routes builds its corner-to-corner table only up to this many active corners: the
#: all-pairs visibility tests grow as C^2 x E and Floyd-Warshall as C^3 (C = 167 on the service
#: benchmark's 50-rectangle floor: ~60 ms once), its tables as C^2 (8 bytes x 2 each).
_TABLE_MAX_CORNERS = 1000
#: Hidden ends a table query tests one by one before it tests all the rest at once (_table_path).
#: On the service benchmark's floor (CPU per query, medians): 4: 0.76 ms, 8: 0.54, 16: 0.46,
#: 32: 0.39, unbounded: 0.39; batches of 3-40 ends per fan instead of single segments: 0.50-1.08.
_LAZY_TESTS = 32


def _cross(ax, ay, bx, by):
    return ax * by - ay * bx


class VisibilityMap:
    """Cached planning structures of one map (enlarged obstacles + rectangular bounds).

    Parameters
    ----------
    polygons : sequence of shapely Polygon
        Enlarged obstacles, oriented with interiors on the left of their rings; may overlap.
    bounds : (xmin, ymin, xmax, ymax)
        The workspace; corners outside it are dropped (exact for a rectangular workspace).
    eps : float
        Geometric tolerance in map units (lengths); angles and areas are scaled from it.

    Notes
    -----
    Threads: queries (``shortest_path``, ``straight_check``, ``segment_free``, ``covered``) may run
    from several threads at once. The search fills the visibility cache under the map's lock, and
    ``copy`` reads it under the same lock, so a copy never holds half of a cache update.
    ``add_obstacles`` changes the map: do not call it while other threads query this map (replan
    adds obstacles to a copy). ``stats`` are counters for tests and benchmarks; the one-segment
    tests update them without the lock, so concurrent queries may lose counts.
    """

    def __init__(self, polygons: Sequence[Polygon], bounds: Sequence[float], *, eps: float):
        self.bounds = tuple(float(b) for b in bounds)
        self.eps = float(eps)
        self._lock = threading.Lock()
        self.polygons: list[Polygon] = []
        ea = np.zeros((0, 2))
        self._ea, self._eb, self._vp = ea, ea, ea
        self._cp = np.zeros((0, 2))
        self._cprev = np.zeros((0, 2))
        self._cnext = np.zeros((0, 2))
        self._cactive = np.zeros(0, bool)
        self._vis = np.zeros((0, 0), np.int8)
        self._pcount = np.zeros(0, np.int64)
        #: prepare_routes' table (_CornerTable) or None; dropped when obstacles are added
        self._table: _CornerTable | None = None
        self._tree: shapely.STRtree  # set by add_obstacles below
        self.stats = {"segment_pairs": 0, "expansions": 0}
        self._prepare()
        self.add_obstacles(polygons, _initial=True)

    # -- structure --------------------------------------------------------------------------------
    @property
    def corners(self) -> np.ndarray:
        """The active auxiliary corners, shape (C, 2) ``(x, y)``."""
        return self._cp[self._cactive]

    @property
    def tree(self) -> shapely.STRtree:
        """The spatial index of ``polygons`` (a shapely STRtree; its query results index
        ``polygons``). Rebuilt, never modified, when obstacles are added: do not modify it."""
        return self._tree

    def copy(self) -> "VisibilityMap":
        """An independent copy with the same visibility cache (copied, not recomputed): adding
        obstacles to either leaves the other as it was."""
        with self._lock:
            new = copy.copy(self)
            # What add_obstacles and the search change in place; every other array is replaced,
            # never modified (see _prepare), so the copy shares it.
            new._vis = self._vis.copy()
            new._cactive = self._cactive.copy()
            new.polygons = list(self.polygons)
            new.stats = dict(self.stats)
        new._lock = threading.Lock()
        return new

    def covered(self, pts: np.ndarray, *, boundary: bool = True) -> np.ndarray:
        """True for points ``(K, 2)`` inside (or, with ``boundary``, on) an enlarged obstacle."""
        pts = np.atleast_2d(np.asarray(pts, float))
        out = np.zeros(len(pts), bool)
        if not self.polygons or len(pts) == 0:
            return out
        geoms = shapely.points(pts)
        # STRtree evaluates predicate(point, polygon): "within" is the strict interior.
        pred: Literal["intersects", "within"] = "intersects" if boundary else "within"
        ip, io = self._tree.query(geoms, predicate=pred)
        out[ip] = True
        return out

    def add_obstacles(self, polygons: Sequence[Polygon], *, _initial: bool = False) -> None:
        """Add enlarged obstacles and update the cache incrementally: corners now covered are
        dropped, cached free pairs crossing a new obstacle become blocked, the new convex corners
        join (unknown visibility)."""
        with self._lock:
            self._add_obstacles(polygons, _initial)

    def _add_obstacles(self, polygons: Sequence[Polygon], _initial: bool) -> None:
        polygons = [p for p in polygons if not p.is_empty]
        if polygons:
            self._table = None  # its distances and visibility no longer hold
        if not polygons:
            if _initial:
                self._tree = shapely.STRtree([])
            return
        ea, eb, vp, conv, pcount = _ring_edges(polygons)
        old_c = len(self._cp)
        if old_c and not _initial:
            # Old corners buried by the new obstacles, and cached free pairs they now cross.
            tree_new = shapely.STRtree(polygons)
            ip, _ = tree_new.query(shapely.points(self._cp), predicate="intersects")
            self._cactive[np.unique(ip)] = False
            i, j = np.nonzero(np.triu(self._vis == _FREE))
            if len(i):
                blocked = self._blocked_segments(self._cp[i], self._cp[j], ea, eb, vp)
                self._vis[i[blocked], j[blocked]] = _BLOCKED
                self._vis[j[blocked], i[blocked]] = _BLOCKED
        self.polygons.extend(polygons)
        self._ea = np.concatenate([self._ea, ea])
        self._eb = np.concatenate([self._eb, eb])
        self._vp = np.concatenate([self._vp, vp])
        self._pcount = np.concatenate([self._pcount, pcount])
        self._tree = shapely.STRtree(self.polygons)
        # New corners: convex, inside the bounds, and not inside or on another obstacle. A corner
        # lies on its own polygon, so count the hits and allow exactly one (its own).
        cand = ea[conv]
        xmin, ymin, xmax, ymax = self.bounds
        e = self.eps
        inb = (cand[:, 0] >= xmin - e) & (cand[:, 0] <= xmax + e) & (cand[:, 1] >= ymin - e) & (cand[:, 1] <= ymax + e)
        ip, io = self._tree.query(shapely.points(cand), predicate="intersects")
        hits = np.bincount(ip, minlength=len(cand))
        keep = inb & (hits <= 1)
        self._cp = np.concatenate([self._cp, cand])
        self._cprev = np.concatenate([self._cprev, vp[conv]])
        self._cnext = np.concatenate([self._cnext, eb[conv]])
        self._cactive = np.concatenate([self._cactive, keep])
        n = len(self._cp)
        vis = np.zeros((n, n), np.int8)
        vis[:old_c, :old_c] = self._vis
        self._vis = vis
        self._prepare()

    def _prepare(self) -> None:
        """Per-map arrays the queries use: every edge and corner quantity that does not depend on
        the query, as contiguous 1-D arrays (a query then costs a few whole-array numpy operations,
        no per-query column slicing, gathering or normalisation). Rebuilt (never modified in place)
        by add_obstacles, so a shallow copy of the map may share them."""
        ea, eb = self._ea, self._eb
        self._ax, self._ay = ea[:, 0].copy(), ea[:, 1].copy()
        self._bx, self._by = eb[:, 0].copy(), eb[:, 1].copy()
        self._ex, self._ey = self._bx - self._ax, self._by - self._ay
        e2 = self._ex * self._ex + self._ey * self._ey
        self._tol_e = self.eps * np.sqrt(e2)  # |cross(e, x - a)| below this: x is on the edge's line
        self._up = self._by > self._ay  # upward edges (the ray-crossing parity of straight_check)
        # Complex forms for the one-segment test (_segment): a, e and -conj(e).
        self._ac = self._ax + 1j * self._ay
        self._ecx = self._ex + 1j * self._ey
        self._nce = -self._ex + 1j * self._ey
        # Unit vectors from each edge's start vertex to its next and previous vertex, and whether
        # that vertex is convex (the cone test of _cone_hit).
        u1 = eb - ea
        n1 = np.hypot(u1[:, 0], u1[:, 1]) + 1e-300
        u2 = self._vp - ea
        n2 = np.hypot(u2[:, 0], u2[:, 1]) + 1e-300
        self._u1x, self._u1y = u1[:, 0] / n1, u1[:, 1] / n1
        self._u2x, self._u2y = u2[:, 0] / n2, u2[:, 1] / n2
        self._convex = _cross(-self._u2x, -self._u2y, self._u1x, self._u1y) > 0
        # Where each polygon's edges start (polygons without edges left out: reduceat needs
        # increasing starts below E).
        self._pstart = (np.cumsum(self._pcount) - self._pcount)[self._pcount > 0]
        cp = self._cp
        self._cx, self._cy = cp[:, 0].copy(), cp[:, 1].copy()
        # The corner's two edges, as vectors from the corner (tangency and tautness tests).
        self._rpx, self._rpy = self._cprev[:, 0] - self._cx, self._cprev[:, 1] - self._cy
        self._rnx, self._rny = self._cnext[:, 0] - self._cx, self._cnext[:, 1] - self._cy
        self._scan_polys = self._scan_tables() if 0 < len(ea) <= _SCALAR_MAX_EDGES else None

    def _scan_tables(self) -> tuple:
        """_scan's per-map tables: per polygon (with edges) its bounding box and its edges in
        chunks of _SCAN_EDGES consecutive edges, each chunk with the bounding box of its vertices
        and per edge the floats (ax, ay, by, ex, ey, tol_e, upward, edge index) -- the very values
        of the numpy arrays, so both forms compute the same products."""
        cols = list(zip(self._ax.tolist(), self._ay.tolist(), self._by.tolist(), self._ex.tolist(),
                        self._ey.tolist(), self._tol_e.tolist(), self._up.tolist(), range(len(self._ax))))
        # Chunk starts: every _SCAN_EDGES-th edge of each polygon (vectorized, like the boxes).
        n = self._pcount[self._pcount > 0]
        nch = (n + _SCAN_EDGES - 1) // _SCAN_EDGES
        first = np.repeat(np.cumsum(nch) - nch, nch)
        cs = np.repeat(self._pstart, nch) + _SCAN_EDGES * (np.arange(len(first)) - first)
        ce = np.minimum(cs + _SCAN_EDGES, np.repeat(self._pstart + n, nch))
        lo = np.minimum.reduceat(np.minimum(self._ea, self._eb), cs)  # (chunks, 2): x, y
        hi = np.maximum.reduceat(np.maximum(self._ea, self._eb), cs)
        pfirst = np.cumsum(nch) - nch
        plo, phi = np.minimum.reduceat(lo, pfirst), np.maximum.reduceat(hi, pfirst)
        chunks = [(x0, y0, x1, y1, tuple(cols[c0:c1]))
                  for (x0, y0), (x1, y1), c0, c1 in zip(lo.tolist(), hi.tolist(), cs.tolist(), ce.tolist())]
        polys = [(x0, y0, x1, y1, tuple(chunks[c0:c0 + k]))
                 for (x0, y0), (x1, y1), c0, k in zip(plo.tolist(), phi.tolist(), pfirst.tolist(), nch.tolist())]
        return tuple(polys)

    # -- segment tests ----------------------------------------------------------------------------
    #
    # A segment p-q enters an obstacle's interior iff it properly crosses one of its edges a-b, or
    # passes through a vertex (strictly between its ends) in a direction inside that vertex's
    # interior cone. Ends at a corner are covered by the tangency filters of the search. With
    # D = q - p, A = a - p, B = b - p, e = b - a (all crosses z-components):
    #   o1 = D x A, o2 = D x B     sides of a and b relative to the segment's line
    #   o3 = e x (p - a)           side of p relative to the edge's line (one value per edge)
    #   o4 = e x (q - a) = o3 + e x D
    # Proper crossing: o1, o2 beyond +-eps|D| with opposite signs and o3, o4 beyond +-eps|e| with
    # opposite signs. Vertex a on the segment: |o1| <= eps|D| and A.D strictly between the ends.

    def segment_free(self, p: XY, q: XY) -> bool:
        """True when the segment p-q enters no enlarged obstacle (touching is allowed)."""
        return not self._blocker(float(p[0]), float(p[1]), float(q[0]), float(q[1]))

    def straight_free(self, p: XY, q: XY) -> bool:
        """True when p and q are certainly not inside any enlarged obstacle (outside, or on a
        boundary) and the segment p-q enters none: then p-q is the shortest route (see
        straight_check)."""
        return self.straight_check(p, q) == 1

    def straight_check(self, p: XY, q: XY) -> int:
        """The ends and the segment p-q at once: 1 when both ends are certainly not inside any
        enlarged obstacle (outside, or on a boundary) and the segment enters none -- then p-q is
        the shortest route, and the full checks (shapely point queries) and the search would say
        exactly that; 0 when both ends are certainly outside but the segment enters an obstacle
        (the endpoint checks would pass both ends unchanged: only the search is left); -1 when an
        end is inside an obstacle or too close to an edge to decide here (the full checks decide).

        The ends: a ray-crossing parity per polygon that reuses the segment test's cross products
        e x (end - a). The straddle test (half-open in y) is exact; the side test is trusted only
        beyond eps from the edge's line (else -1), so the parity is exact whenever it is used.
        A ray to +x crosses an upward edge with the end on its left (cross > 0), a downward one
        with the end on its right."""
        px, py, qx, qy = float(p[0]), float(p[1]), float(q[0]), float(q[1])
        if self._scan_polys is not None:
            if self._ends_undecided(px, py, qx, qy):
                return -1
            return 0 if self._scan(px, py, qx, qy) else 1
        if len(self._ax) == 0:
            return 1
        blocked, o3, o4 = self._segment(px, py, qx, qy)
        # Row 0: p, row 1: q.
        o = np.stack((o3, o4))
        y = np.array(((py,), (qy,)))
        straddle = (self._ay > y) != (self._by > y)
        if (straddle & (np.abs(o) <= self._tol_e)).any():
            return -1
        cross = straddle & ((o > 0) == self._up)
        if (np.add.reduceat(cross.view(np.uint8), self._pstart, axis=1) & 1).any():
            return -1
        return 0 if blocked else 1

    def _scan(self, px: float, py: float, qx: float, qy: float):
        """The one-segment test in plain Python: on small maps a few dozen float operations cost
        less than the fixed overhead of ~30 numpy calls. The same predicates, tolerances and
        products as _segment; bounding boxes only skip polygons and chunks whose vertex box misses
        the segment's box grown by 4 eps (a proper crossing, signs beyond the tolerances, far
        above rounding, needs the segments to meet; a vertex on the segment lies within eps of
        it), and polygons whose box lies beyond 2 eps|D| on one side of the segment's line.

        Returns False when the segment is free, else a true value: the chunks of the polygon one
        of whose edges it properly crosses (see _blocker), or True (a vertex's cone decided).
        """
        dx, dy = qx - px, qy - py
        L2 = dx * dx + dy * dy
        eps = self.eps
        tol_s = eps * math.sqrt(L2)
        pad = 4 * eps
        if px < qx:
            sx0, sx1 = px - pad, qx + pad
        else:
            sx0, sx1 = qx - pad, px + pad
        if py < qy:
            sy0, sy1 = py - pad, qy + pad
        else:
            sy0, sy1 = qy - pad, py + pad
        on, tested = None, 0
        # The segment's line, f(x, y) = D x ((x, y) - p) (o1 of a vertex): a polygon's box whose
        # corners all lie beyond 2 tol_s on one side (rounding is far below tol_s) holds no edge
        # that crosses the segment and no vertex on it.
        m = 2 * tol_s
        dxp, dyp = dx > 0, dy > 0
        for x0, y0, x1, y1, chunks in self._scan_polys or ():  # (called only when there are tables)
            if not (x0 <= sx1 and x1 >= sx0 and y0 <= sy1 and y1 >= sy0):
                continue
            if dxp:
                fhi, flo = dx * (y1 - py), dx * (y0 - py)
            else:
                fhi, flo = dx * (y0 - py), dx * (y1 - py)
            if dyp:
                fhi, flo = fhi - dy * (x0 - px), flo - dy * (x1 - px)
            else:
                fhi, flo = fhi - dy * (x1 - px), flo - dy * (x0 - px)
            if not (flo <= m and fhi >= -m):
                continue
            for x0, y0, x1, y1, edges in chunks:
                if not (x0 <= sx1 and x1 >= sx0 and y0 <= sy1 and y1 >= sy0):
                    continue
                tested += len(edges)
                for ax, ay, by, ex, ey, te, up, i in edges:
                    Ax, Ay = ax - px, ay - py
                    o1 = dx * Ay - dy * Ax  # D x A
                    De = dx * ey - dy * ex  # D x e
                    o2 = o1 + De  # D x (A + e)
                    if o1 * o2 < 0:
                        o3 = ey * Ax - ex * Ay  # e x (p - a)
                        o4 = o3 - De  # e x (q - a)
                        if o3 * o4 < 0 and abs(o1) > tol_s and abs(o2) > tol_s and abs(o3) > te and abs(o4) > te:
                            self.stats["segment_pairs"] += tested
                            return chunks  # the blocking polygon: _blocker's hint
                    if abs(o1) <= tol_s:
                        t = dx * Ax + dy * Ay
                        if tol_s < t < L2 - tol_s:
                            if on is None:
                                on = []
                            on.append(i)
        self.stats["segment_pairs"] += tested
        if on is not None:
            # A vertex strictly inside the segment (rare): the numpy cone test decides.
            ee = np.array(on)
            k = len(ee)
            return bool(_enters_cone(self, ee, np.full(k, dx), np.full(k, dy), self._ax[ee] - px,
                                     self._ay[ee] - py).any())
        return False

    def _ends_undecided(self, px: float, py: float, qx: float, qy: float) -> bool:
        """straight_check's test of its ends, in plain Python on _scan's tables: True when p or q
        is inside an enlarged obstacle or too close to an edge to decide (within eps of the line
        of an edge that straddles its y). A ray-crossing parity per polygon over the edges that
        straddle the end's y (the half-open straddle test is exact; the side test, e x (end - a),
        is trusted only beyond eps from the edge's line, so the parity is exact whenever it is
        used): a ray to +x crosses an upward edge with the end on its left (cross > 0), a
        downward one with the end on its right. Polygons and chunks whose vertices' y-range
        [ymin, ymax) does not hold the end's y are skipped: none of their edges straddles it.

        e x (q - a) is computed as e x (p - a) - D x e, as the segment test computes it. Separate
        from the segment test, which then stops at its first crossing (most straight lines of
        the service's queries are blocked; a pass doing both had to go through every polygon)."""
        dx, dy = qx - px, qy - py
        for _, y0, _, y1, chunks in self._scan_polys or ():
            hp = y0 <= py < y1
            hq = y0 <= qy < y1
            if not (hp or hq):
                continue
            cp = cq = False
            for _, y0, _, y1, edges in chunks:
                cpp = hp and y0 <= py < y1
                cqq = hq and y0 <= qy < y1
                if not (cpp or cqq):
                    continue
                for ax, ay, by, ex, ey, te, up, _ in edges:
                    if cpp and (ay > py) != (by > py):
                        o3 = ey * (ax - px) - ex * (ay - py)
                        if abs(o3) <= te:
                            return True
                        if (o3 > 0) == up:
                            cp = not cp
                    if cqq and (ay > qy) != (by > qy):
                        o4 = (ey * (ax - px) - ex * (ay - py)) - (dx * ey - dy * ex)
                        if abs(o4) <= te:
                            return True
                        if (o4 > 0) == up:
                            cq = not cq
            if cp or cq:
                return True
        return False

    def _segment(self, px: float, py: float, qx: float, qy: float):
        """One segment p-q against every edge: (blocked, o3, o4), o3 and o4 per edge.

        The lean form of _fan_blocked for one segment (the straight-line test of every query and
        OMPL's motion checks): complex products give two crosses (and a dot) per operation, and
        the tolerance tests run only on the few edges whose signs already differ."""
        E = len(self._ac)
        if E == 0:
            z = np.zeros(0)
            return False, z, z
        A = self._ac - complex(px, py)  # the edges' start vertices a, relative to p
        dx, dy = qx - px, qy - py
        cd = complex(dx, -dy)  # conj(D)
        P1 = cd * A  # real: A . D, imag: D x A = o1
        o1 = P1.imag
        o3 = (self._nce * A).imag  # -conj(e) * A: e x (p - a)
        De = (cd * self._ecx).imag  # D x e
        o2 = o1 + De  # D x (a + e - p)
        o4 = o3 - De  # e x (q - a)
        L2 = dx * dx + dy * dy
        tol_s = self.eps * math.sqrt(L2)
        self.stats["segment_pairs"] += E
        # A proper crossing has strictly opposite signs on both lines: the products pick the
        # candidates, the tolerances (_proper) decide.
        c = np.flatnonzero((o1 * o2 < 0) & (o3 * o4 < 0))
        if len(c) and _proper(o1[c], o2[c], o3[c], o4[c], tol_s, self._tol_e[c]).any():
            return True, o3, o4
        on = np.flatnonzero(np.abs(o1) <= tol_s)
        if len(on):
            t = P1.real[on]
            on = on[(t > tol_s) & (t < L2 - tol_s)]
            if len(on) and _enters_cone(self, on, np.full(len(on), dx), np.full(len(on), dy), A.real[on],
                                        A.imag[on]).any():
                return True, o3, o4
        return False, o3, o4

    def _fan_blocked(self, p: np.ndarray, qx: np.ndarray, qy: np.ndarray) -> np.ndarray:
        """For K segments from the one point p to (qx[k], qy[k]), True where one enters an
        obstacle's interior. Dense K x E arrays up to _DENSE_LIMIT pairs, above that only the
        (segment, edge) pairs the angular pre-filter keeps (_fan_pairs).

        Candidates first: a proper crossing needs strictly opposite signs of o1, o2 and of o3, o4
        (sign products), a vertex on the segment |o1| <= eps|D|; the tolerance tests run on those
        few pairs only (17 instead of 30 whole-array operations per batch)."""
        K, E = len(qx), len(self._ax)
        out = np.zeros(K, bool)
        if K == 0 or E == 0:
            return out
        px, py = float(p[0]), float(p[1])
        Ax, Ay = self._ax - px, self._ay - py
        ex, ey, tol_e = self._ex, self._ey, self._tol_e
        o3 = ey * Ax - ex * Ay  # per edge: the fan's common start p
        Dx, Dy = qx - px, qy - py
        L2 = Dx * Dx + Dy * Dy
        tol_s = self.eps * np.sqrt(L2)
        if K * E <= _DENSE_LIMIT:
            self.stats["segment_pairs"] += K * E
            dx, dy = Dx[:, None], Dy[:, None]
            o1 = dx * Ay - dy * Ax  # (K, E)
            De = dx * ey - dy * ex
            o2, o4 = o1 + De, o3 - De
            kk, ee = np.nonzero((o1 * o2 < 0) & (o3 * o4 < 0))
            if len(kk):
                hit = _proper(o1[kk, ee], o2[kk, ee], o3[ee], o4[kk, ee], tol_s[kk], tol_e[ee])
                out[kk[hit]] = True
            kk, ee = np.nonzero(np.abs(o1) <= tol_s[:, None])
        else:
            k, e = self._fan_pairs(Ax, Ay, self._bx - px, self._by - py, Dx, Dy, L2)
            self.stats["segment_pairs"] += len(k)
            if len(k) == 0:
                return out
            dx, dy, o3e = Dx[k], Dy[k], o3[e]
            o1 = dx * Ay[e] - dy * Ax[e]
            De = dx * ey[e] - dy * ex[e]
            o2, o4 = o1 + De, o3e - De
            c = np.flatnonzero((o1 * o2 < 0) & (o3e * o4 < 0))
            if len(c):
                hit = _proper(o1[c], o2[c], o3e[c], o4[c], tol_s[k[c]], tol_e[e[c]])
                out[k[c[hit]]] = True
            c = np.flatnonzero(np.abs(o1) <= tol_s[k])
            kk, ee = k[c], e[c]
        # Vertex a strictly between the ends (A . D beyond eps|D| from 0 and |D|^2): cone test.
        if len(kk):
            t = Ax[ee] * Dx[kk] + Ay[ee] * Dy[kk]
            ts = tol_s[kk]
            sel = (t > ts) & (t < L2[kk] - ts) & ~out[kk]
            if sel.any():
                kk, ee = kk[sel], ee[sel]
                hit = _enters_cone(self, ee, Dx[kk], Dy[kk], Ax[ee], Ay[ee])
                out[kk[hit]] = True
        return out

    def _fan_pairs(self, Ax, Ay, Bx, By, Dx, Dy, L2):
        """Candidate (segment, edge) pairs of a fan (edges and segment ends relative to its start):
        an edge can only meet a segment whose direction lies within the edge's angular extent seen
        from the start (+-1e-9 rad). Directions sorted once, each edge's interval found with
        searchsorted."""
        K = len(Dx)
        ang = np.arctan2(Dy, Dx)
        order = np.argsort(ang)
        A = ang[order]
        # The sorted directions three times (shifted by -2 pi, 0, 2 pi): an interval that wraps
        # around +-pi is then one range of this array, read modulo K.
        A3 = np.concatenate((A - 2 * np.pi, A, A + 2 * np.pi))
        ta, tb = np.arctan2(Ay, Ax), np.arctan2(By, Bx)
        # The edge's interval, counter-clockwise from lo over w (< pi unless the start is on it).
        lo, hi = np.minimum(ta, tb), np.maximum(ta, tb)
        w = hi - lo
        wr = w > np.pi
        lo = np.where(wr, hi, lo)
        w = np.where(wr, 2 * np.pi - w, w)
        # (A reach filter, dropping pairs whose segment ends before the edge's nearest point, cost
        # more than it saved: it kept 75 % of the pairs on rect-200.)
        st = np.searchsorted(A3, lo - 1e-9, "left")
        cnt = np.searchsorted(A3, lo + (w + 1e-9), "right") - st
        total = int(cnt.sum())
        if total == 0:
            return np.zeros(0, np.int64), np.zeros(0, np.int64)
        csum = np.cumsum(cnt)
        e = np.repeat(np.arange(len(lo)), cnt)
        k = order[(np.arange(total) + np.repeat(st - (csum - cnt), cnt)) % K]
        return k, e

    def _blocked_segments(self, P: np.ndarray, Q: np.ndarray, ea, eb, vp) -> np.ndarray:
        """For K segments P[k]-Q[k] with different starts, True where one enters the interior of
        an obstacle with edges ea -> eb (vp: the vertex before ea). Dense, in row chunks that bound
        the temporaries. The incremental update after new obstacles uses it (old pairs x new edges)."""
        K, E = len(P), len(ea)
        out = np.zeros(K, bool)
        if K == 0 or E == 0:
            return out
        self.stats["segment_pairs"] += K * E
        ax, ay = ea[:, 0], ea[:, 1]
        ex, ey = eb[:, 0] - ax, eb[:, 1] - ay
        tol_e = self.eps * np.sqrt(ex * ex + ey * ey)
        step = max(1, _CHUNK_PAIRS // E)
        for c0 in range(0, K, step):
            px, py = P[c0:c0 + step, 0:1], P[c0:c0 + step, 1:2]
            Dx, Dy = Q[c0:c0 + step, 0:1] - px, Q[c0:c0 + step, 1:2] - py
            Ax, Ay = ax - px, ay - py
            o3 = ey * Ax - ex * Ay
            L2 = Dx * Dx + Dy * Dy
            proper, on = _crossings(Ax, Ay, o3, ex, ey, tol_e, Dx, Dy, L2, self.eps * np.sqrt(L2))
            if on.any():
                kk, ee = np.nonzero(on)
                hit = _enters_cone_at(ea[ee], vp[ee], eb[ee], Dx[kk, 0], Dy[kk, 0], Ax[kk, ee], Ay[kk, ee], self.eps)
                proper[kk[hit], ee[hit]] = True
            out[c0:c0 + step] = proper.any(axis=1)
        return out

    # -- search -----------------------------------------------------------------------------------
    def prepare_routes(self) -> bool:
        """Precompute what every search on this map shares, once: which pairs of active corners
        see each other and the shortest distances between all corners (with the next corner of
        each shortest route). ``shortest_path`` then only finds the corners its start and its
        goal see, and takes the best pair of them: no A*, no visibility test between corners.
        The same lengths as the A* (both are exact; equal-length routes may differ in the
        corners they pass).

        Only bitangent pairs enter the table: a shortest route leaves and reaches a corner along
        a line that cuts into neither corner (the A*'s tangency and tautness filters keep a
        subset of these). The pairs' visibility is the search's own test (``_fan_blocked``),
        and fills the same cache.

        Returns False (and builds nothing) above _TABLE_MAX_CORNERS active corners. Adding
        obstacles drops the table (searches are A* again until the next call).
        """
        with self._lock:
            if self._table is None:
                act = np.flatnonzero(self._cactive)
                if len(act) > _TABLE_MAX_CORNERS:
                    return False
                self._table = self._corner_table(act)
            return True

    def _corner_table(self, act: np.ndarray) -> "_CornerTable":
        n = len(act)
        X, Y = self._cx[act], self._cy[act]
        rpx, rpy, rnx, rny = self._rpx[act], self._rpy[act], self._rnx[act], self._rny[act]
        dist = np.full((n, n), np.inf)
        np.fill_diagonal(dist, 0.0)
        vis = self._vis
        for a in range(n - 1):
            b = np.arange(a + 1, n)
            dx, dy = X[b] - X[a], Y[b] - Y[a]
            d = np.hypot(dx, dy)
            ok = _not_cut(dx, dy, d, rpx[b], rpy[b], rnx[b], rny[b], self.eps) & \
                _not_cut(dx, dy, d, rpx[a], rpy[a], rnx[a], rny[a], self.eps)
            b, d = b[ok], d[ok]
            u, v = act[a], act[b]
            row = vis[u, v]
            unk = row == _UNKNOWN
            if unk.any():
                bl = self._fan_blocked(self._cp[u], X[b[unk]], Y[b[unk]])
                vals = np.where(bl, _BLOCKED, _FREE).astype(np.int8)
                vis[u, v[unk]] = vals
                vis[v[unk], u] = vals
                row[unk] = vals
            free = row == _FREE
            dist[a, b[free]] = d[free]
            dist[b[free], a] = d[free]
        # Floyd-Warshall, one intermediate corner k at a time over the whole matrix; nxt[i, j]:
        # the corner after i on the shortest route from i to j.
        nxt = np.tile(np.arange(n), (n, 1))
        for k in range(n):
            via = dist[:, k, None] + dist[k]
            better = via < dist
            if better.any():
                dist = np.where(better, via, dist)
                nxt = np.where(better, nxt[:, k, None], nxt)
        return _CornerTable(X, Y, rpx, rpy, rnx, rny, dist, nxt)

    def _table_path(self, t: "_CornerTable", s: np.ndarray, g: np.ndarray) -> tuple[np.ndarray, float]:
        """shortest_path on prepare_routes' table (the segment s-g already found blocked).

        The route is s, a first corner i, the table's shortest route to a last corner j, g, with
        s seeing i and g seeing j along lines tangent at the corner (as the A* takes them). Lazy:
        the pairs in order of their length as if both were seen, each end tested (the one-segment
        test) when its pair comes first; an end that is hidden drops its row or column. The first
        pair whose ends are both seen is the shortest. After _LAZY_TESTS hidden ends, the fans
        (every candidate corner at once) decide the rest."""
        (ds, cs), (dg, cg) = self._tangents_from(t, s, g)
        if len(cg) == 0:
            raise NoRouteError("no route: the goal is enclosed (no corner sees it)")
        # (ns, ng) pair lengths as if both ends were seen. Two takes and in-place sums: half the
        # time of a 2-D fancy index on the service benchmark's ~85 x 85 (the same sums).
        total = t.dist.take(cs, axis=0).take(cg, axis=1)
        total += ds[:, None]
        total += dg
        flat = total.ravel()  # a view
        ns, ng = len(cs), len(cg)
        # Python lists and floats in the loop: numpy scalar reads cost more than the argmin.
        seen_s, seen_g = [False] * ns, [False] * ng
        sx, sy, gx, gy = float(s[0]), float(s[1]), float(g[0]), float(g[1])
        xl, yl, csl, cgl = t.xl, t.yl, cs.tolist(), cg.tolist()
        blocker = self._blocker
        hint_s = hint_g = None  # what blocked the last hidden end's segment, each end's
        hidden = 0
        while total.size:
            k = int(total.argmin())
            if not math.isfinite(flat[k]):
                break
            i, j = divmod(k, ng)
            if not seen_s[i]:
                hit = blocker(sx, sy, xl[csl[i]], yl[csl[i]], hint_s)
                if hit:
                    total[i] = np.inf
                    hidden += 1
                    hint_s = hit
                else:
                    seen_s[i] = True
            if seen_s[i] and not seen_g[j]:
                hit = blocker(gx, gy, xl[cgl[j]], yl[cgl[j]], hint_g)
                if hit:
                    total[:, j] = np.inf
                    hidden += 1
                    hint_g = hit
                else:
                    seen_g[j] = True
            if seen_s[i] and seen_g[j]:
                return self._table_route(t, s, g, csl[i], cgl[j]), float(flat[k])
            if hidden >= _LAZY_TESTS:
                # Many hidden ends: test every candidate left at once (the fans).
                rows = np.flatnonzero(~np.array(seen_s) & np.isfinite(total).any(1))
                cols = np.flatnonzero(~np.array(seen_g) & np.isfinite(total).any(0))
                total[rows[self._fan_blocked(s, t.x[cs[rows]], t.y[cs[rows]])]] = np.inf
                total[:, cols[self._fan_blocked(g, t.x[cg[cols]], t.y[cg[cols]])]] = np.inf
                k = int(total.argmin())
                if not math.isfinite(flat[k]):
                    break
                i, j = divmod(k, ng)
                return self._table_route(t, s, g, int(cs[i]), int(cg[j])), float(flat[k])
        if not (~self._fan_blocked(g, t.x[cg], t.y[cg])).any():
            raise NoRouteError("no route: the goal is enclosed (no corner sees it)")
        raise NoRouteError("no route: start and goal are not connected (search exhausted)")

    def _blocker(self, px: float, py: float, qx: float, qy: float, hint=None):
        """Whether the segment p-q enters an enlarged obstacle (segment_free's test on floats):
        False, or a true value; with _scan's tables the blocking polygon's chunks when one of its
        edges is properly crossed (else True).

        ``hint``: such chunks, from the previous blocked test from the same end, tested first.
        The tests of a table query from one end are mostly blocked (76 % on the service
        benchmark's floor), 71 % of them by the same obstacle as the previous one; a proper
        crossing of any edge blocks the segment whatever else it meets, so this only skips the
        other polygons (the same answers)."""
        if self._scan_polys is None:
            return self._segment(px, py, qx, qy)[0]
        if hint is not None and hint is not True:
            dx, dy = qx - px, qy - py
            tol_s = self.eps * math.sqrt(dx * dx + dy * dy)
            for _, _, _, _, edges in hint:
                for ax, ay, by, ex, ey, te, up, i in edges:
                    # _scan's proper crossing, the same products and tolerances
                    Ax, Ay = ax - px, ay - py
                    o1 = dx * Ay - dy * Ax
                    De = dx * ey - dy * ex
                    o2 = o1 + De
                    if o1 * o2 < 0:
                        o3 = ey * Ax - ex * Ay
                        o4 = o3 - De
                        if o3 * o4 < 0 and abs(o1) > tol_s and abs(o2) > tol_s and abs(o3) > te and abs(o4) > te:
                            return hint
        return self._scan(px, py, qx, qy)

    def _tangents_from(self, t: "_CornerTable", s: np.ndarray, g: np.ndarray):
        """For each of s and g: the distances to the table's corners it may reach along a line
        tangent at the corner, and their indices (seen or not). Both ends in one pass of (2, C)
        arrays.

        _not_cut's products and comparisons, in fewer numpy calls (in place; "not (max > tol and
        min < -tol)" as "max <= tol or min >= -tol": the same for the finite values here): 25
        against 32 us per query on the service benchmark's floor, the same corners."""
        e = np.array(((s[0],), (g[0],), (s[1],), (g[1],)), float)
        dx = t.x - e[:2]
        dy = t.y - e[2:]
        d = np.hypot(dx, dy)
        a = dx * t.rpy
        a -= dy * t.rpx
        b = dx * t.rny
        b -= dy * t.rnx
        tol = self.eps * d
        hi = np.maximum(a, b)
        lo = np.minimum(a, b, out=a)
        ok = (hi <= tol) | (lo >= np.negative(tol, out=b))
        cs, cg = ok[0].nonzero()[0], ok[1].nonzero()[0]
        return (d[0][cs], cs), (d[1][cg], cg)

    @staticmethod
    def _table_route(t: "_CornerTable", s: np.ndarray, g: np.ndarray, a: int, b: int) -> np.ndarray:
        """s, the table's shortest route from corner a to corner b, g: shape (M, 2)."""
        xl, yl, nxt = t.xl, t.yl, t.nxt
        pts = [(float(s[0]), float(s[1])), (xl[a], yl[a])]
        while a != b:
            a = int(nxt[a, b])
            pts.append((xl[a], yl[a]))
        pts.append((float(g[0]), float(g[1])))
        return np.array(pts)

    def shortest_path(self, start: XY, goal: XY, *, should_stop=None,
                      straight_blocked: bool = False) -> tuple[np.ndarray, float]:
        """Euclidean-shortest route from start to goal, shape (M, 2) ``(x, y)``, and its length.

        Start and goal must be free points inside the bounds. Raises NoRouteError when the search
        is exhausted (a proof that no route exists). ``should_stop()`` is polled per expansion
        (OMPL's termination condition); stopping early raises NoRouteError with reason timeout.
        ``straight_blocked``: the caller already found the segment start-goal blocked (the same
        test, straight_check), so it is not tested again.

        The search reads and fills the visibility cache: it holds the map's lock.
        """
        with self._lock:
            return self._shortest_path(start, goal, should_stop, straight_blocked)

    def _shortest_path(self, start, goal, should_stop, straight_blocked) -> tuple[np.ndarray, float]:
        s = np.asarray(start, float)
        g = np.asarray(goal, float)
        if not straight_blocked and self.segment_free(s, g):
            return np.stack([s, g]), float(np.hypot(*(g - s)))
        if self._table is not None:
            return self._table_path(self._table, s, g)
        C = len(self._cp)
        S, G = C, C + 1
        eps = self.eps
        ang_eps = 1e-12
        X, Y = self._cx, self._cy
        rpx, rpy, rnx, rny = self._rpx, self._rpy, self._rnx, self._rny

        def not_cut(dx, dy, n):
            return _not_cut(dx, dy, n, rpx, rpy, rnx, rny, eps)

        # Goal row: corners that see the goal (the last segment, tangent at the corner).
        dxg, dyg = X - g[0], Y - g[1]
        hgoal_c = np.hypot(dxg, dyg)  # also the A* heuristic of every corner
        cand = np.flatnonzero(self._cactive & not_cut(dxg, dyg, hgoal_c))
        goal_vis = np.zeros(C, bool)
        if len(cand):
            goal_vis[cand[~self._fan_blocked(g, X[cand], Y[cand])]] = True
        if not goal_vis.any():
            raise NoRouteError("no route: the goal is enclosed (no corner sees it)")

        gs = np.full(C + 2, np.inf)
        gs_c = gs[:C]  # a view: the corners' g values
        parent = np.full(C + 2, -1, np.int64)
        open_c = self._cactive.copy()  # active corners not closed yet
        gs[S] = 0.0
        heap = [(float(np.hypot(*(g - s))), 0.0, S)]
        pos = np.concatenate([self._cp, s[None], g[None]])
        vis = self._vis
        gx, gy = float(g[0]), float(g[1])
        closed_s = False
        expansions = 0
        while heap:
            f, gu, u = heapq.heappop(heap)
            if gu > gs[u]:
                continue
            if u == G:
                path = [G]
                while path[-1] != S:
                    path.append(int(parent[path[-1]]))
                self.stats["expansions"] += expansions
                return pos[path[::-1]].copy(), float(gs[G])
            if u == S:
                if closed_s:
                    continue
                closed_s = True
            else:
                if not open_c[u]:
                    continue
                open_c[u] = False
            expansions += 1
            if should_stop is not None and should_stop():
                raise NoRouteError("no route found before the time limit (timeout)")
            ux, uy = float(pos[u, 0]), float(pos[u, 1])
            # Every open corner at once (whole-array operations beat gathering a subset first).
            dx, dy = X - ux, Y - uy
            n = np.hypot(dx, dy)
            newg = gu + n
            ok = open_c & (newg < gs_c) & not_cut(dx, dy, n)
            goal_ok = u != S and goal_vis[u]
            if u != S:
                # Taut: the obstacle at u stays on the inner side of the turn parent -> u -> v.
                pp = pos[parent[u]]
                d1x, d1y = ux - pp[0], uy - pp[1]
                n1 = math.hypot(d1x, d1y) + 1e-300
                d1x, d1y = d1x / n1, d1y / n1
                ax, ay, bx, by = rpx[u], rpy[u], rnx[u], rny[u]
                side = np.sign((d1x * ay - d1y * ax) + (d1x * by - d1y * bx))
                if side != 0:
                    # side * cross(d / n, r) >= -eps for both edges r of u, and the turn d1 -> d
                    # goes to that side (angles to 1e-12): multiplied through by n.
                    tol = eps * n
                    ok &= (side * (dx * ay - dy * ax) >= -tol) & (side * (dx * by - dy * bx) >= -tol) & \
                          (side * (d1x * dy - d1y * dx) >= -ang_eps * n)
                    if goal_ok:
                        dgx, dgy = gx - ux, gy - uy
                        ng = math.hypot(dgx, dgy) + 1e-300
                        dgx, dgy = dgx / ng, dgy / ng
                        goal_ok = (side * (dgx * ay - dgy * ax) >= -eps) and \
                                  (side * (dgx * by - dgy * bx) >= -eps) and \
                                  (side * (d1x * dgy - d1y * dgx) >= -ang_eps)
                if goal_ok:
                    ng = gu + math.hypot(gx - ux, gy - uy)
                    if ng < gs[G]:
                        gs[G] = ng
                        parent[G] = u
                        heapq.heappush(heap, (ng, ng, G))
            idx = np.flatnonzero(ok)
            if len(idx) == 0:
                continue
            if u == S:
                free = ~self._fan_blocked(pos[S], X[idx], Y[idx])
            else:
                # Visibility of u's candidates: cached, or tested now (one batch) and cached.
                row = vis[u, idx]
                unk = row == _UNKNOWN
                if unk.any():
                    ui = idx[unk]
                    bl = self._fan_blocked(pos[u], X[ui], Y[ui])
                    vals = np.where(bl, _BLOCKED, _FREE).astype(np.int8)
                    vis[u, ui] = vals
                    vis[ui, u] = vals
                    row[unk] = vals
                free = row == _FREE
            idx = idx[free]
            newg = newg[idx]
            gs[idx] = newg
            parent[idx] = u
            for fv, gv, v in zip((newg + hgoal_c[idx]).tolist(), newg.tolist(), idx.tolist()):
                heapq.heappush(heap, (fv, gv, v))
        self.stats["expansions"] += expansions
        raise NoRouteError("no route: start and goal are not connected (search exhausted)")


def _not_cut(dx, dy, n, rpx, rpy, rnx, rny, eps) -> np.ndarray:
    """Tangent at a corner: a segment along d (|d| = n) through the corner, whose edges are the
    vectors rp and rn from it, must not cut into the corner's interior cone, i.e. its two edges
    must not lie strictly on opposite sides of d (sides beyond eps, as with unit d). A property
    of the line: the same for d and -d."""
    a = dx * rpy - dy * rpx
    b = dx * rny - dy * rnx
    tol = eps * n
    return ~((np.maximum(a, b) > tol) & (np.minimum(a, b) < -tol))


@dataclass(frozen=True)
class _CornerTable:
    """prepare_routes' table over the C active corners: their positions ``x``, ``y`` (C,), their
    edge vectors (the tangency test), ``dist`` (C, C) the shortest distances between them
    (inf: not connected) and ``nxt`` (C, C) the corner after i on the shortest route from i to
    j. Never modified: copies of the map share it."""

    x: np.ndarray
    y: np.ndarray
    rpx: np.ndarray
    rpy: np.ndarray
    rnx: np.ndarray
    rny: np.ndarray
    dist: np.ndarray
    nxt: np.ndarray
    #: ``x`` and ``y`` as Python lists (a query's few one-segment tests read single corners)
    xl: list = field(init=False, repr=False)
    yl: list = field(init=False, repr=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "xl", self.x.tolist())
        object.__setattr__(self, "yl", self.y.tolist())


def _ring_edges(polygons: Sequence[Polygon]):
    """Every ring of the polygons (each exterior, then its holes; rings not closed, interiors on
    the left of their edges as enlarge orients them, rings of fewer than 3 vertices skipped): the
    edge start vertices ``ea`` (E, 2), the next ``eb`` and previous ``vp`` vertices, whether
    ``ea`` is a convex vertex (interior turns left there: an auxiliary corner) and the edge count
    of each polygon. Vectorized: a loop of np.roll per ring cost ~1.5 ms of a 200-rectangle
    map's build."""
    rr, pidx = shapely.get_rings(np.asarray(polygons, dtype=object), return_index=True)
    coords, ridx = shapely.get_coordinates(rr, return_index=True)
    counts = np.bincount(ridx, minlength=len(rr))  # vertices + the closing repeat
    n = counts - 1
    good = n >= 3
    keep = np.repeat(good, counts)
    keep[np.cumsum(counts)[counts > 0] - 1] = False  # the closing repeats
    ea = coords[keep]
    n = n[good]
    first = np.repeat(np.cumsum(n) - n, n)  # each vertex's ring start, and that ring's end
    last = first + np.repeat(n, n) - 1
    i = np.arange(len(ea))
    eb = ea[np.where(i == last, first, i + 1)]
    vp = ea[np.where(i == first, last, i - 1)]
    a, b = ea - vp, eb - ea
    conv = (a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]) > 0
    pcount = np.bincount(pidx[good], weights=n, minlength=len(polygons)).astype(np.int64)
    return ea, eb, vp, conv, pcount


def _proper(a1, a2, a3, a4, ts, te) -> np.ndarray:
    """Proper crossing with tolerances: o1, o2 beyond +-eps|D| with opposite signs, and o3, o4
    beyond +-eps|e| with opposite signs (same-shaped or broadcastable arrays)."""
    return (np.maximum(a1, a2) > ts) & (np.minimum(a1, a2) < -ts) & \
           (np.maximum(a3, a4) > te) & (np.minimum(a3, a4) < -te)


def _crossings(Ax, Ay, o3, ex, ey, tol_e, Dx, Dy, L2, tol_s):
    """(proper, on) for segments D from p and edges from A (relative to p) along e (see the
    comment above segment_free; any broadcastable shapes): proper crossings, and vertex a on the
    segment strictly between its ends (then the cone test decides)."""
    o1 = Dx * Ay - Dy * Ax
    De = Dx * ey - Dy * ex  # D x e: o2 = D x (A + e), o4 = e x (D - A) = o3 - D x e
    proper = _proper(o1, o1 + De, o3, o3 - De, tol_s, tol_e)
    t = Ax * Dx + Ay * Dy
    on = (np.abs(o1) <= tol_s) & (t > tol_s) & (t < L2 - tol_s)
    return proper, on


def _enters_cone(vm: "VisibilityMap", ee, dx, dy, ax, ay) -> np.ndarray:
    """True where a segment (direction (dx, dy), the vertex at (ax, ay) from its start) that
    passes through the start vertex of the map's edge ee enters that vertex's interior cone (the
    unit edge vectors precomputed by _prepare)."""
    return _cone_hit(vm._u1x[ee], vm._u1y[ee], vm._u2x[ee], vm._u2y[ee], vm._convex[ee], dx, dy, ax, ay, vm.eps)


def _enters_cone_at(v, vprev, vnext, dx, dy, ax, ay, eps) -> np.ndarray:
    """_enters_cone for vertices given as (K, 2) arrays v with their ring neighbours."""
    e1, e2 = vnext - v, vprev - v
    n1 = np.hypot(e1[:, 0], e1[:, 1]) + 1e-300
    n2 = np.hypot(e2[:, 0], e2[:, 1]) + 1e-300
    u1x, u1y, u2x, u2y = e1[:, 0] / n1, e1[:, 1] / n1, e2[:, 0] / n2, e2[:, 1] / n2
    return _cone_hit(u1x, u1y, u2x, u2y, _cross(-u2x, -u2y, u1x, u1y) > 0, dx, dy, ax, ay, eps)


def _cone_hit(u1x, u1y, u2x, u2y, convex, dx, dy, ax, ay, eps) -> np.ndarray:
    """The cone test: interior on the left of the ring prev -> v -> next, u1 the unit vector
    v -> next, u2 the unit vector v -> prev; the segment passes through v in direction d, with
    length lf after v and lb before it (v at (ax, ay) from the segment's start).

    With unit d, c1 = u1 x d and c2 = d x u2: at a convex vertex the part after v enters when c1
    and c2 are both positive, the part before v when both are negative; at a reflex vertex the
    interior is all but the closed exterior cone from u2 to u1, entered by the part after v when
    c1 or c2 is positive, by the part before v when one is negative. "Enters" means deeper than
    the tolerance: a part of length l at sine c from an edge reaches l * c from it, so c must
    exceed eps / l. (A plain angular eps wrongly blocked a segment leaving a corner along a
    bevel edge a few eps long: its neighbour vertex was "on" the segment, at 0.17 rad.)"""
    n = np.hypot(dx, dy) + 1e-300
    dx, dy = dx / n, dy / n
    lb = ax * dx + ay * dy
    tf = eps / np.maximum(n - lb, 1e-300)
    tb = eps / np.maximum(lb, 1e-300)
    c1 = u1x * dy - u1y * dx
    c2 = dx * u2y - dy * u2x
    convex_hit = ((c1 > tf) & (c2 > tf)) | ((c1 < -tb) & (c2 < -tb))
    reflex_hit = (c1 > tf) | (c2 > tf) | (c1 < -tb) | (c2 < -tb)
    return np.where(convex, convex_hit, reflex_hit)
