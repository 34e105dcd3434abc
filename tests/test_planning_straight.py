"""The straight-line fast path of PlanningMap.solve (VisibilityMap.straight_check).

It must answer exactly what the full path (shapely endpoint checks, then the search) answers:
the same route, the same typed errors, the same escapes. Degenerate cases (a segment grazing a
corner, running along an enlarged edge, ending on one, passing through a vertex) and random
worlds (hypothesis), with both forms of the test: plain Python over per-map tuples (_scan, maps
of at most _SCALAR_MAX_EDGES edges) and numpy (larger maps), which must agree.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import shapely
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from shapely.geometry import LineString, box

import sbplan
from sbplan.errors import (GoalInObstacleError, NoRouteError, OutOfBoundsError, PlanningError,
                           StartInObstacleError)
from sbplan.planning import PlanningMap, vismap
from sbplan.planning.aux_corner import solve_checked

from test_planning_exact import random_world

B = (0.0, 0.0, 100.0, 100.0)


def full(pm: PlanningMap, s, g):
    """The answer of the full path (no fast path): a Route or the PlanningError class."""
    try:
        return solve_checked(pm, np.asarray(s, float), np.asarray(g, float), time_limit=10.0)
    except PlanningError as e:
        return type(e)


def answer(pm: PlanningMap, s, g):
    try:
        return pm.solve(s, g, time_limit=10.0)
    except PlanningError as e:
        return type(e)


def assert_same(a, b):
    if isinstance(b, type):
        assert a is b
    else:
        assert not isinstance(a, type), a
        assert a.status == b.status
        np.testing.assert_array_equal(a.waypoints, b.waypoints)
        assert a.length == b.length


def square_map(radius=1.0):
    pm = PlanningMap([box(40, 40, 60, 60)], robot_radius=radius, bounds=B)
    (big,) = pm.enlarged
    x0, y0, x1, y1 = big.bounds  # the enlarged square: 39 - tol .. 61 + tol
    return pm, (x0, y0, x1, y1)


def test_a_free_segment_is_the_route_and_needs_no_search_state():
    pm, _ = square_map()
    route = pm.solve((10, 10), (90, 20))
    assert route.status == "exact" and len(route.waypoints) == 2
    assert route.length == pytest.approx(math.hypot(80, 10), rel=1e-15)
    assert pm.vmap.stats["expansions"] == 0 and not (pm.vmap._vis != 0).any()
    assert route.map is pm and route.planner == "aux-corner"
    np.testing.assert_array_equal(route.goal, (90, 20))


def test_segment_grazing_a_corner_is_free():
    pm, (x0, y0, x1, y1) = square_map()
    # Through the lower-left enlarged corner, perpendicular to the diagonal: touches it only.
    s, g = (x0 - 20, y0 + 20), (x0 + 20, y0 - 20)
    assert LineString([s, g]).distance(box(40, 40, 60, 60)) == pytest.approx(math.sqrt(2) * pm.clearance, rel=1e-9)
    assert pm.vmap.straight_free(s, g)
    route = pm.solve(s, g)
    assert len(route.waypoints) == 2
    assert_same(route, full(pm, s, g))
    # Rotated a little into the square: blocked, a detour around the corner.
    s2 = (x0 - 20, y0 + 20.5)
    assert not pm.vmap.straight_free(s2, g)
    route = pm.solve(s2, g)
    assert len(route.waypoints) == 3
    assert_same(route, full(pm, s2, g))


def test_segment_along_an_enlarged_edge_and_ending_on_one_is_free():
    pm, (x0, y0, x1, y1) = square_map()
    for s, g in [((x0 - 10, y0), (x1 + 10, y0)),  # along the bottom edge, past both corners
                 ((x0 - 10, 50), (x0, 50)),  # ends on the left edge
                 ((x0, 50), (x0, 90)),  # starts on the left edge, runs along it and beyond
                 ((x0, y0), (10, 10))]:  # starts on a corner
        route = pm.solve(s, g)
        assert len(route.waypoints) == 2 and route.status == "exact", (s, g)
        assert_same(route, full(pm, s, g))


def test_segment_through_the_square_is_blocked_even_between_two_corners():
    pm, (x0, y0, x1, y1) = square_map()
    # The diagonal through two opposite corners: it enters the interior.
    s, g = (x0 - 10, y0 - 10), (x1 + 10, y1 + 10)
    assert not pm.vmap.straight_free(s, g)
    route = pm.solve(s, g)
    assert len(route.waypoints) == 3
    assert_same(route, full(pm, s, g))


@pytest.mark.parametrize("s, g, err", [
    ((50, 50), (10, 10), StartInObstacleError),  # inside the real obstacle
    ((10, 10), (40, 50), GoalInObstacleError),  # on the real obstacle's boundary
    ((-1, 10), (10, 10), OutOfBoundsError),
    ((10, 10), (10, 100.5), OutOfBoundsError),
])
def test_endpoints_in_obstacles_or_outside_raise_the_same_typed_errors(s, g, err):
    pm, _ = square_map()
    with pytest.raises(err):
        pm.solve(s, g)
    assert full(pm, s, g) is err
    with pytest.raises(err):
        sbplan.plan([box(40, 40, 60, 60)], s, g, robot_radius=1.0, bounds=B)


def test_endpoint_within_the_clearance_escapes_instead():
    pm, _ = square_map()
    # (39.5, 50) is outside the real square but inside the enlarged one: no straight route.
    assert not pm.vmap.straight_free((39.5, 50), (10, 50))
    route = pm.solve((39.5, 50), (10, 50))
    assert route.status == "approximate" and len(route.waypoints) == 3
    assert_same(route, full(pm, (39.5, 50), (10, 50)))


def test_overlapping_and_holed_obstacles():
    room = box(30, 30, 70, 70).difference(box(35, 35, 65, 65))
    pm = PlanningMap([room, box(45, 45, 55, 55), box(50, 50, 60, 60)], robot_radius=0.5, bounds=B)
    for s, g in [((40, 40), (40, 60)),  # inside the room, free
                 ((40, 40), (60, 42)),  # inside the room, free
                 ((40, 40), (60, 60)),  # through the overlapping boxes
                 ((10, 10), (40, 40)),  # through the room's wall
                 ((50, 50), (10, 10))]:  # start in the overlap
        assert_same(answer(pm, s, g), full(pm, s, g))
    assert len(pm.solve((40, 40), (40, 60)).waypoints) == 2


def test_empty_map_and_no_route_are_unchanged():
    pm = PlanningMap([], robot_radius=0.5, bounds=B)
    assert len(pm.solve((1, 1), (99, 99)).waypoints) == 2
    wall = [box(40, -1, 50, 101)]
    pm = PlanningMap(wall, robot_radius=0.0, bounds=B)
    with pytest.raises(NoRouteError):
        pm.solve((10, 50), (90, 50))


def numpy_form(pm: PlanningMap) -> PlanningMap:
    """A copy of the map whose segment tests take the numpy form (no _scan tables)."""
    other = pm.copy()
    other.vmap._scan_polys = None
    return other


def test_maps_above_the_limit_use_numpy_and_answer_the_same(monkeypatch):
    polys = random_world(3, 8)
    pm = PlanningMap(polys, robot_radius=0.5, bounds=B)
    assert pm.vmap._scan_polys is not None
    monkeypatch.setattr(vismap, "_SCALAR_MAX_EDGES", 0)
    big = PlanningMap(polys, robot_radius=0.5, bounds=B)
    assert big.vmap._scan_polys is None
    rng = np.random.default_rng(3)
    for s, g in rng.uniform(0, 100, (40, 2, 2)):
        assert_same(answer(big, s, g), answer(pm, s, g))
        assert big.vmap.straight_check(s, g) == pm.vmap.straight_check(s, g)


def test_scan_tables_follow_added_obstacles_and_copies():
    pm, _ = square_map()
    s, g = (10, 20), (90, 20)
    assert pm.vmap.straight_check(s, g) == 1
    other = pm.copy()
    other.add_obstacles([box(70, 10, 72, 30)])
    assert other.vmap.straight_check(s, g) == 0 and pm.vmap.straight_check(s, g) == 1
    assert_same(other.solve(s, g), full(other, s, g))


def test_a_segment_through_a_vertex_takes_the_cone_test():
    # A diamond: the segment along its diagonal through two vertices is blocked, one touching a
    # vertex from outside is free; both through _scan's vertex branch (the numpy cone test).
    diamond = shapely.Polygon([(50, 40), (60, 50), (50, 60), (40, 50)])
    pm = PlanningMap([diamond], robot_radius=0.0, bounds=B)
    (big,) = pm.enlarged
    ys = sorted(y for _, y in big.exterior.coords[:-1])
    top = max(big.exterior.coords[:-1], key=lambda c: c[1])
    for s, g in [((50.0, 10.0), (50.0, 90.0)),  # through the bottom and top vertices: enters
                 ((top[0] - 20, top[1]), (top[0] + 20, top[1]))]:  # grazes the top vertex
        assert_same(answer(pm, s, g), full(pm, s, g))
        assert pm.vmap.straight_check(s, g) == numpy_form(pm).vmap.straight_check(s, g)
    assert ys[0] < 40 and pm.vmap.straight_check((50.0, 10.0), (50.0, 90.0)) == 0


@st.composite
def world_and_points(draw):
    seed = draw(st.integers(0, 2**31 - 1))
    n = draw(st.integers(1, 8))
    radius = draw(st.sampled_from([0.0, 0.5, 2.0]))
    chunk = draw(st.sampled_from([1, 3, vismap._SCAN_EDGES]))
    discs = draw(st.integers(0, 2))
    return seed, n, radius, chunk, discs


@settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(case=world_and_points())
def test_fast_path_agrees_with_the_full_path_and_shapely(case):
    seed, n, radius, chunk, discs = case
    polys = random_world(seed, n)
    rng = np.random.default_rng(seed)
    # Many-edged obstacles too (several chunks per polygon in _scan's tables).
    polys += [shapely.Point(rng.uniform(10, 90, 2)).buffer(rng.uniform(2, 10), quad_segs=int(rng.integers(2, 12)))
              for _ in range(discs)]
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(vismap, "_SCAN_EDGES", chunk)
        pm = PlanningMap(polys, robot_radius=radius, bounds=B)
    pn = numpy_form(pm)
    corners = np.concatenate([np.zeros((0, 2))] + [np.asarray(p.exterior.coords)[:-1] for p in pm.enlarged])
    pts = list(rng.uniform(-1, 101, (16, 2)))
    # Degenerate ends: enlarged corners, and points on enlarged edges.
    for _ in range(8 if len(corners) else 0):
        i = rng.integers(len(corners))
        pts.append(corners[i])
        pts.append(corners[i] + rng.uniform() * (corners[(i + 1) % len(corners)] - corners[i]))
    # Segments through a corner (the vertex branch and its cone test), from both sides.
    for _ in range(4 if len(corners) else 0):
        c = corners[rng.integers(len(corners))]
        d = rng.normal(size=2)
        pts.append(c - rng.uniform(1, 30) * d)
        pts.append(c + rng.uniform(1, 30) * d)
    for k in range(0, len(pts) - 1, 2):
        s, g = pts[k], pts[k + 1]
        fast = answer(pm, s, g)
        assert_same(fast, full(pm, s, g))
        # The two forms of the test give the same decisions.
        assert pm.vmap.segment_free(s, g) == pn.vmap.segment_free(s, g)
        ok_bounds = pm.in_bounds(s) and pm.in_bounds(g)
        if not ok_bounds:
            continue
        code = pm.vmap.straight_check(s, g)
        assert code == pn.vmap.straight_check(s, g)
        assert_same(answer(pn, s, g), fast)
        if code >= 0:
            # Both ends certainly free: the endpoint checks the fast path skips pass them unchanged.
            for p, which in ((s, "start"), (g, "goal")):
                q, esc = pm.check_endpoint(np.asarray(p, float), which)
                assert not esc and q is not None
            assert (code == 1) == pm.vmap.segment_free(s, g)
        # Away from every boundary (1e-6 of the map) shapely decides without tolerances: the
        # fast path must then be taken exactly when the segment is free.
        seg = LineString([s, g])
        if all(seg.distance(q.boundary) > 1e-4 for q in pm.enlarged):
            free = not any(seg.intersects(q) for q in pm.enlarged)
            assert pm.vmap.straight_free(s, g) == free
