"""The auxiliary-corner planner against an independent exact shortest-path oracle.

The oracle is written here, independent of sbplan.planning: a plain visibility graph over ALL
vertices of the same enlarged polygons (plus start and goal), edges tested with shapely's DE-9IM
predicate (segment interior meets no polygon interior), and Dijkstra.
"""

from __future__ import annotations

import heapq
import math

import numpy as np
import pytest
import shapely
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from shapely import affinity
from shapely.geometry import LineString, Point, Polygon, box

import sbplan
from sbplan.errors import NoRouteError
from sbplan.planning import PlanningMap, vismap

DENSE_LIMIT = vismap._DENSE_LIMIT

SIZE = 100.0


def random_world(seed: int, n: int, *, holes: bool = True, size=(2, 30)) -> list[Polygon]:
    """Rotated rectangles, star-shaped (non-convex) polygons and, sometimes, a closed room."""
    rng = np.random.default_rng(seed)
    obs = []
    for _ in range(n):
        c = rng.uniform(0, SIZE, 2)
        kind = rng.integers(0, 3)
        if kind < 2:
            w, h = rng.uniform(*size, 2)
            obs.append(affinity.rotate(box(c[0] - w / 2, c[1] - h / 2, c[0] + w / 2, c[1] + h / 2), rng.uniform(0, 180)))
        else:
            k = int(rng.integers(5, 9))
            ang = np.sort(rng.uniform(0, 2 * np.pi, k))
            rad = rng.uniform(size[0], size[1] / 2, k) + 1
            p = Polygon(np.c_[c[0] + rad * np.cos(ang), c[1] + rad * np.sin(ang)])
            if p.is_valid and p.area > 1:
                obs.append(p)
    if holes and rng.random() < 0.25:
        c = rng.uniform(20, 80, 2)
        outer = box(c[0] - 15, c[1] - 15, c[0] + 15, c[1] + 15)
        obs.append(outer.difference(box(c[0] - 11, c[1] - 11, c[0] + 11, c[1] + 11)))
    return obs


def oracle(polys: list[Polygon], bounds, s, g) -> float:
    """Shortest path length through the vertices of ``polys`` (math.inf when none)."""
    x0, y0, x1, y1 = bounds
    verts = []
    for p in polys:
        for ring in (p.exterior, *p.interiors):
            verts.extend(ring.coords[:-1])
    verts = np.array(verts, float).reshape(-1, 2)
    inside = np.zeros(len(verts), bool)
    if len(verts):
        for p in polys:
            inside |= shapely.contains_properly(p, shapely.points(verts))
        inb = (verts[:, 0] >= x0) & (verts[:, 0] <= x1) & (verts[:, 1] >= y0) & (verts[:, 1] <= y1)
        verts = verts[~inside & inb]
    nodes = np.vstack([np.asarray(s, float), np.asarray(g, float), verts])
    n = len(nodes)
    i, j = np.triu_indices(n, 1)
    lines = shapely.linestrings(np.stack([nodes[i], nodes[j]], axis=1))
    tree = shapely.STRtree(polys)
    li, pi = tree.query(lines, predicate="intersects")
    bad = np.zeros(len(lines), bool)
    if len(li):
        cross = shapely.relate_pattern(lines[li], np.asarray(polys, dtype=object)[pi], "T********")
        bad[li[cross]] = True
    adj = [[] for _ in range(n)]
    for a, b, ok in zip(i.tolist(), j.tolist(), (~bad).tolist()):
        if ok:
            w = math.dist(nodes[a], nodes[b])
            adj[a].append((b, w))
            adj[b].append((a, w))
    dist = [math.inf] * n
    dist[0] = 0.0
    heap = [(0.0, 0)]
    while heap:
        d, u = heapq.heappop(heap)
        if d > dist[u]:
            continue
        if u == 1:
            return d
        for v, w in adj[u]:
            if d + w < dist[v]:
                dist[v] = d + w
                heapq.heappush(heap, (d + w, v))
    return math.inf


def free_points(pm: PlanningMap, rng, k: int) -> list[np.ndarray]:
    pts = rng.uniform(0, SIZE, (k * 20, 2))
    ok = ~pm.vmap.covered(pts)
    return list(pts[ok][:k])


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(1, 9), radius=st.sampled_from([0.0, 0.5, 2.0]),
       angular=st.booleans())
def test_exact_length_matches_oracle(seed, n, radius, angular):
    # ``angular`` forces the angle-sorted pre-filter that large maps use on every segment batch.
    vismap._DENSE_LIMIT = 0 if angular else DENSE_LIMIT
    try:
        check_world(seed, n, radius)
    finally:
        vismap._DENSE_LIMIT = DENSE_LIMIT


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**31 - 1))
def test_exact_length_matches_oracle_on_crowded_maps(seed):
    check_world(seed, 25, 0.3, size=(1, 10))


def test_segment_leaving_a_corner_along_a_bevel_a_few_eps_long_is_free():
    # A needle of a star polygon, enlarged by the tolerance only, is bevelled into two corners
    # 5.8e-7 apart (eps 1e-7). The route leaves one of them almost along the bevel; the other
    # corner was "on" that segment and its cone test (an angular eps) called it blocked: no route.
    check_world(56981, 3, 0.0)


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(1, 12), radius=st.sampled_from([0.0, 0.5, 2.0]),
       fans=st.booleans())
def test_corner_table_matches_oracle(seed, n, radius, fans):
    # prepare_routes' all-pairs table (the service's warm maps) answers without A*. ``fans``:
    # every end's visibility by the fans at once, not one segment at a time.
    lazy = vismap._LAZY_TESTS
    vismap._LAZY_TESTS = 0 if fans else lazy
    try:
        check_world(seed, n, radius, table=True)
    finally:
        vismap._LAZY_TESTS = lazy


def test_corner_table_gives_the_searchs_lengths_and_errors():
    # Both exact: the same lengths (to rounding) and the same errors, on many seeded queries
    # (free points, and points inside obstacles or their clearance).
    polys = random_world(7, 30, size=(1, 12))
    a = PlanningMap(polys, robot_radius=0.5, bounds=(0, 0, SIZE, SIZE))
    b = PlanningMap(polys, robot_radius=0.5, bounds=(0, 0, SIZE, SIZE))
    assert b.prepare_routes() and b.vmap._table is not None
    rng = np.random.default_rng(3)
    routes = 0
    for s, g in rng.uniform(0, SIZE, (150, 2, 2)):
        try:
            want = a.solve(s, g)
        except sbplan.PlanningError as exc:
            with pytest.raises(type(exc)) as got:
                b.solve(s, g)
            assert str(got.value) == str(exc)
            continue
        route = b.solve(s, g)
        assert route.length == pytest.approx(want.length, rel=1e-12)
        assert route.status == want.status
        routes += 1
    assert routes > 50
    assert b.vmap.stats["expansions"] == 0  # the table answered, not the A*
    # new obstacles drop the table (a copy keeps it): searches are A* again, still exact
    c = b.copy()
    c.add_obstacles([box(48, 48, 52, 52)])
    assert c.vmap._table is None and b.vmap._table is not None
    assert c.solve((10, 50), (90, 50)).length > 0


def test_enclosed_goal_with_the_corner_table_says_why():
    room = box(40, 40, 60, 60).difference(box(44, 44, 56, 56))
    pm = PlanningMap([room], robot_radius=0.5, bounds=(0, 0, 100, 100))
    pm.prepare_routes()
    with pytest.raises(NoRouteError, match="enclosed"):
        pm.solve((10, 10), (50, 50))
    with pytest.raises(NoRouteError, match="not connected"):
        pm.solve((50, 50), (10, 10))


def check_world(seed, n, radius, size=(2, 30), table=False):
    polys = random_world(seed, n, size=size)
    pm = PlanningMap(polys, robot_radius=radius, bounds=(0, 0, SIZE, SIZE))
    if table:
        assert pm.prepare_routes()
    rng = np.random.default_rng(seed + 1)
    pts = free_points(pm, rng, 6)
    for s, g in zip(pts[0::2], pts[1::2]):
        want = oracle(pm.enlarged, pm.bounds, s, g)
        if math.isinf(want):
            with pytest.raises(NoRouteError):
                pm.solve(s, g)
            continue
        route = pm.solve(s, g)
        assert route.status == "exact"
        assert route.length == pytest.approx(want, rel=1e-6, abs=1e-9)
        np.testing.assert_allclose(route.waypoints[0], s)
        np.testing.assert_allclose(route.waypoints[-1], g)
        # Clearance: the route keeps the robot radius from every real obstacle.
        line = LineString(route.waypoints)
        for p in polys:
            assert line.distance(p) >= radius - 1e-7 * SIZE


def test_enclosed_goal_has_no_route_and_the_error_says_why():
    room = box(40, 40, 60, 60).difference(box(44, 44, 56, 56))
    with pytest.raises(NoRouteError) as exc:
        sbplan.plan([room], (10, 10), (50, 50), robot_radius=0.5, bounds=(0, 0, 100, 100))
    assert exc.value.reason == "no-route"
    assert "no route" in str(exc.value)


def test_door_in_the_room_lets_the_route_in_and_it_bends_at_convex_corners():
    room = box(40, 40, 60, 60).difference(box(44, 44, 56, 56)).difference(box(49, 38, 51, 46))
    route = sbplan.plan([room], (10, 10), (50, 50), robot_radius=0.5, bounds=(0, 0, 100, 100))
    assert route.status == "exact"
    pm = route.map
    assert route.length == pytest.approx(oracle(pm.enlarged, pm.bounds, (10, 10), (50, 50)), rel=1e-9)
    assert len(route.waypoints) > 2


def test_touching_obstacles_leave_no_slit():
    # Two squares sharing an edge: the shared edge must not be a passage.
    a, b = box(40, 0, 50, 60), box(50, 0, 60, 60)
    route = sbplan.plan([a, b], (45, 80), (45, 80.5), robot_radius=0.0, bounds=(0, 0, 100, 100))
    assert route.length == pytest.approx(0.5)
    wall = [box(40, 0, 50, 100.0), box(50, 0, 60, 100.0)]  # cuts the workspace in two
    with pytest.raises(NoRouteError):
        sbplan.plan(wall, (10, 50), (90, 50), robot_radius=0.0, bounds=(0, 0, 100, 100))


def test_diagonal_through_aligned_corners_is_blocked():
    # Segment (0,0)-(30,30) passes exactly through the square's opposite corners.
    sq = box(10, 10, 20, 20)
    route = sbplan.plan([sq], (5, 5), (25, 25), robot_radius=0.0, bounds=(0, 0, 30, 30))
    assert route.length > math.dist((5, 5), (25, 25)) + 1e-3
    assert not LineString(route.waypoints).crosses(sq)
    assert route.length == pytest.approx(oracle(route.map.enlarged, route.map.bounds, (5, 5), (25, 25)), rel=1e-9)


def test_cache_reuse_gives_the_same_answers_as_fresh_maps():
    polys = random_world(7, 12, holes=False)
    pm = PlanningMap(polys, robot_radius=0.5, bounds=(0, 0, SIZE, SIZE))
    rng = np.random.default_rng(3)
    pts = free_points(pm, rng, 10)
    solved = 0
    for s, g in zip(pts[0::2], pts[1::2]):
        fresh_map = PlanningMap(polys, robot_radius=0.5, bounds=(0, 0, SIZE, SIZE))
        try:
            fresh = fresh_map.solve(s, g).length
        except NoRouteError:
            fresh = math.inf
        try:
            warm = pm.solve(s, g).length  # the cache fills up across these queries
        except NoRouteError:
            warm = math.inf
        assert warm == pytest.approx(fresh, rel=1e-12)
        solved += math.isfinite(warm)
    assert solved >= 3
    assert (pm.vmap._vis != 0).any()


def test_start_within_clearance_escapes_and_says_approximate():
    sq = box(40, 40, 60, 60)
    route = sbplan.plan([sq], (39.5, 50), (10, 10), robot_radius=1.0, bounds=(0, 0, 100, 100))
    assert route.status == "approximate"
    np.testing.assert_allclose(route.waypoints[0], (39.5, 50))
    assert route.waypoints[1][0] <= 39.0


def test_escape_from_a_pocket_never_steps_through_the_obstacle():
    # a U open upwards (walls 0.1 thick, a pocket 0.5 wide): with a 0.3 robot radius the whole pocket
    # is within the clearance, and the nearest free point from its bottom lies through the bottom wall
    u = Polygon([(2.0, 1.0), (2.7, 1.0), (2.7, 2.2), (2.6, 2.2), (2.6, 1.1), (2.1, 1.1), (2.1, 2.2), (2.0, 2.2)])
    route = sbplan.plan([u], (2.35, 1.15), (2.35, 0.2), robot_radius=0.3, bounds=(0, 0, 5, 5))
    assert route.status == "approximate"
    np.testing.assert_allclose(route.waypoints[0], (2.35, 1.15))
    for a, b in zip(route.waypoints[:-1], route.waypoints[1:]):
        assert not shapely.relate_pattern(u, LineString([a, b]), "T********"), (a, b)
    # out through the opening, then round the outside
    assert route.waypoints[1][1] > 2.2
