"""The public pieces of a planning map (copy, straight_check, the spatial index), the arguments of
plan and replan, and the aux-corner stage the registry gives."""

from __future__ import annotations

import threading

import numpy as np
import pytest
import shapely
from shapely.geometry import LineString, Point, box

import sbplan
from sbplan import registry
from sbplan.errors import InputError, NoRouteError, PlanningError
from sbplan.planning import PlanningMap
from sbplan.planning.aux_corner import AuxCornerPlanner, solve_aux_corner
from sbplan.planning.plan_replan import MapCache

from test_planning_exact import random_world

B = (0.0, 0.0, 100.0, 100.0)


def routes(pm: PlanningMap, pairs) -> list:
    out = []
    for s, g in pairs:
        try:
            out.append(pm.solve(s, g).waypoints.tolist())
        except PlanningError as e:
            out.append(type(e).__name__)
    return out


def test_copy_is_independent_of_the_original():
    obs = random_world(5, 12, holes=False)
    pm = PlanningMap(obs, robot_radius=0.5, bounds=B)
    pairs = np.random.default_rng(5).uniform(0, 100, (30, 2, 2))
    before = routes(pm, pairs)  # also fills the visibility cache the copy takes along
    new = [box(30, 30, 70, 34), box(48, 0, 52, 60)]
    copy = pm.copy()
    copy.add_obstacles(new)
    # The original keeps its obstacles, enlargements, corners and answers.
    assert len(pm.obstacles) == len(obs) and len(pm.enlarged) == len(pm.vmap.polygons) == len(obs)
    assert routes(pm, pairs) == before
    # The copy answers as a map built with every obstacle does.
    assert len(copy.obstacles) == len(obs) + 2 and len(copy.vmap.polygons) == len(obs) + 2
    fresh = PlanningMap(obs + new, robot_radius=0.5, bounds=B)
    assert routes(copy, pairs) == routes(fresh, pairs)
    assert routes(copy, pairs) != before
    # And the other way round: obstacles added to the original leave an earlier copy alone.
    other = pm.copy()
    pm.add_obstacles(new)
    assert routes(other, pairs) == before
    assert len(other.vmap.corners) < len(pm.vmap.corners)


def test_straight_check_agrees_with_the_search():
    for seed in range(4):
        pm = PlanningMap(random_world(seed, 10), robot_radius=0.5, bounds=B)
        vm = pm.vmap
        seen = set()
        for s, g in np.random.default_rng(seed).uniform(0, 100, (60, 2, 2)):
            code = vm.straight_check(s, g)
            seen.add(code)
            # Random points are never within eps of an edge: -1 means an end inside an obstacle.
            assert (code == -1) == bool(vm.covered(np.stack([s, g]), boundary=False).any())
            if code == -1:
                continue
            assert vm.straight_free(s, g) == (code == 1) == vm.segment_free(s, g)
            # shapely, independently: does the segment enter an enlarged obstacle's interior?
            enters = shapely.relate_pattern(LineString([s, g]), shapely.union_all(pm.enlarged), "T********")
            assert enters == (code == 0)
            try:
                route = pm.solve(s, g)
            except NoRouteError:
                assert code == 0
                continue
            if code == 1:  # the straight segment is the route
                np.testing.assert_array_equal(route.waypoints, [s, g])
            else:  # the search bends around an obstacle
                assert len(route.waypoints) > 2 and route.length > np.hypot(*(g - s))
        assert seen == {-1, 0, 1}


def test_the_spatial_index_finds_the_enlarged_obstacles():
    pm = PlanningMap([box(10, 10, 20, 20), box(60, 60, 70, 90)], robot_radius=1.0, bounds=B)
    tree = pm.vmap.tree
    assert tree.query(Point(15, 15), predicate="intersects").tolist() == [0]
    assert tree.query(Point(65, 59.5), predicate="intersects").tolist() == [1]  # within the clearance
    assert len(tree.query(Point(40, 40), predicate="intersects")) == 0
    pm.add_obstacles([box(40, 38, 42, 42)])
    (i,) = pm.vmap.tree.query(Point(40, 40), predicate="intersects").tolist()
    assert pm.vmap.polygons[i].equals(pm.enlarged[2])


def test_the_map_cache_keeps_one_map_per_key_across_threads():
    cache = MapCache(2)
    inside = threading.Barrier(2, timeout=30)

    def build():
        inside.wait()  # both threads build at once: the lock is not held while building
        return PlanningMap([box(40, 40, 60, 60)], robot_radius=1.0, bounds=B)

    got = []
    threads = [threading.Thread(target=lambda: got.append(cache.get("k", build))) for _ in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert len(got) == 2 and got[0] is got[1] and len(cache) == 1
    for k in "abc":
        cache.get(k, lambda: got[0])
    assert len(cache) == 2


def test_a_copy_waits_for_a_search_that_fills_the_cache():
    pm = PlanningMap([box(40, 20, 60, 80), box(20, 0, 25, 40)], robot_radius=1.0, bounds=B)
    s, g = (10.0, 50.0), (90.0, 50.0)
    assert pm.vmap.straight_check(s, g) == 0
    searching, release = threading.Event(), threading.Event()

    def should_stop():
        searching.set()
        release.wait(30)
        return False

    search = threading.Thread(target=lambda: pm.vmap.shortest_path(s, g, should_stop=should_stop))
    search.start()
    assert searching.wait(30)
    copies = []
    copier = threading.Thread(target=lambda: copies.append(pm.copy()))
    copier.start()
    copier.join(0.5)
    assert not copies  # still waiting for the search's lock
    release.set()
    search.join()
    copier.join()
    assert len(copies) == 1


def test_include_grows_the_default_bounds():
    obs = [box(40, 40, 60, 60)]
    plain = PlanningMap(obs, robot_radius=1.0)
    wide = PlanningMap(obs, robot_radius=1.0, include=[(0, 50), (100, 50)])
    assert plain.bounds[0] > 30 and wide.bounds[0] < 0 and wide.bounds[2] > 100
    assert PlanningMap(obs, robot_radius=1.0, bounds=B, include=[(-50, 0)]).bounds == B
    with pytest.raises(InputError, match="include"):
        PlanningMap(obs, robot_radius=1.0, include=[(0, 1, 2)])


def test_plan_on_a_map_takes_its_radius_and_margin():
    pm = PlanningMap([box(40, 40, 60, 60)], robot_radius=1.0, margin=0.5, bounds=B)
    route = sbplan.plan(pm, (10, 50), (90, 50))
    assert route.map is pm and route.length == pm.solve((10, 50), (90, 50)).length
    assert sbplan.plan(pm, (10, 50), (90, 50), robot_radius=1.0, margin=0.5).length == route.length
    with pytest.raises(InputError, match="robot_radius"):
        sbplan.plan(pm, (10, 50), (90, 50), robot_radius=2.0)
    with pytest.raises(InputError, match="margin"):
        sbplan.plan(pm, (10, 50), (90, 50), margin=0.0)
    with pytest.raises(InputError, match="robot_radius: required"):
        sbplan.plan([box(40, 40, 60, 60)], (10, 50), (90, 50))


def test_the_registry_gives_the_core_solver_as_the_aux_corner_stage():
    stage = registry.planner("aux-corner")
    assert type(stage) is AuxCornerPlanner
    pm = PlanningMap([box(40, 40, 60, 60)], robot_radius=1.0, bounds=B)
    direct = solve_aux_corner(pm, (10, 50), (90, 50))
    via = sbplan.plan(pm, (10, 50), (90, 50))
    assert direct.planner == via.planner == "aux-corner"
    np.testing.assert_array_equal(direct.waypoints, via.waypoints)


def test_replan_plans_with_the_route_s_planner_unless_told_otherwise():
    obs = [box(40, 20, 60, 80)]
    wall = box(70, 30, 72, 70)
    route = sbplan.plan(obs, (10, 50), (90, 50), robot_radius=1.0, bounds=B, planner="rrt-connect")
    again = sbplan.replan(route, (10, 50), [wall])
    assert again.replanned and again.planner == "rrt-connect"
    assert LineString(again.waypoints).distance(wall) >= 1.0 - 1e-6
    exact = sbplan.replan(route, (10, 50), [wall], planner="aux-corner")
    assert exact.planner == "aux-corner"
    scratch = PlanningMap(obs + [wall], robot_radius=1.0, bounds=B).solve((10, 50), (90, 50))
    np.testing.assert_array_equal(exact.waypoints, scratch.waypoints)
    assert again.length >= exact.length - 1e-9
