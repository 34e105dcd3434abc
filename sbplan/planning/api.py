"""Planning API: maps, problems, routes, ``plan`` and ``replan``.

World frame: ``(x, y)`` in metres (or pixels), x to the right, y up.
"""

from __future__ import annotations

import copy
import math
import time
from collections import OrderedDict
from dataclasses import dataclass, field
from typing import Any, Iterable, Sequence

import numpy as np
import shapely
from shapely.geometry import LineString, Point, Polygon
from shapely.ops import nearest_points, unary_union

from ..errors import (GoalInObstacleError, InputError, NoRouteError, OutOfBoundsError, PlanningError,
                      StartInObstacleError)
from .geometry import as_polygons, enlarge
from .vismap import VisibilityMap

#: Planning tolerance relative to the map's extent: obstacles are enlarged by radius + margin +
#: TOL * extent (closing zero-width slits between touching obstacles); routes are checked at radius.
TOL = 1e-6


_F64 = np.dtype(float)

#: The ``format`` of a route's JSON (``Route.to_dict``, ``sbplan plan --json``, the demo's route.json).
ROUTE_FORMAT = "sbplan.route/1"


def _point(p: Any, name: str) -> np.ndarray:
    return _point_xy(p, name)[0]


def _point_xy(p: Any, name: str) -> tuple[np.ndarray, float, float]:
    """The point as a float array of shape (2,) and as two floats."""
    if type(p) is np.ndarray and p.dtype is _F64 and p.shape == (2,):
        a = p  # the common case, without asarray's and isfinite's call overhead
    else:
        try:
            a = np.asarray(p, dtype=float).reshape(-1)
        except (TypeError, ValueError):
            raise InputError(f"{name}: expected a point (x, y), got {p!r}") from None
        if a.shape != (2,):
            raise InputError(f"{name}: expected a finite point (x, y), got {p!r}")
    x, y = a.tolist()
    if not (math.isfinite(x) and math.isfinite(y)):
        raise InputError(f"{name}: expected a finite point (x, y), got {p!r}")
    return a, x, y


class PlanningMap:
    """One map prepared for planning: obstacles, their enlargement, bounds and the visibility
    cache. Build it once and plan many queries on it (``plan(pmap, ...)``).

    Parameters
    ----------
    obstacles : iterable of shapely Polygon or (M, 2) arrays ``(x, y)``
        The real obstacles.
    robot_radius : float
        Robot radius, >= 0, in map units.
    margin : float
        Extra safety distance, >= 0.
    bounds : (xmin, ymin, xmax, ymax), optional
        The workspace the robot's centre stays in; default: the obstacles' bounding box grown by
        2 * (radius + margin) + 5 % of its size.
    """

    def __init__(self, obstacles: Iterable, *, robot_radius: float, margin: float = 0.0,
                 bounds: Sequence[float] | None = None, _extra_points: Sequence[np.ndarray] = ()):
        r = _nonneg(robot_radius, "robot_radius")
        m = _nonneg(margin, "margin")
        self.obstacles = as_polygons(obstacles)
        self.robot_radius, self.margin = r, m
        if bounds is None:
            pts = [np.asarray(p.bounds).reshape(2, 2) for p in self.obstacles] + [np.asarray(p)[None] for p in _extra_points]
            if not pts:
                raise InputError("bounds: cannot be derived without obstacles; give bounds")
            allp = np.concatenate(pts)
            lo, hi = allp.min(0), allp.max(0)
            pad = 2 * (r + m) + 0.05 * max(float((hi - lo).max()), 1e-9)
            bounds = (lo[0] - pad, lo[1] - pad, hi[0] + pad, hi[1] + pad)
        try:
            b = tuple(float(v) for v in bounds)
        except (TypeError, ValueError):
            raise InputError(f"bounds: expected (xmin, ymin, xmax, ymax), got {bounds!r}") from None
        if len(b) != 4 or not all(math.isfinite(v) for v in b) or b[0] >= b[2] or b[1] >= b[3]:
            raise InputError(f"bounds: expected finite (xmin, ymin, xmax, ymax) with xmin < xmax, ymin < ymax, got {bounds!r}")
        self.bounds = b
        self.scale = max(b[2] - b[0], b[3] - b[1])
        self.tolerance = TOL * self.scale
        self.clearance = r + m + self.tolerance
        self.enlarged = enlarge(self.obstacles, self.clearance)
        self.vmap = VisibilityMap(self.enlarged, b, eps=1e-9 * self.scale)
        self._real_tree = shapely.STRtree(self.obstacles)

    # -- queries ----------------------------------------------------------------------------------
    def in_bounds(self, p: np.ndarray) -> bool:
        x0, y0, x1, y1 = self.bounds
        x, y = p.tolist() if type(p) is np.ndarray else p
        return x0 <= x <= x1 and y0 <= y <= y1

    def check_endpoint(self, p: np.ndarray, which: str) -> tuple[np.ndarray, bool]:
        """Validate a start or goal; return the free point to plan from and whether it had to
        escape from an enlarged obstacle."""
        err = StartInObstacleError if which == "start" else GoalInObstacleError
        if not self.in_bounds(p):
            raise OutOfBoundsError(f"{which} ({p[0]:g}, {p[1]:g}) is outside the workspace bounds {self.bounds}")
        if len(self._real_tree.query(Point(p), predicate="intersects")):
            raise err(f"{which} ({p[0]:g}, {p[1]:g}) is inside an obstacle")
        # On the enlarged boundary is free: routes run along it, and a robot replanning from a
        # point of its route stands there.
        if not self.vmap.covered(p[None], boundary=False)[0]:
            return p, False
        q = self._escape(p)
        if q is None:
            raise err(f"{which} ({p[0]:g}, {p[1]:g}) is within the robot radius of obstacles and no free point is near")
        return q, True

    def _escape(self, p: np.ndarray) -> np.ndarray | None:
        """Nearest free point just outside the enlarged obstacles around p."""
        idx = self.vmap._tree.query(Point(p).buffer(2 * self.clearance + self.tolerance), predicate="intersects")
        union = unary_union([self.enlarged[i] for i in idx])
        for part in getattr(union, "geoms", [union]):
            if part.intersects(Point(p)):
                q = np.asarray(nearest_points(part.boundary, Point(p))[0].coords[0])
                d = q - p
                n = math.hypot(*d)
                if n == 0:
                    return None
                q = q + d / n * 10 * self.tolerance
                if self.in_bounds(q) and not self.vmap.covered(q[None])[0]:
                    return q
        return None

    def solve(self, start: Any, goal: Any, *, time_limit: float = 1.0, planner: str = "aux-corner") -> "Route":
        """The exact shortest route (the auxiliary-corner search). Raises a PlanningError."""
        t0 = time.perf_counter()
        s0, sx, sy = _point_xy(start, "start")
        g0, gx, gy = _point_xy(goal, "goal")
        # Both ends inside the bounds and certainly outside (or on) every enlarged obstacle, hence
        # outside every real one: the endpoint checks of _solve_full (shapely point queries)
        # would pass them unchanged. straight_check decides that from the map's edges alone,
        # with the segment test: a free segment is the route (what the search would return, no
        # search state); a blocked one goes straight to the search. Undecided cases (an end
        # inside an obstacle or within eps of an edge) take the full path.
        x0, y0, x1, y1 = self.bounds
        if x0 <= sx <= x1 and y0 <= sy <= y1 and x0 <= gx <= x1 and y0 <= gy <= y1:
            code = self.vmap._straight_check(sx, sy, gx, gy)
            if code == 1:
                return Route._segment(sx, sy, gx, gy, planner, t0, self, g0)
            if code == 0:
                return self._search(s0, g0, False, False, t0=t0, time_limit=time_limit, planner=planner,
                                    straight_blocked=True)
        return self._solve_full(s0, g0, t0=t0, time_limit=time_limit, planner=planner)

    def _solve_full(self, s0: np.ndarray, g0: np.ndarray, *, t0: float, time_limit: float, planner: str) -> "Route":
        """solve without the fast paths: endpoint checks (errors, escapes), then the search."""
        s, s_esc = self.check_endpoint(s0, "start")
        g, g_esc = self.check_endpoint(g0, "goal")
        return self._search(s0, g0, s if s_esc else False, g if g_esc else False, t0=t0, time_limit=time_limit,
                            planner=planner)

    def _search(self, s0: np.ndarray, g0: np.ndarray, s_esc: Any, g_esc: Any, *, t0: float, time_limit: float,
                planner: str, straight_blocked: bool = False) -> "Route":
        """The search from s0 (or its escape point s_esc) to g0 (or g_esc); the route starts and
        ends at s0 and g0."""
        s = s0 if s_esc is False else s_esc
        g = g0 if g_esc is False else g_esc
        deadline = t0 + float(time_limit)
        wp, _ = self.vmap.shortest_path(s, g, should_stop=lambda: time.perf_counter() > deadline,
                                        straight_blocked=straight_blocked)
        if s_esc is not False:
            wp = np.concatenate([s0[None], wp])
        if g_esc is not False:
            wp = np.concatenate([wp, g0[None]])
        return Route(wp, status="approximate" if (s_esc is not False or g_esc is not False) else "exact",
                     planner=planner, time_s=time.perf_counter() - t0, map=self, goal=g0)

    def copy(self) -> "PlanningMap":
        """An independent copy (the visibility cache is copied, not rebuilt)."""
        new = copy.copy(self)
        new.obstacles = list(self.obstacles)
        new.enlarged = list(self.enlarged)
        v = copy.copy(self.vmap)
        for name in ("_ea", "_eb", "_vp", "_cp", "_cprev", "_cnext", "_cactive", "_vis"):
            setattr(v, name, getattr(self.vmap, name).copy())
        v.polygons = list(self.vmap.polygons)
        v.stats = dict(self.vmap.stats)
        new.vmap = v
        return new

    def add_obstacles(self, obstacles: Iterable) -> list[Polygon]:
        """Add real obstacles in place (incremental cache update); return their enlargements."""
        polys = as_polygons(obstacles, name="new_obstacles")
        big = enlarge(polys, self.clearance)
        self.obstacles.extend(polys)
        self.enlarged.extend(big)
        self.vmap.add_obstacles(big)
        self._real_tree = shapely.STRtree(self.obstacles)
        return big


def _nonneg(v: Any, name: str) -> float:
    try:
        f = float(v)
    except (TypeError, ValueError):
        raise InputError(f"{name}: expected a number, got {v!r}") from None
    if not math.isfinite(f) or f < 0:
        raise InputError(f"{name}: must be a finite number >= 0, got {v!r}")
    return f


@dataclass
class Problem:
    """A query on a map: what a planner stage's ``solve`` receives."""

    map: PlanningMap
    start: np.ndarray
    goal: np.ndarray


@dataclass
class Route:
    """A planned route.

    Attributes
    ----------
    waypoints : ndarray of shape (M, 2), ``(x, y)``
    length : float
    status : "exact" | "approximate"
        approximate: the start or goal had to escape from within the clearance of an obstacle, or
        a sampling planner returned an approximate solution.
    planner : str
    time_s : float, seconds spent planning
    replanned : bool
        True only for a route ``replan`` planned anew; False for a fresh ``plan`` and for the
        remaining route ``replan`` returned unchanged (no new obstacle touched it).
    """

    waypoints: np.ndarray
    status: str = "exact"
    planner: str = "aux-corner"
    time_s: float = 0.0
    replanned: bool = False
    map: PlanningMap | None = field(default=None, repr=False, compare=False)
    goal: np.ndarray | None = field(default=None, repr=False, compare=False)
    length: float = field(init=False)

    def __post_init__(self) -> None:
        w = self.waypoints
        if not (type(w) is np.ndarray and w.dtype is _F64 and w.ndim == 2 and w.shape[1] == 2):
            w = self.waypoints = np.asarray(w, float).reshape(-1, 2)
        # Plain Python over the waypoints: numpy's call overhead showed on straight-line queries.
        pts = w.tolist()
        length = 0.0
        for (x0, y0), (x1, y1) in zip(pts, pts[1:]):
            length += math.hypot(x1 - x0, y1 - y0)
        self.length = length
        if self.goal is None and pts:
            self.goal = w[-1].copy()

    @classmethod
    def _segment(cls, sx: float, sy: float, gx: float, gy: float, planner: str, t0: float, pmap: PlanningMap,
                 goal: np.ndarray) -> "Route":
        """The exact route start -> goal along one segment: what ``Route(np.stack((s, g)),
        planner=planner, time_s=..., map=pmap, goal=goal)`` builds, the same length (the sum in
        __post_init__ of one hypot), without the dataclass machinery (straight-line queries)."""
        r = cls.__new__(cls)
        r.waypoints = np.array(((sx, sy), (gx, gy)))
        r.status, r.planner, r.replanned, r.map, r.goal = "exact", planner, False, pmap, goal
        r.length = math.hypot(gx - sx, gy - sy)
        r.time_s = time.perf_counter() - t0
        return r

    def to_dict(self) -> dict:
        return {"format": ROUTE_FORMAT, "status": self.status, "planner": self.planner, "length": self.length,
                "time_s": self.time_s, "replanned": self.replanned,
                "waypoints": self.waypoints.tolist()}


_CACHE: "OrderedDict[Any, PlanningMap]" = OrderedDict()
_CACHE_SIZE = 8


def _map_for(obstacles: Any, start: np.ndarray, goal: np.ndarray, robot_radius: float, margin: float,
             bounds: Any) -> PlanningMap:
    if isinstance(obstacles, PlanningMap):
        if (obstacles.robot_radius, obstacles.margin) != (float(robot_radius), float(margin)):
            raise InputError("robot_radius/margin: differ from the PlanningMap's; build a new map")
        return obstacles
    polys = as_polygons(obstacles)
    key = (tuple(p.wkb for p in polys), None if bounds is None else tuple(map(float, bounds)),
           float(robot_radius), float(margin))
    if bounds is None:
        key = key + (tuple(start), tuple(goal))
    pm = _CACHE.get(key)
    if pm is None:
        pm = PlanningMap(polys, robot_radius=robot_radius, margin=margin, bounds=bounds, _extra_points=(start, goal))
        _CACHE[key] = pm
        while len(_CACHE) > _CACHE_SIZE:
            _CACHE.popitem(last=False)
    else:
        _CACHE.move_to_end(key)
    return pm


def plan(obstacles: Any, start: Any, goal: Any, *, robot_radius: float, planner: Any = "aux-corner",
         bounds: Sequence[float] | None = None, time_limit: float = 1.0, margin: float = 0.0) -> Route:
    """Plan a collision-free route for a disc robot among polygonal obstacles.

    Parameters
    ----------
    obstacles : iterable of shapely Polygon / (M, 2) arrays ``(x, y)``, or a PlanningMap
        Real obstacles; a PlanningMap (or repeated calls with the same obstacles) reuses the
        visibility cache.
    start, goal : (x, y)
    robot_radius, margin : float, >= 0
    planner : str or Planner stage
        ``aux-corner`` (exact shortest route) or an OMPL planner (``sbplan plugins``).
    bounds : (xmin, ymin, xmax, ymax), optional
    time_limit : float, seconds

    Returns
    -------
    Route

    Raises
    ------
    OutOfBoundsError, StartInObstacleError, GoalInObstacleError, NoRouteError, InputError
    """
    from .. import plugins

    _nonneg(robot_radius, "robot_radius")
    _nonneg(margin, "margin")
    tl = _nonneg(time_limit, "time_limit")
    s, g = _point(start, "start"), _point(goal, "goal")
    stage = plugins.planner(planner)
    pm = _map_for(obstacles, s, g, robot_radius, margin, bounds)
    return stage.solve(Problem(pm, s, g), time_limit=tl)


def replan(route: Route, position: Any, new_obstacles: Any, *, time_limit: float = 1.0) -> Route:
    """Update a route after new obstacles appeared, from the robot's current position.

    The route's map is copied and updated incrementally. If no new obstacle (enlarged by the
    clearance) touches the remaining route, the remaining route is returned with
    ``replanned=False``; otherwise the exact route from ``position`` is planned on the updated map.
    """
    if not isinstance(route, Route) or route.map is None:
        raise InputError("route: expected a Route returned by sbplan.plan")
    t0 = time.perf_counter()
    p = _point(position, "position")
    # A copy, so the caller's route (and the map cache of plan()) keep the old obstacles.
    pm = route.map.copy()
    big = pm.add_obstacles(new_obstacles if not isinstance(new_obstacles, (Polygon,)) else [new_obstacles])
    wp = route.waypoints
    # The remaining route: from the position's projection onto the nearest leg, on to the goal.
    if len(wp) >= 2:
        a, b = wp[:-1], wp[1:]
        d = b - a
        t = np.clip(((p - a) * d).sum(1) / np.maximum((d * d).sum(1), 1e-300), 0, 1)
        dist = np.hypot(*(a + t[:, None] * d - p).T)
        i = int(np.argmin(dist))
        remaining = np.concatenate([p[None], wp[i + 1:]])
    else:
        remaining = np.stack([p, wp[-1]]) if len(wp) else p[None]
    line = LineString(remaining) if len(remaining) >= 2 else Point(p)
    touched = any(shapely.relate_pattern(line, q, "T********") or q.contains(Point(p)) for q in big)
    if not touched:
        return Route(remaining, status=route.status, planner=route.planner, time_s=time.perf_counter() - t0,
                     replanned=False, map=pm, goal=route.goal)
    out = pm.solve(p, route.goal, time_limit=time_limit, planner="aux-corner")
    out.time_s = time.perf_counter() - t0
    out.replanned = True
    return out
