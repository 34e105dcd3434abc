"""The exact auxiliary-corner search: a lazy visibility graph over the convex corners of the
enlarged obstacles, searched with A*, its visibility cache kept for later queries.

Coordinates are world ``(x, y)``, y up. Obstacles given here are already enlarged (robot radius +
margin + tolerance); a point is free when it is outside or on the boundary of every one of them.
"""

from __future__ import annotations

import heapq
import math
from typing import Sequence

import numpy as np
import shapely
from shapely.geometry import Polygon

from ..errors import NoRouteError
from .geometry import convex_mask, rings

_UNKNOWN, _FREE, _BLOCKED = 0, 1, 2
#: Above this many segment x edge pairs a batch is pre-filtered by angle (see _pairs_by_angle);
#: 10k measured best (rect-200 cold median 13 -> 8 ms, same elsewhere) with `sbplan bench plan`.
_DENSE_LIMIT = 10_000


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
    """

    def __init__(self, polygons: Sequence[Polygon], bounds: Sequence[float], *, eps: float):
        self.bounds = tuple(float(b) for b in bounds)
        self.eps = float(eps)
        self.polygons: list[Polygon] = []
        ea = np.zeros((0, 2))
        self._ea, self._eb, self._vp = ea, ea, ea
        self._cp = np.zeros((0, 2))
        self._cprev = np.zeros((0, 2))
        self._cnext = np.zeros((0, 2))
        self._cactive = np.zeros(0, bool)
        self._vis = np.zeros((0, 0), np.int8)
        self._tree = None
        self.stats = {"segment_pairs": 0, "expansions": 0}
        self.add_obstacles(polygons, _initial=True)

    # -- structure --------------------------------------------------------------------------------
    @property
    def corners(self) -> np.ndarray:
        """The active auxiliary corners, shape (C, 2) ``(x, y)``."""
        return self._cp[self._cactive]

    def covered(self, pts: np.ndarray, *, boundary: bool = True) -> np.ndarray:
        """True for points ``(K, 2)`` inside (or, with ``boundary``, on) an enlarged obstacle."""
        pts = np.atleast_2d(np.asarray(pts, float))
        out = np.zeros(len(pts), bool)
        if not self.polygons or len(pts) == 0:
            return out
        geoms = shapely.points(pts)
        # STRtree evaluates predicate(point, polygon): "within" is the strict interior.
        pred = "intersects" if boundary else "within"
        ip, io = self._tree.query(geoms, predicate=pred)
        out[ip] = True
        return out

    def add_obstacles(self, polygons: Sequence[Polygon], *, _initial: bool = False) -> None:
        """Add enlarged obstacles and update the cache incrementally: corners now covered are
        dropped, cached free pairs crossing a new obstacle become blocked, the new convex corners
        join (unknown visibility)."""
        polygons = [p for p in polygons if not p.is_empty]
        if not polygons:
            if _initial:
                self._tree = shapely.STRtree([])
            return
        new_rings = rings(polygons)
        ea = np.concatenate(new_rings) if new_rings else np.zeros((0, 2))
        eb = np.concatenate([np.roll(r, -1, axis=0) for r in new_rings])
        vp = np.concatenate([np.roll(r, 1, axis=0) for r in new_rings])
        conv = np.concatenate([convex_mask(r) for r in new_rings])
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

    # -- segment tests ----------------------------------------------------------------------------
    def segment_free(self, p: Sequence[float], q: Sequence[float]) -> bool:
        """True when the segment p-q enters no enlarged obstacle (touching is allowed)."""
        p = np.asarray(p, float).reshape(1, 2)
        q = np.asarray(q, float).reshape(1, 2)
        return not bool(self._blocked_segments(p, q, self._ea, self._eb, self._vp)[0])

    def _blocked_segments(self, P: np.ndarray, Q: np.ndarray, ea, eb, vp) -> np.ndarray:
        """For K segments P[k]-Q[k], True where one enters an obstacle's interior.

        A segment enters an interior iff it properly crosses an edge, or passes through a vertex
        (strictly between its ends) in a direction inside that vertex's interior cone. Ends at a
        corner are covered by the tangency filters of the search.
        """
        K, E = len(P), len(ea)
        if K == 0 or E == 0:
            return np.zeros(K, bool)
        if K * E <= _DENSE_LIMIT:
            k = None
            e = None
            PX, PY = P[:, 0:1], P[:, 1:2]
            DX, DY = Q[:, 0:1] - PX, Q[:, 1:2] - PY
            AX, AY, BX, BY = ea[None, :, 0], ea[None, :, 1], eb[None, :, 0], eb[None, :, 1]
        else:
            k, e = _pairs_by_angle(P, Q, ea, eb)
            if len(k) == 0:
                return np.zeros(K, bool)
            PX, PY = P[k, 0], P[k, 1]
            DX, DY = Q[k, 0] - PX, Q[k, 1] - PY
            AX, AY, BX, BY = ea[e, 0], ea[e, 1], eb[e, 0], eb[e, 1]
        self.stats["segment_pairs"] += K * E if k is None else len(k)
        ax, ay = AX - PX, AY - PY
        o1 = _cross(DX, DY, ax, ay)
        o2 = _cross(DX, DY, BX - PX, BY - PY)
        ex, ey = BX - AX, BY - AY
        o3 = _cross(ex, ey, -ax, -ay)
        o4 = _cross(ex, ey, DX - ax, DY - ay)
        L2 = DX * DX + DY * DY
        eL = np.sqrt(ex * ex + ey * ey)
        tol_s = self.eps * np.sqrt(L2)  # |cross| below this: the point is on the segment's line
        tol_e = self.eps * eL
        proper = (((o1 > tol_s) & (o2 < -tol_s)) | ((o1 < -tol_s) & (o2 > tol_s))) & \
                 (((o3 > tol_e) & (o4 < -tol_e)) | ((o3 < -tol_e) & (o4 > tol_e)))
        # Vertex a strictly inside the segment: check the cone.
        t = (ax * DX + ay * DY)
        on = (np.abs(o1) <= tol_s) & (t > self.eps * np.sqrt(L2)) & (t < L2 - self.eps * np.sqrt(L2))
        if on.any():
            if k is None:
                kk, ee = np.nonzero(on)
                dx, dy = DX[kk, 0], DY[kk, 0]
            else:
                idx = np.nonzero(on)[0]
                kk, ee = k[idx], e[idx]
                dx, dy = DX[idx], DY[idx]
            hit = _enters_cone(ea[ee], vp[ee], eb[ee], dx, dy, self.eps)
            if hit.any():
                if k is None:
                    proper[kk[hit], ee[hit]] = True
                else:
                    proper[idx[hit]] = True
        if k is None:
            return proper.any(axis=1)
        out = np.zeros(K, bool)
        out[k[proper]] = True
        return out

    # -- search -----------------------------------------------------------------------------------
    def shortest_path(self, start: Sequence[float], goal: Sequence[float], *, should_stop=None
                      ) -> tuple[np.ndarray, float]:
        """Euclidean-shortest route from start to goal, shape (M, 2) ``(x, y)``, and its length.

        Start and goal must be free points inside the bounds. Raises NoRouteError when the search
        is exhausted (a proof that no route exists). ``should_stop()`` is polled per expansion
        (OMPL's termination condition); stopping early raises NoRouteError with reason timeout.
        """
        s = np.asarray(start, float)
        g = np.asarray(goal, float)
        if self.segment_free(s, g):
            return np.stack([s, g]), float(np.hypot(*(g - s)))
        C = len(self._cp)
        S, G = C, C + 1
        act = np.nonzero(self._cactive)[0]
        cp, cprev, cnext = self._cp, self._cprev, self._cnext
        ang_eps = 1e-12

        def tangent_at_target(src: np.ndarray, idx: np.ndarray) -> np.ndarray:
            d = cp[idx] - src
            n = np.hypot(d[:, 0], d[:, 1]) + 1e-300
            dx, dy = d[:, 0] / n, d[:, 1] / n
            a = _cross(dx, dy, cprev[idx, 0] - cp[idx, 0], cprev[idx, 1] - cp[idx, 1])
            b = _cross(dx, dy, cnext[idx, 0] - cp[idx, 0], cnext[idx, 1] - cp[idx, 1])
            sc = self.eps
            return ~(((a > sc) & (b < -sc)) | ((a < -sc) & (b > sc)))

        # Goal row: corners that see the goal (the last segment, tangent at the corner).
        cand = act[tangent_at_target(g, act)]
        goal_vis = np.zeros(C, bool)
        if len(cand):
            bl = self._blocked_segments(np.repeat(g[None], len(cand), 0), cp[cand], self._ea, self._eb, self._vp)
            goal_vis[cand[~bl]] = True
        if not goal_vis.any():
            raise NoRouteError("no route: the goal is enclosed (no corner sees it)")

        gs = np.full(C + 2, np.inf)
        parent = np.full(C + 2, -1, np.int64)
        closed = np.zeros(C + 2, bool)
        gs[S] = 0.0
        heap = [(float(np.hypot(*(g - s))), 0.0, S)]
        pos = np.concatenate([cp, s[None], g[None]])
        hgoal = np.hypot(pos[:, 0] - g[0], pos[:, 1] - g[1])
        expansions = 0
        while heap:
            f, gu, u = heapq.heappop(heap)
            if closed[u] or gu > gs[u]:
                continue
            if u == G:
                path = [G]
                while path[-1] != S:
                    path.append(int(parent[path[-1]]))
                self.stats["expansions"] += expansions
                return pos[path[::-1]].copy(), float(gs[G])
            closed[u] = True
            expansions += 1
            if should_stop is not None and should_stop():
                raise NoRouteError("no route found before the time limit (timeout)")
            pu = pos[u]
            idx = act[~closed[act]]
            if len(idx):
                idx = idx[tangent_at_target(pu, idx)]
            if u != S:
                # Taut: the obstacle at u stays on the inner side of the turn parent -> u -> v.
                pp = pos[parent[u]]
                d1 = pu - pp
                d1 = d1 / (math.hypot(*d1) + 1e-300)
                r_prev, r_next = cprev[u] - pu, cnext[u] - pu
                side = np.sign(_cross(d1[0], d1[1], *r_prev) + _cross(d1[0], d1[1], *r_next))
                if side != 0 and len(idx):
                    d2 = cp[idx] - pu
                    n2 = np.hypot(d2[:, 0], d2[:, 1]) + 1e-300
                    dx, dy = d2[:, 0] / n2, d2[:, 1] / n2
                    ok = (side * _cross(dx, dy, r_prev[0], r_prev[1]) >= -self.eps) & \
                         (side * _cross(dx, dy, r_next[0], r_next[1]) >= -self.eps) & \
                         (side * _cross(d1[0], d1[1], dx, dy) >= -ang_eps)
                    idx = idx[ok]
                    goal_ok = goal_vis[u]
                    if goal_ok:
                        dg = g - pu
                        ng = math.hypot(*dg) + 1e-300
                        dgx, dgy = dg / ng
                        goal_ok = (side * _cross(dgx, dgy, *r_prev) >= -self.eps) and \
                                  (side * _cross(dgx, dgy, *r_next) >= -self.eps) and \
                                  (side * _cross(d1[0], d1[1], dgx, dgy) >= -ang_eps)
                else:
                    goal_ok = goal_vis[u]
                if goal_ok:
                    ng = gu + math.hypot(*(g - pu))
                    if ng < gs[G]:
                        gs[G] = ng
                        parent[G] = u
                        heapq.heappush(heap, (ng, ng, G))
            if len(idx) == 0:
                continue
            d = cp[idx] - pu
            newg = gu + np.hypot(d[:, 0], d[:, 1])
            better = newg < gs[idx]
            idx, newg = idx[better], newg[better]
            if len(idx) == 0:
                continue
            if u == S:
                bl = self._blocked_segments(np.repeat(s[None], len(idx), 0), cp[idx], self._ea, self._eb, self._vp)
                free = ~bl
            else:
                row = self._vis[u, idx]
                unk = row == _UNKNOWN
                if unk.any():
                    ui = idx[unk]
                    bl = self._blocked_segments(np.repeat(pu[None], len(ui), 0), cp[ui], self._ea, self._eb, self._vp)
                    vals = np.where(bl, _BLOCKED, _FREE).astype(np.int8)
                    self._vis[u, ui] = vals
                    self._vis[ui, u] = vals
                    row = self._vis[u, idx]
                free = row == _FREE
            idx, newg = idx[free], newg[free]
            gs[idx] = newg
            parent[idx] = u
            fs = newg + hgoal[idx]
            for fv, gv, v in zip(fs.tolist(), newg.tolist(), idx.tolist()):
                heapq.heappush(heap, (fv, gv, v))
        self.stats["expansions"] += expansions
        raise NoRouteError("no route: start and goal are not connected (search exhausted)")


def _enters_cone(v, vprev, vnext, dx, dy, eps) -> np.ndarray:
    """True where direction (dx, dy) or its opposite points strictly into the interior cone at
    vertex v (interior on the left of the ring prev -> v -> next)."""
    n = np.hypot(dx, dy) + 1e-300
    dx, dy = dx / n, dy / n
    e1 = vnext - v
    e2 = vprev - v
    e1 = e1 / (np.hypot(e1[:, 0], e1[:, 1])[:, None] + 1e-300)
    e2 = e2 / (np.hypot(e2[:, 0], e2[:, 1])[:, None] + 1e-300)
    convex = _cross(-e2[:, 0], -e2[:, 1], e1[:, 0], e1[:, 1]) > 0
    out = np.zeros(len(v), bool)
    for sgn in (1.0, -1.0):
        x, y = sgn * dx, sgn * dy
        c1 = _cross(e1[:, 0], e1[:, 1], x, y)
        c2 = _cross(x, y, e2[:, 0], e2[:, 1])
        inside_convex = (c1 > eps) & (c2 > eps)
        # Reflex: interior is everything but the closed exterior cone from e2 to e1.
        ext = (_cross(e2[:, 0], e2[:, 1], x, y) >= -eps) & (_cross(x, y, e1[:, 0], e1[:, 1]) >= -eps)
        out |= np.where(convex, inside_convex, ~ext)
    return out


def _pairs_by_angle(P, Q, ea, eb):
    """Candidate (segment, edge) pairs for segments that share their start point P[0]: an edge
    can only meet a segment whose direction lies within the edge's angular extent seen from P[0]
    (and which reaches at least as far as the edge's nearest point). Falls back to all pairs when
    the starts differ."""
    K, E = len(P), len(ea)
    if not np.all(P == P[0]):
        k = np.repeat(np.arange(K), E)
        e = np.tile(np.arange(E), K)
        return k, e
    p = P[0]
    d = Q - p
    ang = np.arctan2(d[:, 1], d[:, 0])
    order = np.argsort(ang)
    A = ang[order]
    a = ea - p
    b = eb - p
    ta = np.arctan2(a[:, 1], a[:, 0])
    tb = np.arctan2(b[:, 1], b[:, 0])
    diff = (tb - ta + np.pi) % (2 * np.pi) - np.pi
    lo = np.where(diff >= 0, ta, tb) - 1e-9
    hi = lo + np.abs(diff) + 2e-9
    # Edges too far to reach: nearest distance of the edge from p beyond the longest segment.
    ex = b - a
    t = np.clip(-(a * ex).sum(1) / np.maximum((ex * ex).sum(1), 1e-300), 0, 1)
    near = np.hypot(a[:, 0] + t * ex[:, 0], a[:, 1] + t * ex[:, 1])
    Lmax = np.hypot(d[:, 0], d[:, 1]).max()
    live = near <= Lmax
    eidx = np.nonzero(live)[0]
    lo, hi = lo[live], hi[live]
    wrap = hi > np.pi
    # Split wrapping intervals into [lo, pi] and [-pi, hi - 2 pi].
    e_all = np.concatenate([eidx, eidx[wrap]])
    lo_all = np.concatenate([lo, np.full(wrap.sum(), -np.pi - 1e-9)])
    hi_all = np.concatenate([np.minimum(hi, np.pi + 1e-9), hi[wrap] - 2 * np.pi])
    st = np.searchsorted(A, lo_all, "left")
    en = np.searchsorted(A, hi_all, "right")
    cnt = np.maximum(en - st, 0)
    total = int(cnt.sum())
    if total == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    e = np.repeat(e_all, cnt)
    offs = np.repeat(st - np.concatenate([[0], np.cumsum(cnt)[:-1]]), cnt)
    k = order[np.arange(total) + offs]
    # Drop pairs whose segment ends before the edge begins.
    reach = np.hypot(d[k, 0], d[k, 1]) >= near[e] - 1e-9 * (1 + Lmax)
    return k[reach], e[reach]
