"""The auxiliary-corner planner: the exact shortest route on a map's lazy visibility graph.

Shaped like the OMPL planners (:mod:`sbplan.planning.ompl_planners`): :func:`solve_aux_corner`
plans one query on a :class:`~sbplan.planning.PlanningMap` and returns a
:class:`~sbplan.planning.Route`, as ``solve_ompl`` does, and :class:`AuxCornerPlanner` is the
planner stage around it, registered by the built-in plugin ``sbplan_planners`` through the
``sbplan`` entry points like every other stage. The search itself is
:meth:`VisibilityMap.shortest_path <sbplan.planning.vismap.VisibilityMap.shortest_path>`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from ..contracts import Planner
from .geometry import as_point
from .route import Problem, Route

if TYPE_CHECKING:
    from .planning_map import PlanningMap

#: The stage name, and the ``planner`` of the routes it makes.
NAME = "aux-corner"


def solve_aux_corner(pmap: PlanningMap, start: Any, goal: Any, *, time_limit: float = 1.0) -> Route:
    """The exact shortest route from start to goal on the map.

    Parameters
    ----------
    pmap : PlanningMap
    start, goal : (x, y)
    time_limit : float, seconds
        Polled once per expansion of the search.

    Returns
    -------
    Route
        ``status`` "approximate" when the start or goal had to step out of an obstacle's
        clearance (the route then begins or ends with that step).

    Raises
    ------
    OutOfBoundsError, StartInObstacleError, GoalInObstacleError, NoRouteError, InputError
    """
    t0 = time.perf_counter()
    s0, sx, sy = as_point(start, "start")
    g0, gx, gy = as_point(goal, "goal")
    # Both ends inside the bounds and certainly outside (or on) every enlarged obstacle, hence
    # outside every real one: the endpoint checks of solve_checked (shapely point queries) would
    # pass them unchanged. straight_check decides that from the map's edges alone, with the
    # segment test: a free segment is the route (what the search would return, no search
    # state); a blocked one goes straight to the search. Undecided cases (an end inside an
    # obstacle or within eps of an edge) take the full path.
    x0, y0, x1, y1 = pmap.bounds
    if x0 <= sx <= x1 and y0 <= sy <= y1 and x0 <= gx <= x1 and y0 <= gy <= y1:
        code = pmap.vmap.straight_check((sx, sy), (gx, gy))
        if code == 1:
            r = Route.segment(sx, sy, gx, gy, planner=NAME, map=pmap, goal=g0)
            r.time_s = time.perf_counter() - t0
            return r
        if code == 0:
            return _search(pmap, s0, g0, False, False, t0=t0, time_limit=time_limit, straight_blocked=True)
    return solve_checked(pmap, s0, g0, t0=t0, time_limit=time_limit)


def solve_checked(pmap: PlanningMap, start: np.ndarray, goal: np.ndarray, *, time_limit: float = 1.0,
                  t0: float | None = None) -> Route:
    """:func:`solve_aux_corner` without its straight-line fast path: the endpoint checks
    (errors, escapes), then the search. The same answers (the tests compare them).

    ``start`` and ``goal``: validated points, float arrays of shape (2,). ``t0``: the
    ``time.perf_counter()`` the time limit counts from (default: now)."""
    if t0 is None:
        t0 = time.perf_counter()
    s, s_esc = pmap.check_endpoint(start, "start")
    g, g_esc = pmap.check_endpoint(goal, "goal")
    return _search(pmap, start, goal, s if s_esc else False, g if g_esc else False, t0=t0,
                   time_limit=time_limit)


def _search(pmap: PlanningMap, s0: np.ndarray, g0: np.ndarray, s_esc: Any, g_esc: Any, *, t0: float,
            time_limit: float, straight_blocked: bool = False) -> Route:
    """The search from s0 (or its escape point s_esc) to g0 (or g_esc); the route starts and
    ends at s0 and g0."""
    s = s0 if s_esc is False else s_esc
    g = g0 if g_esc is False else g_esc
    deadline = t0 + float(time_limit)
    wp, _ = pmap.vmap.shortest_path(s, g, should_stop=lambda: time.perf_counter() > deadline,
                                    straight_blocked=straight_blocked)
    if s_esc is not False:
        wp = np.concatenate([s0[None], wp])
    if g_esc is not False:
        wp = np.concatenate([wp, g0[None]])
    return Route(wp, status="approximate" if (s_esc is not False or g_esc is not False) else "exact",
                 planner=NAME, time_s=time.perf_counter() - t0, map=pmap, goal=g0)


@dataclass(kw_only=True, frozen=True)
class AuxCornerPlanner(Planner):
    """The planner stage ``aux-corner``: :func:`solve_aux_corner` on the problem's map."""

    name: ClassVar[str] = NAME
    description: ClassVar[str] = "exact shortest route: lazy A* over the enlarged obstacles' convex corners"
    guarantee: ClassVar[str] = "proven shortest for the robot's radius"
    exact: ClassVar[bool] = True

    def solve(self, problem: Problem, *, time_limit: float = 1.0) -> Route:
        return solve_aux_corner(problem.map, problem.start, problem.goal, time_limit=time_limit)
