"""Replanning (incremental cache update, equal to planning from scratch) and the OMPL integration
(the auxiliary-corner planner through SimpleSetup and ompl.tools.Benchmark, OMPL planner stages)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import shapely
from shapely import affinity
from shapely.geometry import LineString, box

import sbplan
from sbplan.errors import InputError, NoRouteError
from sbplan.planning import PlanningMap, vismap

B = (0.0, 0.0, 100.0, 100.0)


def rect_world(seed: int, n: int) -> list:
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        c = rng.uniform(0, 100, 2)
        w, h = rng.uniform(3, 15, 2)
        out.append(affinity.rotate(box(c[0] - w / 2, c[1] - h / 2, c[0] + w / 2, c[1] + h / 2), rng.uniform(0, 180)))
    return out


def query(pm, rng):
    while True:
        s, g = rng.uniform(0, 100, (2, 2))
        if math.dist(s, g) > 40 and not pm.vmap.covered(np.stack([s, g])).any():
            try:
                return s, g, pm.solve(s, g)
            except NoRouteError:
                continue


def blocker(route, side=3.0):
    wp = route.waypoints
    k = (len(wp) - 1) // 2
    m = (wp[k] + wp[k + 1]) / 2
    return box(m[0] - side / 2, m[1] - side / 2, m[0] + side / 2, m[1] + side / 2)


@pytest.mark.parametrize("seed", range(8))
def test_replan_equals_planning_from_scratch(seed):
    obs = rect_world(seed, 20)
    pm = PlanningMap(obs, robot_radius=0.5, bounds=B)
    rng = np.random.default_rng(seed + 100)
    for _ in range(3):  # fill the visibility cache with other queries first
        query(pm, rng)
    s, g, route = query(pm, rng)
    new = blocker(route)
    if new.distance(shapely.Point(s)) < 2 or new.distance(shapely.Point(g)) < 2:
        pytest.skip("blocker too close to an end of this route")
    try:
        scratch = PlanningMap(obs + [new], robot_radius=0.5, bounds=B).solve(s, g).length
    except NoRouteError:
        with pytest.raises(NoRouteError):
            sbplan.replan(route, s, [new])
        return
    out = sbplan.replan(route, s, [new])
    assert out.replanned and out.status == "exact"
    assert out.length == pytest.approx(scratch, rel=1e-9)
    assert out.length >= route.length - 1e-9
    assert LineString(out.waypoints).distance(new) >= 0.5 - 1e-6
    np.testing.assert_allclose(out.waypoints[[0, -1]], [s, g])
    # The caller's route and map are untouched.
    assert len(route.map.obstacles) == len(obs)


def test_replan_updates_the_cache_incrementally():
    obs = rect_world(3, 30)
    pm = PlanningMap(obs, robot_radius=0.5, bounds=B)
    rng = np.random.default_rng(5)
    for _ in range(4):
        s, g, route = query(pm, rng)
    new = blocker(route, side=4.0)
    vm = pm.vmap
    C = len(vm._cp)
    old_vis = vm._vis.copy()
    old_active = vm._cactive.copy()
    free_pairs = int(np.triu(old_vis == vismap._FREE).sum())
    assert free_pairs > 50

    pm2 = pm.copy()
    before = pm2.vmap.stats["segment_pairs"]
    (big,) = pm2.add_obstacles([new])
    # Only the cached free pairs were tested, and only against the new obstacle's 4 edges.
    assert pm2.vmap.stats["segment_pairs"] - before == free_pairs * 4
    v2 = pm2.vmap
    # Old corners keep their indices; the new obstacle's corners are appended.
    np.testing.assert_array_equal(v2._cp[:C], vm._cp)
    assert len(v2._cp) == C + 4
    buried = shapely.intersects_xy(big, vm._cp[:, 0], vm._cp[:, 1])
    np.testing.assert_array_equal(v2._cactive[:C], old_active & ~buried)
    # Each cached free pair stays free unless its segment now enters the new obstacle.
    i, j = np.nonzero(np.triu(old_vis == vismap._FREE))
    segs = shapely.linestrings(np.stack([vm._cp[i], vm._cp[j]], axis=1))
    enters = shapely.relate_pattern(segs, big, "T********")
    assert enters.any() and (~enters).any()
    np.testing.assert_array_equal(v2._vis[i, j] == vismap._BLOCKED, enters)
    np.testing.assert_array_equal(v2._vis[i, j] == vismap._FREE, ~enters)
    # Unknown pairs stay unknown (not recomputed); the original map is unchanged.
    unk = old_vis[:C, :C] == vismap._UNKNOWN
    assert (v2._vis[:C, :C][unk] == vismap._UNKNOWN).all()
    np.testing.assert_array_equal(pm.vmap._vis, old_vis)


def test_obstacle_off_the_remaining_route_returns_it_unchanged():
    obs = [box(40, 40, 60, 60)]
    route = sbplan.plan(obs, (10, 50), (90, 50), robot_radius=1.0, bounds=B)
    assert len(route.waypoints) == 4
    pos = route.waypoints[1] + (route.waypoints[2] - route.waypoints[1]) * 0.5
    # Far from the rest of the route, but on the part already driven.
    out = sbplan.replan(route, pos, [box(12, 55, 16, 70)])
    assert not out.replanned
    np.testing.assert_allclose(out.waypoints, np.vstack([pos, route.waypoints[2:]]))
    assert out.length == pytest.approx(route.length - math.dist(route.waypoints[0], route.waypoints[1])
                                       - math.dist(route.waypoints[1], pos))
    # The same obstacle on the remaining route does trigger a replan.
    wall = box(70, 0, 72, 80)
    out2 = sbplan.replan(route, pos, [wall])
    assert out2.replanned and out2.length > out.length
    assert LineString(out2.waypoints).distance(wall) >= 1.0 - 1e-6


def test_replan_rejects_a_non_route():
    with pytest.raises(InputError, match="route"):
        sbplan.replan([(0, 0), (1, 1)], (0, 0), [box(1, 1, 2, 2)])


# -- OMPL ------------------------------------------------------------------------------------------
def test_aux_corner_runs_through_simple_setup_and_ompl_path_checking():
    from ompl import base as ob

    from sbplan.planning.ompl_planners import allocate, make_setup, quiet, set_query

    quiet()
    obs = rect_world(11, 15)
    pm = PlanningMap(obs, robot_radius=0.5, bounds=B)
    s, g, exact = query(pm, np.random.default_rng(2))
    ss = make_setup(pm)
    set_query(ss, s, g)
    ss.setPlanner(allocate("aux-corner", ss.getSpaceInformation(), pm))
    assert ss.solve(1.0) == ob.PlannerStatus.EXACT_SOLUTION
    path = ss.getSolutionPath()
    assert path.check()  # OMPL's own validity check of every state and motion
    assert path.length() == pytest.approx(exact.length, rel=1e-12)
    wp = np.array([[path.getState(i)[0], path.getState(i)[1]] for i in range(path.getStateCount())])
    np.testing.assert_allclose(wp, exact.waypoints)


def test_aux_corner_runs_in_ompl_benchmark(tmp_path):
    from ompl import tools as ot

    from sbplan.planning.ompl_planners import allocate, make_setup, quiet, set_query

    quiet()
    pm = PlanningMap([box(40, 20, 60, 80)], robot_radius=1.0, bounds=B)
    ss = make_setup(pm)
    set_query(ss, (10, 50), (90, 50))
    bench = ot.Benchmark(ss, "sbplan test")
    si = ss.getSpaceInformation()
    planners = [allocate("aux-corner", si, pm), allocate("rrt-connect", si, pm)]
    for p in planners:
        bench.addPlanner(p)
    bench.benchmark(ot.Request(0.2, 4096.0, 2, 0.05, False, False, True))
    log = tmp_path / "bench.log"
    bench.saveResultsToFile(str(log))
    text = log.read_text()
    assert "AuxCorner" in text and "RRTConnect" in text
    assert "2 runs" in text or text.count("\n") > 20


@pytest.mark.parametrize("name", ["rrt-connect", "rrt-star", "informed-rrt-star", "prm-star", "bit-star", "fmt-star"])
def test_ompl_planner_stages_route_around_the_obstacles(name):
    obs = [box(40, 20, 60, 80), box(20, 0, 25, 40)]
    exact = sbplan.plan(obs, (10, 50), (90, 50), robot_radius=1.0, bounds=B)
    route = sbplan.plan(obs, (10, 50), (90, 50), robot_radius=1.0, bounds=B, planner=name, time_limit=0.3)
    assert route.planner == name and route.status == "exact"
    np.testing.assert_allclose(route.waypoints[[0, -1]], [(10, 50), (90, 50)])
    line = LineString(route.waypoints)
    for p in obs:
        assert line.distance(p) >= 1.0 - 1e-6  # the exact motion validator, at the robot radius
    assert exact.length - 1e-9 <= route.length < 2 * exact.length


def test_free_points_and_ompl_state_validity():
    from sbplan.planning.ompl_planners import make_setup

    pm = PlanningMap([box(40, 40, 60, 60)], robot_radius=1.0, bounds=B)
    pts = np.array([[50, 50], [39.5, 50], [pm.enlarged[0].bounds[0], 50], [30, 50]])
    np.testing.assert_array_equal(pm.vmap.covered(pts, boundary=False), [True, True, False, False])
    np.testing.assert_array_equal(pm.vmap.covered(pts), [True, True, True, False])
    si = make_setup(pm).getSpaceInformation()
    state = si.allocState()
    valid = []
    for x, y in pts:
        state[0], state[1] = float(x), float(y)
        valid.append(si.isValid(state))
    assert valid == [False, False, True, True]
