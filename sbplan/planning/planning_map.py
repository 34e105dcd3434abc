"""One map prepared for planning: :class:`PlanningMap`.

World frame: ``(x, y)`` in metres (or pixels), x to the right, y up.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, Iterable, Sequence

import numpy as np
import shapely
from shapely.geometry import LineString, Point, Polygon
from shapely.ops import nearest_points, unary_union

from ..errors import GoalInObstacleError, InputError, OutOfBoundsError, StartInObstacleError
from .aux_corner import solve_aux_corner
from .geometry import MAX_COORDINATE, as_polygons, check_extent, check_size, enlarge, nonneg
from .vismap import VisibilityMap

if TYPE_CHECKING:
    from .route import Route

#: Planning tolerance relative to the map's extent: obstacles are enlarged by radius + margin +
#: TOL * extent (closing zero-width slits between touching obstacles); routes are checked at radius.
TOL = 1e-6


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
        The workspace the robot's centre stays in; default: the bounding box of the obstacles
        and of ``include``, grown by 2 * (radius + margin) + 5 % of its size.
    include : sequence of (x, y), optional
        Points the default bounds must hold (the start and goal of the queries to come);
        ignored when ``bounds`` is given.

    Notes
    -----
    Threads: queries (``solve``, ``plan(pmap, ...)``, OMPL planners) and ``copy`` may run on one
    map from several threads at once (see :class:`VisibilityMap`); ``add_obstacles`` must not run
    while other threads use the map (``replan`` copies the route's map and adds obstacles to the
    copy).
    """

    def __init__(self, obstacles: Iterable, *, robot_radius: float, margin: float = 0.0,
                 bounds: Sequence[float] | None = None, include: Sequence[Any] = ()):
        r = nonneg(robot_radius, "robot_radius")
        m = nonneg(margin, "margin")
        if r + m > MAX_COORDINATE:  # enlarging by it would overflow like a coordinate would
            raise InputError(f"robot_radius + margin: {r + m:g} is beyond the {MAX_COORDINATE:g} the planner's "
                             "arithmetic holds")
        self.obstacles = as_polygons(obstacles)
        check_size(self.obstacles)
        self.robot_radius, self.margin = r, m
        if bounds is None:
            try:
                extra = [np.asarray(p, dtype=float).reshape(1, 2) for p in include]
            except (TypeError, ValueError):
                raise InputError(f"include: expected points (x, y), got {include!r}") from None
            pts = [np.asarray(p.bounds).reshape(2, 2) for p in self.obstacles] + extra
            if not pts:
                raise InputError("bounds: cannot be derived without obstacles; give bounds")
            allp = np.concatenate(pts)
            if not np.isfinite(allp).all():
                raise InputError(f"include: expected finite points (x, y), got {include!r}")
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
        check_extent(self.obstacles, b)
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
        """Nearest free point just outside the enlarged obstacles around p that a straight step
        from p reaches without entering a real obstacle."""
        vm = self.vmap
        idx = vm.tree.query(Point(p).buffer(2 * self.clearance + self.tolerance), predicate="intersects")
        union = unary_union([vm.polygons[i] for i in idx])
        for part in getattr(union, "geoms", [union]):
            if part.intersects(Point(p)):
                q = np.asarray(nearest_points(part.boundary, Point(p))[0].coords[0])
                if math.hypot(*(q - p)) <= self.tolerance:
                    # p is on the boundary (a route running along an obstacle's side, where a
                    # robot replans from): a step off it, whichever way is free
                    for a in np.linspace(0, 2 * math.pi, 16, endpoint=False):
                        q = p + 10 * self.tolerance * np.array([math.cos(a), math.sin(a)])
                        if self._reachable(p, q):
                            return q
                    return None
                out = self._step_out(p, q)
                if out is not None:
                    return out
                # In a concave pocket the nearest way out can run through the obstacle itself: the
                # nearest of the boundary's points (every tenth of the clearance) that a step
                # reaches in the open
                ring = part.exterior
                step = max(self.clearance / 10, 10 * self.tolerance)
                points = np.array([ring.interpolate(t).coords[0] for t in np.arange(0.0, ring.length, step)])
                for q in points[np.argsort(np.hypot(*(points - p).T))]:
                    out = self._step_out(p, q)
                    if out is not None:
                        return out
                return None
        return None

    def _step_out(self, p: np.ndarray, q: np.ndarray) -> np.ndarray | None:
        """``q``, a point of the enlarged obstacles' boundary, moved a little further from ``p``
        into the free space, when a straight step from ``p`` reaches it (:meth:`_reachable`)."""
        d = q - p
        n = math.hypot(*d)
        if n <= self.tolerance:
            return None
        q = q + d / n * 10 * self.tolerance
        return q if self._reachable(p, q) else None

    def _reachable(self, p: np.ndarray, q: np.ndarray) -> bool:
        """Is ``q`` free, within the bounds, and the segment p -> q out of every real obstacle's
        interior?"""
        if not self.in_bounds(q) or self.vmap.covered(q[None])[0]:
            return False
        seg = LineString([p, q])
        return not any(shapely.relate_pattern(self.obstacles[i], seg, "T********")
                       for i in self._real_tree.query(seg, predicate="intersects"))

    def solve(self, start: Any, goal: Any, *, time_limit: float = 1.0) -> Route:
        """The exact shortest route on this map: :func:`sbplan.planning.aux_corner.solve_aux_corner`.
        Raises a PlanningError."""
        return solve_aux_corner(self, start, goal, time_limit=time_limit)

    def prepare_routes(self) -> bool:
        """Precompute, once, the corner-to-corner distances every query on this map shares
        (:meth:`VisibilityMap.prepare_routes`): a query then costs the visibility of its two
        ends, not a search. Worth it for a map that will answer many queries (the service's);
        tens of milliseconds on a 50-obstacle floor. False when the map has too many corners
        (queries stay A*). Adding obstacles drops it."""
        return self.vmap.prepare_routes()

    # -- changes ----------------------------------------------------------------------------------
    def copy(self) -> "PlanningMap":
        """An independent copy (the visibility cache is copied, not rebuilt): adding obstacles to
        either leaves the other as it was."""
        new = PlanningMap.__new__(PlanningMap)
        new.__dict__.update(self.__dict__)
        new.obstacles = list(self.obstacles)
        new.enlarged = list(self.enlarged)
        new.vmap = self.vmap.copy()
        return new

    def add_obstacles(self, obstacles: Iterable) -> list[Polygon]:
        """Add real obstacles in place (incremental cache update); return their enlargements."""
        polys = as_polygons(obstacles, name="new_obstacles")
        check_size(self.obstacles + polys)
        check_extent(polys, self.bounds)
        big = enlarge(polys, self.clearance)
        self.obstacles.extend(polys)
        self.enlarged.extend(big)
        self.vmap.add_obstacles(big)
        self._real_tree = shapely.STRtree(self.obstacles)
        return big
