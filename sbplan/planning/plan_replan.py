"""``plan`` and ``replan``: a route for a query, by planner name, and its update after new obstacles.

``plan`` keeps the maps it builds in a small cache shared by every caller (:class:`MapCache`,
thread-safe), so repeated queries on the same obstacles reuse the visibility cache.
World frame: ``(x, y)`` in metres (or pixels), x to the right, y up.
"""

from __future__ import annotations

import threading
import time
from collections import OrderedDict
from typing import Any, Callable, Hashable, Sequence

import numpy as np
import shapely
from shapely.geometry import LineString, Point, Polygon

from .. import registry
from ..contracts import Planner, call_stage, describe_value
from ..errors import InputError
from .geometry import as_point, as_polygons, nonneg
from .loaders import ObstacleSet
from .planning_map import PlanningMap
from .route import Problem, Route


class MapCache:
    """A least-recently-used store of PlanningMaps, safe to share between threads.

    Parameters
    ----------
    size : int
        How many maps it keeps.
    """

    def __init__(self, size: int = 8):
        self.size = int(size)
        self._maps: OrderedDict[Hashable, PlanningMap] = OrderedDict()
        self._lock = threading.Lock()

    def get(self, key: Hashable, build: Callable[[], PlanningMap]) -> PlanningMap:
        """The map stored under ``key``, or ``build()``'s, stored. Two threads that build the
        same key at once both get the one stored first."""
        with self._lock:
            pm = self._maps.get(key)
            if pm is not None:
                self._maps.move_to_end(key)
                return pm
        # Built outside the lock: a large map takes milliseconds, and other keys need not wait.
        built = build()
        with self._lock:
            pm = self._maps.setdefault(key, built)
            self._maps.move_to_end(key)
            while len(self._maps) > self.size:
                self._maps.popitem(last=False)
        return pm

    def clear(self) -> None:
        with self._lock:
            self._maps.clear()

    def __len__(self) -> int:
        return len(self._maps)


#: The maps ``plan`` built from obstacles (not the PlanningMaps passed to it).
MAPS = MapCache(8)


def _map_for(obstacles: Any, start: np.ndarray, goal: np.ndarray, robot_radius: float | None,
             margin: float | None, bounds: Any) -> PlanningMap:
    if isinstance(obstacles, PlanningMap):
        for name, given, own in (("robot_radius", robot_radius, obstacles.robot_radius),
                                 ("margin", margin, obstacles.margin)):
            if given is not None and float(given) != own:
                raise InputError(f"{name}: {given!r} differs from the PlanningMap's {own!r}; build a new map")
        return obstacles
    if robot_radius is None:
        raise InputError("robot_radius: required unless obstacles is a PlanningMap")
    margin = 0.0 if margin is None else margin
    polys = as_polygons(obstacles)
    key: tuple = (tuple(p.wkb for p in polys), None if bounds is None else tuple(map(float, bounds)),
                  float(robot_radius), float(margin))
    if bounds is None:  # then the bounds depend on the query's ends
        key = key + (tuple(start), tuple(goal))
    return MAPS.get(key, lambda: PlanningMap(polys, robot_radius=robot_radius, margin=margin, bounds=bounds,
                                             include=(start, goal)))


def plan(obstacles: Any, start: Any, goal: Any, *, robot_radius: float | None = None, planner: str | Planner = "aux-corner",
         bounds: Sequence[float] | None = None, time_limit: float = 1.0, margin: float | None = None,
         obstacle_model: str | None = None) -> Route:
    """Plan a collision-free route for a disc robot among polygonal obstacles.

    Parameters
    ----------
    obstacles : iterable of shapely Polygon / (M, 2) arrays ``(x, y)``, a PlanningMap, an ObstacleSet or a Detection
        Real obstacles; a PlanningMap (or repeated calls with the same obstacles) reuses the
        visibility cache; an ObstacleSet (``load_obstacles``) gives its bounds too. A
        :class:`sbplan.Detection` stands for its obstacles under ``obstacle_model``
        (:func:`sbplan.planning.detection_obstacles`), on its floor (``bounds`` default to the
        calibrated grid's).
    obstacle_model : "mar" | "parts" | "outline", optional
        For a Detection: what stands for each obstacle (default ``parts``, see
        :mod:`sbplan.detection.obstacles`).
    start, goal : (x, y)
    robot_radius, margin : float, >= 0
        Required (margin: default 0) with obstacles; with a PlanningMap, the map's own (a value
        given must equal it).
    planner : str or Planner stage
        ``aux-corner`` (exact shortest route) or an OMPL planner (``sbplan plugins``).
    bounds : (xmin, ymin, xmax, ymax), optional
        With obstacles: default the box of the obstacles, start and goal, grown by 2 x clearance
        + 5 %. With a PlanningMap: the map's.
    time_limit : float, seconds

    Returns
    -------
    Route

    Raises
    ------
    OutOfBoundsError, StartInObstacleError, GoalInObstacleError, NoRouteError, InputError
        As their names say; InputError also for coordinates beyond the planner's precision.
    LimitError
        More obstacle vertices than the ``obstacle_vertices`` limit (:mod:`sbplan.limits`).
    StageError
        The planner stage raised or returned something other than a finite Route.
    """
    # a Detection: its obstacles under the obstacle model, on its floor (issue 15)
    if hasattr(obstacles, "planner_obstacles"):
        from .loaders import detection_obstacles

        found = detection_obstacles(obstacles, use=obstacle_model)
        obstacles, bounds = found.polygons, found.bounds if bounds is None else bounds
    elif obstacle_model is not None:
        raise InputError("obstacle_model: only a Detection has obstacle models; give its polygons otherwise")
    for name, v in (("robot_radius", robot_radius), ("margin", margin)):
        if v is not None:
            nonneg(v, name)
    tl = nonneg(time_limit, "time_limit")
    s, g = as_point(start, "start")[0], as_point(goal, "goal")[0]
    if isinstance(obstacles, ObstacleSet):  # what load_obstacles gives: its polygons, and its bounds
        bounds = obstacles.bounds if bounds is None else bounds
        obstacles = obstacles.polygons
    stage = registry.planner(planner)
    pm = _map_for(obstacles, s, g, robot_radius, margin, bounds)
    return call_stage(stage, "solve", Problem(pm, s, g), time_limit=tl, returns=route_problem)


def route_problem(v: Any) -> str | None:
    """The planner's contract for :func:`~sbplan.contracts.call_stage`: a Route with finite
    waypoints (a route through overflowed geometry is never called exact)."""
    if not isinstance(v, Route):
        return f"{describe_value(v)}, expected a Route"
    if not len(v.waypoints) or not (np.isfinite(v.waypoints).all() and np.isfinite(v.length)):
        return "a route with no or non-finite waypoints"
    return None


def replan(route: Route, position: Any, new_obstacles: Any, *, planner: str | Planner | None = None,
           time_limit: float = 1.0) -> Route:
    """Update a route after new obstacles appeared, from the robot's current position.

    The route's map is copied and updated incrementally. If no new obstacle (enlarged by the
    clearance) touches the remaining route, the remaining route is returned with
    ``replanned=False``; otherwise the route from ``position`` to the route's goal is planned on
    the updated map, and has ``replanned=True``.

    Parameters
    ----------
    route : Route
        A route from :func:`plan` (or ``replan``).
    position : (x, y)
        Where the robot is now.
    new_obstacles : shapely Polygon, or iterable of Polygons / (M, 2) arrays ``(x, y)``
    planner : str or Planner stage, optional
        Default: the planner that made ``route`` (by name, with its default options).
    time_limit : float, seconds
    """
    if not isinstance(route, Route) or route.map is None:
        raise InputError("route: expected a Route returned by sbplan.plan")
    t0 = time.perf_counter()
    p = as_point(position, "position")[0]
    tl = nonneg(time_limit, "time_limit")
    stage = registry.planner(route.planner if planner is None else planner)
    # A copy, so the caller's route (and the maps plan() keeps) keep the old obstacles.
    pm = route.map.copy()
    big = pm.add_obstacles([new_obstacles] if isinstance(new_obstacles, Polygon) else new_obstacles)
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
    if route.goal is None:  # only an empty route has none, and an empty route touches nothing
        raise InputError("route: has no goal to replan to")
    out = call_stage(stage, "solve", Problem(pm, p, route.goal), time_limit=tl, returns=route_problem)
    out.time_s = time.perf_counter() - t0
    out.replanned = True
    return out
