"""OMPL integration: the auxiliary-corner search as an ``ompl.base.Planner``, OMPL's own planners on
the same obstacles with an exact motion validator, and the setup both share.

OMPL objects are created per call and never kept in module globals (nanobind's leak warnings).
OMPL's random number generator is one per process: :func:`solve_ompl` seeds it and solves under
one lock, so seeded solves give the same route from any thread.
"""

from __future__ import annotations

import threading
import time
from typing import TYPE_CHECKING, Any

import numpy as np
from ompl import base as ob
from ompl import geometric as og
from ompl import util as ou

from ..errors import InputError, NoRouteError, PlanningError
from .route import Route

if TYPE_CHECKING:
    from .planning_map import PlanningMap

#: Stage name -> OMPL geometric planner class name.
OMPL_PLANNERS = {
    "rrt-connect": "RRTConnect",
    "rrt-star": "RRTstar",
    "informed-rrt-star": "InformedRRTstar",
    "prm-star": "PRMstar",
    "bit-star": "BITstar",
    "fmt-star": "FMT",
}


#: OMPL's console log during sbplan's solves: off unless ``quiet(verbose=True)`` asked for it (the
#: CLI's -v). A plain flag, not an OMPL object (nanobind's leak warnings).
_verbose = False

#: Held from seeding OMPL's process-wide generator to the end of the solve. It costs no
#: parallelism: OMPL's solve() keeps the GIL for its whole run anyway.
_SOLVE_LOCK = threading.Lock()


def quiet(verbose: bool = False) -> None:
    """Silence OMPL's console log (the default for sbplan's solves) unless verbose."""
    global _verbose
    _verbose = bool(verbose)
    ou.setLogLevel(ou.LOG_INFO if verbose else ou.LOG_NONE)


class ExactMotionValidator(ob.MotionValidator):
    """A motion is valid when its segment enters no enlarged obstacle (the same exact test the
    auxiliary-corner search uses) and both ends are inside the bounds."""

    def __init__(self, si: Any, pmap: PlanningMap):
        super().__init__(si)
        self._pmap = pmap

    def checkMotion(self, s1: Any, s2: Any) -> bool:  # noqa: N802 (OMPL's name)
        return self._pmap.vmap.segment_free((s1[0], s1[1]), (s2[0], s2[1]))


class AuxCornerOMPLPlanner(ob.Planner):
    """The auxiliary-corner search as an OMPL planner (for SimpleSetup, path checking and
    ompl.tools.Benchmark). The search is sbplan's VisibilityMap.shortest_path: the same code the
    sbplan API calls."""

    def __init__(self, si: Any, pmap: PlanningMap):
        super().__init__(si, "AuxCorner")
        self._pmap = pmap

    def clear(self) -> None:
        super().clear()

    def solve(self, ptc: Any) -> Any:
        pdef = self.getProblemDefinition()
        st = self.getPlannerInputStates().nextStart()
        if st is None:
            return ob.PlannerStatus(False, False)
        gstate = pdef.getGoal().getState()
        s = np.array([st[0], st[1]])
        g = np.array([gstate[0], gstate[1]])
        try:
            wp, _ = self._pmap.vmap.shortest_path(s, g, should_stop=lambda: bool(ptc()))
        except NoRouteError:
            return ob.PlannerStatus(False, False)
        si = self.getSpaceInformation()
        path = og.PathGeometric(si)
        state = si.allocState()
        for x, y in wp:
            state[0], state[1] = float(x), float(y)
            path.append(state)
        pdef.addSolutionPath(path, False, 0.0, self.getName())
        return ob.PlannerStatus(True, False)


def make_setup(pmap: PlanningMap) -> Any:
    """A SimpleSetup on the map: R^2 within its bounds, free = outside every enlarged obstacle."""
    space = ob.RealVectorStateSpace(2)
    b = ob.RealVectorBounds(2)
    x0, y0, x1, y1 = pmap.bounds
    b.setLow(0, x0)
    b.setHigh(0, x1)
    b.setLow(1, y0)
    b.setHigh(1, y1)
    space.setBounds(b)
    ss = og.SimpleSetup(space)
    vm = pmap.vmap

    def valid(state: Any) -> bool:
        return not vm.covered(np.array([[state[0], state[1]]]), boundary=False)[0]

    ss.setStateValidityChecker(valid)
    si = ss.getSpaceInformation()
    si.setMotionValidator(ExactMotionValidator(si, pmap))
    return ss


def set_query(ss: Any, start: np.ndarray, goal: np.ndarray) -> None:
    si = ss.getSpaceInformation()
    s = si.allocState()
    g = si.allocState()
    s[0], s[1] = float(start[0]), float(start[1])
    g[0], g[1] = float(goal[0]), float(goal[1])
    ss.setStartAndGoalStates(s, g)
    # A fresh objective per solve: AORRTC-style planners overwrite a shared objective's threshold.
    ss.setOptimizationObjective(ob.PathLengthOptimizationObjective(si))


def allocate(name: str, si: Any, pmap: PlanningMap) -> Any:
    """An OMPL planner instance by sbplan stage name (``aux-corner`` or one of OMPL_PLANNERS)."""
    if name == "aux-corner":
        return AuxCornerOMPLPlanner(si, pmap)
    if name not in OMPL_PLANNERS:
        raise InputError(f"planner: unknown OMPL planner {name!r}; known: aux-corner, {', '.join(OMPL_PLANNERS)}")
    return getattr(og, OMPL_PLANNERS[name])(si)


def solve_ompl(pmap: PlanningMap, start: Any, goal: Any, name: str, *, time_limit: float, simplify: bool = True,
               seed: int | None = None) -> Route:
    """Plan with the OMPL planner ``name`` (a key of OMPL_PLANNERS, or ``aux-corner``) on the map.

    Parameters
    ----------
    pmap : PlanningMap
    start, goal : (x, y)
    name : str
    time_limit : float, seconds
    simplify : bool
        Shorten an exact solution with OMPL's simplifier.
    seed : int, optional
        Seed of OMPL's random number generator (default: not seeded).

    Returns
    -------
    Route
        ``status`` "approximate" when the start or goal had to step out of an obstacle's
        clearance. An approximate OMPL solution (the goal not reached) raises PlanningError.
    """
    t0 = time.perf_counter()
    s0, g0 = np.asarray(start, float), np.asarray(goal, float)
    s, s_esc = pmap.check_endpoint(s0, "start")
    g, g_esc = pmap.check_endpoint(g0, "goal")
    with _SOLVE_LOCK:
        ou.setLogLevel(ou.LOG_INFO if _verbose else ou.LOG_NONE)
        if seed is not None:
            ou.RNG.setSeed(int(seed))
        ss = make_setup(pmap)
        set_query(ss, s, g)
        ss.setPlanner(allocate(name, ss.getSpaceInformation(), pmap))
        status = ss.solve(float(time_limit))
        exact = status == ob.PlannerStatus.EXACT_SOLUTION
        approx = status == ob.PlannerStatus.APPROXIMATE_SOLUTION
        if not (exact or approx):
            raise NoRouteError(f"no route found by {name} within {time_limit:g} s (sampling planners cannot prove there is none)")
        if simplify and exact:
            ss.simplifySolution(0.0)
        path = ss.getSolutionPath()
        wp = np.array([[path.getState(i)[0], path.getState(i)[1]] for i in range(path.getStateCount())])
        del path, ss
    if approx:
        end = wp[-1]
        raise PlanningError(f"{name} reached only ({end[0]:g}, {end[1]:g}), not the goal, within {time_limit:g} s")
    if s_esc:
        wp = np.concatenate([s0[None], wp])
    if g_esc:
        wp = np.concatenate([wp, g0[None]])
    return Route(wp, status="approximate" if (s_esc or g_esc) else "exact", planner=name,
                 time_s=time.perf_counter() - t0, map=pmap, goal=g0)
